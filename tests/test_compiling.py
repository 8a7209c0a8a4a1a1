"""compile: auto compiles the step and the update only when the frames to go repay the compile."""

import shutil

import pytest
from conftest import compose_config

from waterair.core.compiling import graphs_kept, graphs_name, keep_graphs
from waterair.envs.config import EnvConfig
from waterair.evaluation import runner
from waterair.evaluation.compiling import compiled_group, note_compiled
from waterair.evaluation.runner import prepare
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
    # the default channel costs 1.8x more a frame eager than compiled: make train's 160,000 frames compile cold
    plan, why = compile_plan(compose_config("config"), frames, cache)
    assert plan.env.compile_kernel is compiled and plan.compile_update is compiled
    assert f"{FullChannel.compile_frames[cache]:,} on the full channel" in why


@pytest.mark.parametrize(
    "actor, agent, compiled",
    [("gru", "ppo", False), ("per_end", "ppo", False), ("per_end", "sac", False), ("per_end", "td3", True)],
)
def test_auto_leaves_eager_the_update_of_a_recurrent_actor_and_of_a_per_end_one_with_a_gaussian_policy(
    actor, agent, compiled
):
    """A per-end actor's update recompiles at every call where the loss builds a distribution around it (PPO, SAC:
    tests/test_torch_internals.py); DDPG's and TD3's compile."""
    plan, why = compile_plan(compose_config("config", [f"actor={actor}", f"agent={agent}"]), 400_000, "cold")
    assert plan.env.compile_kernel is True and plan.compile_update is compiled
    assert (actor in why) is not compiled
    if compiled:
        validate(compose_config("config", [f"actor={actor}", f"agent={agent}", "compile_update=true"]))


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


def test_a_graphs_name_is_kept_once_noted_and_only_while_the_cache_holds_graphs(tmp_path, monkeypatch):
    monkeypatch.setenv("TORCHINDUCTOR_CACHE_DIR", str(tmp_path))
    name = graphs_name("evaluation", {"a": 1})
    assert name == graphs_name("evaluation", {"a": 1}) and name != graphs_name("evaluation", {"a": 2})
    (tmp_path / "fxgraph" / "a2mk64").mkdir(parents=True)  # some graph: the cache is warm
    assert not graphs_kept(name)
    keep_graphs(name)
    assert graphs_kept(name) and not graphs_kept(graphs_name("evaluation", {"a": 2}))
    shutil.rmtree(tmp_path / "fxgraph")  # the cache cleared: nothing is kept, whatever was noted
    assert not graphs_kept(name)


@pytest.mark.parametrize("kept,frames,compiled", [(False, 400_000, False), (False, 600_000, True),
                                                  (True, 30_000, False), (True, 40_000, True)])  # fmt: skip
def test_an_evaluation_group_compiles_when_its_own_frames_repay_it(tmp_path, monkeypatch, kept, frames, compiled):
    """Any graph in the cache (training's) does not make a group warm: only its own, noted when it compiled."""
    monkeypatch.setenv("TORCHINDUCTOR_CACHE_DIR", str(tmp_path))
    (tmp_path / "fxgraph" / "a2mk64").mkdir(parents=True)
    config = EnvConfig(num_envs=64, observation_extras=("spot", "spot_valid"))
    if kept:  # a group of the same interface and physics, another width and divergence, ran compiled before
        note_compiled(config.replace(num_envs=448, optics={"divergence": 0.005}, compile_kernel=True))
    decided, why = compiled_group(config, frames)
    assert decided.compile_kernel is compiled and decided.replace(compile_kernel=False) == config
    least = FullChannel.evaluation_frames["warm" if kept else "cold"]
    assert f"{frames:,} frames to go" in why and f"{least:,}" in why
    # another interface's graphs are its own: never taken as this group's
    other, _ = compiled_group(config.replace(observation_extras=()), 40_000)
    assert other.compile_kernel is False


def test_a_group_run_in_several_processes_compiles_when_each_ones_share_repays_it(tmp_path, monkeypatch):
    """Each process that runs a group's batches compiles its graphs: 600,000 frames repay one cold compile, not two
    (one in each of two processes, 300,000 frames each)."""
    monkeypatch.setenv("TORCHINDUCTOR_CACHE_DIR", str(tmp_path))
    config = EnvConfig(num_envs=64)
    assert FullChannel.evaluation_frames["cold"] == 500_000  # the numbers below straddle it
    assert compiled_group(config, 600_000)[0].compile_kernel is True
    decided, why = compiled_group(config, 600_000, processes=2)
    assert decided.compile_kernel is False and "300,000 frames to go < 500,000" in why
    assert compiled_group(config, 1_200_000, processes=2)[0].compile_kernel is True


def test_an_evaluation_decides_for_each_group_and_notes_the_groups_it_compiled(tmp_path, monkeypatch):
    from test_evaluation import eval_cfg

    monkeypatch.setenv("TORCHINDUCTOR_CACHE_DIR", str(tmp_path))
    (tmp_path / "fxgraph" / "a2mk64").mkdir(parents=True)
    # two baselines and the three shipped policies (their steps are the baselines' but for how they observe, act and
    # sense) in one group, 5 × 16,096 frames
    overrides = ("env.compile_kernel=auto", "baselines=[flat_snell,straight_facing]", "scenarios.S1.realisations=32",
                 "scenarios.S1.steps=500")  # fmt: skip
    plan = prepare(eval_cfg(*overrides))
    assert [len(members) for _, members in plan.groups] == [5]
    assert [config.compile_kernel for config, _ in plan.groups] == [False]  # its graphs not kept
    note_compiled(plan.groups[0][0].replace(compile_kernel=True))
    assert [config.compile_kernel for config, _ in prepare(eval_cfg(*overrides)).groups] == [True]
    # in three processes each would load the graphs for a third of the frames, 26,827 < 35,000: eager
    with monkeypatch.context() as workers:
        workers.setattr(runner, "choose_workers", lambda *args: (3, 1, "3 processes"))
        assert [config.compile_kernel for config, _ in prepare(eval_cfg(*overrides)).groups] == [False]
    # a policy alone: its own group, whose 16,096 frames do not repay even graphs kept
    alone = prepare(eval_cfg(*overrides, "batch_policies=false")).groups
    assert len(alone) == 5 and not any(config.compile_kernel for config, _ in alone)
    for config, _ in alone:
        note_compiled(config.replace(compile_kernel=True))
    assert not any(config.compile_kernel for config, _ in prepare(eval_cfg(*overrides, "batch_policies=false")).groups)


def test_a_cache_folder_that_cannot_be_written_costs_a_compile_not_the_evaluation(tmp_path, monkeypatch):
    blocked = tmp_path / "file"
    blocked.write_text("")  # a file where the cache folder should be: nothing can be made below it
    monkeypatch.setenv("TORCHINDUCTOR_CACHE_DIR", str(blocked))
    keep_graphs(graphs_name("evaluation", {"a": 1}))
    assert not graphs_kept(graphs_name("evaluation", {"a": 1}))
