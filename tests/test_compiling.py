"""compile: auto compiles the step and the update only when the frames to go repay the compile."""

import pytest
from conftest import compose_config

from waterair.physics.channel import FullChannel, SinglePathChannel
from waterair.training import validate
from waterair.training.compiling import cache_state, compile_plan


@pytest.mark.parametrize(
    "frames,cache,compiled",
    [(4_000, "warm", False), (160_000, "warm", True), (160_000, "cold", False), (400_000, "cold", True)],
)
def test_auto_compiles_when_the_frames_to_go_repay_the_compile(frames, cache, compiled):
    plan, why = compile_plan(compose_config("config", ["env/channel=single_path"]), frames, cache)
    assert plan.env.compile_kernel is compiled and plan.compile_update is compiled
    least = SinglePathChannel.compile_frames[cache]
    assert f"{frames:,} frames to go" in why and f"{least:,}" in why and f"cache {cache}" in why


@pytest.mark.parametrize("frames,cache,compiled", [(20_000, "warm", False), (32_000, "warm", True),
                                                   (32_000, "cold", False), (160_000, "cold", True)])  # fmt: skip
def test_on_the_full_channel_compiling_pays_from_fewer_frames(frames, cache, compiled):
    # the default channel costs 7x more a frame eager than compiled: make train's 160,000 frames compile cold
    plan, why = compile_plan(compose_config("config"), frames, cache)
    assert plan.env.compile_kernel is compiled and plan.compile_update is compiled
    assert f"{FullChannel.compile_frames[cache]:,} on the full channel" in why


def test_a_setting_of_true_or_false_is_kept_whatever_the_frames():
    cfg = compose_config("config", ["compile_update=false", "env.compile_kernel=true"])
    plan, why = compile_plan(cfg, 800, "cold")
    assert (plan.env.compile_kernel, plan.compile_update, why) == (
        True,
        False,
        "compiled environment step, eager update (as configured)",
    )
    with pytest.raises(
        ValueError, match=r"^compile_update = 'sometimes' is not allowed; choose one of auto, true, false"
    ):
        validate(compose_config("config", ["compile_update=sometimes"]))


def test_the_cache_is_warm_once_it_holds_compiled_graphs(tmp_path, monkeypatch):
    monkeypatch.setenv("TORCHINDUCTOR_CACHE_DIR", str(tmp_path))
    assert cache_state() == "cold"
    (tmp_path / "fxgraph").mkdir()
    assert cache_state() == "cold"
    (tmp_path / "fxgraph" / "a2mk64").mkdir()
    assert cache_state() == "warm"
