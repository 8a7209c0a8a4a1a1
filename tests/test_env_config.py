"""The env group's keys are each checked once, where they are defined, against the range docs/reference/env.md
documents (generated from waterair/envs/keys.py), and an error names the key path (``env.<key>``,
``env.sea.<key>``): a value valid for the env is never rejected deeper down (in the physics objects, the channel
model or the link budget). A key of the first releases is an error naming where it lives now."""

import dataclasses
import math
import re
import sys
from collections import Counter

import pytest
import torch
from conftest import ROOT, compose_config
from omegaconf import OmegaConf

from waterair.core import validation
from waterair.envs.config import EnvConfig
from waterair.envs.link import link_budget
from waterair.physics.actuator import Actuator
from waterair.physics.channel import (
    Beacon,
    CountingChannel,
    FullChannel,
    LinkGeometry,
    MonteCarloChannel,
    SinglePathChannel,
    Transceiver,
)
from waterair.physics.motion import Motion
from waterair.physics.sea import ElfouhailySea, JonswapSea

NUMBER = r"[-+]?(?:\d+(?:\.\d*)?(?:e[-+]?\d+)?|π/2)"
ROW = re.compile(rf"^\| `([\w.]+)` \| [^|]* \| [^|]* \| (?:odd, )?([\[(])({NUMBER}), ({NUMBER})([\])])")


def documented_ranges() -> dict[str, tuple[float, float, bool, bool]]:
    """Each scalar env key with a numeric range in docs/reference/env.md: (low, high, low closed, high closed)."""
    ranges = {}
    for line in (ROOT / "docs" / "reference" / "env.md").read_text().splitlines():
        match = ROW.match(line)
        if match:
            key, opening, low, high, closing = match.groups()
            value = lambda text: math.pi / 2 if text == "π/2" else float(text)  # noqa: E731
            ranges[key] = (value(low), value(high), opening == "[", closing == "]")
    return ranges


RANGES = documented_ranges()
GROUPS = {
    "sea": (JonswapSea, ElfouhailySea),
    "geometry": (LinkGeometry,),
    "optics": (Transceiver,),
    "beacon": (Beacon,),
    "actuator": (Actuator,),
    "motion": (Motion,),
    "channel": (FullChannel, MonteCarloChannel, CountingChannel),
}


def field_type(key: str) -> str:
    """The annotation of ``key``'s field: on EnvConfig, or on the physics object its group holds."""
    if "." not in key:
        return EnvConfig.__dataclass_fields__[key].type
    group, name = key.split(".")
    return next(dataclasses.fields(kind)[i].type for kind in GROUPS[group]
                for i, field in enumerate(dataclasses.fields(kind)) if field.name == name)  # fmt: skip


INTEGER_KEYS = {key for key in RANGES if field_type(key) == "int"}
SEA_OF = {
    "sea.n_wavenumbers": "elfouhaily",
    "sea.wavenumber_cutoff": "elfouhaily",
    "sea.gamma": "jonswap",
    "sea.n_freq": "jonswap",
}
"""The keys only one sea has, and that sea (the default sea is JONSWAP)."""
CHANNEL_OF = {
    "channel.nodes": "full",
    "channel.span": "full",
    "channel.rays": "montecarlo",
    "channel.points": "montecarlo",
    "channel.facets": "counting",
}
"""The channel each channel key belongs to (a channel has only its own keys)."""


def test_the_documented_ranges_cover_the_physics_keys():
    physics = {"sea.wind", "optics.aperture_diameter", "channel.span", "channel.rays", "optics.divergence"}
    assert physics | {"geometry.tx_depth", "sea.n_wavenumbers", "sea.gamma", "optics.attenuation"} <= set(RANGES)
    assert {"sea.n_dir", "channel.nodes", "max_steps"} <= INTEGER_KEYS and "sea.wind" not in INTEGER_KEYS
    assert set(CHANNEL_OF) <= set(RANGES)


def config_with(key: str, value) -> EnvConfig:
    """EnvConfig with ``key`` (a path such as ``sea.wind``) set to ``value``, from a mapping as Hydra gives it."""
    if "." not in key:
        return EnvConfig.from_mapping({key: value})
    group, name = key.split(".")
    keys = {name: value, **({"spectrum": SEA_OF[key]} if key in SEA_OF else {})}
    keys |= {"name": CHANNEL_OF[key]} if key in CHANNEL_OF else {}
    return EnvConfig.from_mapping({group: keys})


def value_at(config: EnvConfig, key: str):
    for part in key.split("."):
        config = getattr(config, part)
    return config


def accepted(key: str, value) -> EnvConfig:
    config = config_with(key, value)
    link_budget(None, config)  # the budget takes the env's optics without checking them again
    return config


@pytest.mark.parametrize("key", sorted(RANGES))
def test_every_documented_value_is_accepted_and_the_next_one_refused_naming_the_key(key):
    low, high, low_closed, high_closed = RANGES[key]
    integer = key in INTEGER_KEYS
    step = 1 if integer else max(abs(high), 1.0) * 1e-6
    inside_high = high if high_closed else high - step
    inside_low = low if low_closed else low + step
    if integer:
        inside_high, inside_low = int(inside_high), int(math.ceil(inside_low))
    for value in (inside_low, inside_high):
        if key == "channel.nodes" and value % 2 == 0:
            value -= 1
        assert value_at(accepted(key, value), key) == value
    outside = int(high) + 1 if integer else (high if not high_closed else high + step)
    with pytest.raises(ValueError, match=rf"^env\.{re.escape(key)} = "):
        config_with(key, outside)


def test_each_key_is_checked_exactly_once(monkeypatch):
    """Count the top-level range, integer and choice checks that building a config makes, per key."""
    calls, depth = Counter(), [0]

    def counted(check):
        def inner(key, *args, **kwargs):
            if depth[0] == 0:
                calls[key.removeprefix("env.")] += 1
            depth[0] += 1
            try:
                return check(key, *args, **kwargs)
            finally:
                depth[0] -= 1

        return inner

    checks = {name: getattr(validation, name) for name in ("check_range", "check_int", "check_choice")}
    for module in [m for name, m in sys.modules.items() if name.startswith("waterair")]:
        for name, check in checks.items():
            if getattr(module, name, None) is check:
                monkeypatch.setattr(module, name, counted(check))
    given = {"geometry": {"tx_depth": 10.0}, "optics": {"aperture_diameter": 0.05}}  # as Hydra gives the groups
    for overrides in (
        {"sea": {"wind": 12.0}},
        {"channel": {"name": "full"}, "sea": {"spectrum": "elfouhaily", "wind": 12.0}},
        {"channel": {"name": "montecarlo"}, "sea": {"wind": 12.0}},
    ):
        calls.clear()
        config = EnvConfig.from_mapping({**given, **overrides})
        config.channel_model(), link_budget(None, config)
        assert calls["aperture_diameter"] == 1 and calls["wind"] == 1, calls
        assert max(calls.values()) == 1, {key: count for key, count in calls.items() if count > 1}


def test_an_aperture_the_optics_refuse_is_refused_by_the_config_in_one_line():
    with pytest.raises(ValueError, match=r"^env\.optics\.aperture_diameter = 2 is out of range; allowed \(0, 1\] m$"):
        EnvConfig(optics={"aperture_diameter": 2})


@pytest.mark.parametrize("value", ["auto", "true", 1])
def test_compile_kernel_is_true_or_false_and_the_yamls_auto_is_refused_not_compiled(value):
    # 'auto' is decided by train.py and evaluate.py from the frames they run; a truthy string reaching
    # the env would compile it silently
    with pytest.raises(
        ValueError, match=rf"^env.compile_kernel = {re.escape(repr(value))} is not allowed here; choose"
    ):
        EnvConfig(compile_kernel=value)
    assert EnvConfig(compile_kernel=True).compile_kernel is True and EnvConfig().compile_kernel is False


@pytest.mark.parametrize(
    ("key", "now"),
    [("fetch", "sea.fetch"), ("offset_ratio", "geometry.offset_ratio"),
     ("aperture_diameter", "optics.aperture_diameter"), ("spectrum", "sea.spectrum"),
     ("lattice_nodes", "channel.nodes"), ("montecarlo_points", "channel.points")],
)  # fmt: skip
def test_a_key_of_the_first_releases_is_an_error_naming_where_it_lives_now(key, now):
    message = rf"^env\.{key} is env\.{re.escape(now)} in this version \(python -m waterair\.cli\.migrate RUN"
    with pytest.raises(ValueError, match=message):
        EnvConfig.from_mapping({key: 1.0})
    with pytest.raises(ValueError, match=message):
        EnvConfig().replace(**{key: 1.0})


def test_the_channel_is_a_group_of_its_own_keys_and_another_channel_takes_its_defaults():
    full = EnvConfig.from_mapping({"channel": {"name": "full", "nodes": 5}})
    assert full.channel == FullChannel(nodes=5)
    assert full.to_mapping()["channel"] == {"name": "full", "nodes": 5, "span": 4.5}
    assert full.replace(channel={"span": 3.0}).channel == FullChannel(nodes=5, span=3.0)
    assert full.replace(channel={"name": "single_path"}).channel == SinglePathChannel()
    assert EnvConfig.from_mapping(full.to_mapping()) == full
    refusals = [
        (
            {"name": "single_path", "nodes": 5},
            r"^env\.channel\.nodes is not a key of the single_path channel; it has no",
        ),
        (
            {"name": "montecarlo", "facets": 5},
            r"^env\.channel\.facets is not a key of the montecarlo channel; its keys: ra",
        ),
        (
            "single_path",
            r"^env\.channel = 'single_path' must be a mapping of its keys: choose a channel with env/channel=",
        ),
        (
            {"name": "exact"},
            r"^env\.channel\.name = 'exact' is not allowed; choose one of full, single_path, montecarlo",
        ),
    ]
    for channel, message in refusals:
        with pytest.raises(ValueError, match=message):
            EnvConfig.from_mapping({"channel": channel})


def test_naming_another_sea_keeps_the_conditions_and_takes_that_seas_own_discretisation():
    ocean = EnvConfig.from_mapping({"sea": {"spectrum": "elfouhaily", "wind": 7.0, "n_wavenumbers": 12}})
    paper = ocean.replace(sea={"spectrum": "jonswap"})
    assert paper.sea == JonswapSea(wind=7.0)


@pytest.mark.parametrize(
    ("values", "message"),
    [
        ({"sea": {"spectrum": "elfouhaily", "gamma": 2.0}}, r"^env\.sea\.gamma is not a key of the elfouhaily sea"),
        ({"geometry": {"depth": 3.0}}, r"^env\.geometry\.depth is not a known key; allowed: tx_depth, "),
        ({"optics": 0.05}, r"^env\.optics = 0\.05 must be a mapping of its keys"),
        ({"sea": {"spectrum": "pierson"}}, r"^env\.sea\.spectrum = 'pierson' is not allowed; choose one of jonswap"),
    ],
)
def test_a_physics_group_names_the_key_path_of_what_it_refuses(values, message):
    with pytest.raises(ValueError, match=message):
        EnvConfig.from_mapping(values)


def test_the_yaml_states_each_physics_default_the_physics_object_has():
    # one default per key: conf/env/ restates the physics objects' defaults, never different ones
    from conftest import compose_config

    for spectrum, kind in (("jonswap", JonswapSea), ("elfouhaily", ElfouhailySea)):
        env = OmegaConf.to_container(compose_config("config", [f"env/spectrum={spectrum}"]).env, resolve=True)
        sea = {key: value for key, value in env["sea"].items() if key != "spectrum"}
        assert sea.keys() == {f.name for f in dataclasses.fields(kind)} - {"flat"}
        composed = {
            "sea": kind(**sea),
            "geometry": LinkGeometry(**env["geometry"]),
            "optics": Transceiver(**env["optics"]),
        }
        assert composed == {"sea": kind(), "geometry": LinkGeometry(), "optics": Transceiver()}
        assert env["channel"] == {"name": "full", "nodes": FullChannel().nodes, "span": FullChannel().span}


@pytest.mark.parametrize("entry", ["config", "evaluate"])
def test_the_defaults_are_the_measured_slope_sea_and_the_full_channel_and_the_paper_is_one_preset_away(entry):
    # train.py (config) and evaluate.py compose the same physics as the env class on its own
    from conftest import compose_config

    default = compose_config(entry).env
    assert (default.sea.spectrum, default.channel.name) == ("elfouhaily", "full")
    assert (EnvConfig().sea, EnvConfig().channel) == (ElfouhailySea(), FullChannel())
    assert EnvConfig.from_mapping({"sea": {"wind": 8.0}}).sea == ElfouhailySea(wind=8.0)  # a sea that names none
    assert EnvConfig.from_mapping({"channel": dict(default.channel)}).channel == EnvConfig().channel
    paper = compose_config(entry, ["+experiment=paper"]).env
    assert (paper.sea.spectrum, dict(paper.channel)) == ("jonswap", {"name": "single_path"})
    sea = {key: value for key, value in paper.sea.items() if key != "spectrum"}
    assert JonswapSea(**sea) == JonswapSea()  # the paper's sea as it always was: 64 × 32, γ 3.3


def test_a_policy_reads_its_own_columns_frame_by_frame_out_of_a_wider_observation():
    own = EnvConfig(observation_extras=("beacon",), frames=2)
    wide = EnvConfig(observation_extras=("spot", "beacon", "geometry"), frames=3)  # frames of 8 + 2 + 2 + 2
    assert wide.frame_size == 14
    assert own.columns_in(wide) == [*range(8), 10, 11, *range(14, 22), 24, 25]
    assert own.columns_in(own) == list(range(own.observation_size))
    with pytest.raises(ValueError, match="lacks a part"):
        wide.columns_in(own)


def test_the_operating_point_sets_its_groups_key_and_follows_a_replace():
    config = EnvConfig(wind=8, offset=0.3, divergence=0.01, wind_direction=30, offset_azimuth=-45)
    assert (config.sea.wind, config.sea.wind_direction_deg) == (8.0, 30.0)
    assert (config.geometry.offset_ratio, config.geometry.offset_azimuth_deg, config.optics.divergence) == (
        0.3, -45.0, 0.01)  # fmt: skip
    assert EnvConfig.from_mapping(config.to_mapping()) == config
    assert config.replace(dt=0.1).sea.wind == 8.0
    moved = config.replace(wind=4)
    assert (moved.wind, moved.sea.wind) == (4.0, 4.0)
    # set another way, the quantity is no longer the operating point's (evaluation's scenarios do this)
    swept = config.replace(wind_values=(4.0, 12.0), sea={"fetch": 1e4})
    assert swept.wind is None and swept.sea.wind == 8.0 and swept.wind_values == (4.0, 12.0)
    assert config.replace(sea={"wind": 10.0}).wind is None


@pytest.mark.parametrize(
    ("keys", "message"),
    [
        ({"wind": 12, "wind_range": (4, 20)}, "env.wind = 12 and env.wind_range = [4, 20] are both set"),
        ({"offset": 0.2, "offset_values": (0.1,)}, "env.offset = 0.2 and env.offset_values = [0.1] are both set"),
        ({"wind": 12, "sea": {"wind": 8}}, "env.wind = 12 and env.sea.wind = 8 disagree; env.wind sets env.sea.wind"),
        ({"divergence": 0.01, "optics": Transceiver(divergence=0.02)}, "env.divergence = 0.01 and env.optics.diverg"),
        ({"wind": 0}, "env.wind = 0 is out of range; allowed (0, 60] m/s"),
        ({"offset_azimuth": 400}, "env.offset_azimuth = 400 is out of range; allowed [-360, 360] deg"),
    ],
)
def test_an_operating_point_with_its_own_draws_or_another_group_value_is_refused(keys, message):
    with pytest.raises(ValueError, match=f"^{re.escape(message)}"):
        EnvConfig(**keys)


def test_env_wind_trains_every_link_of_every_reset_at_that_wind(monkeypatch):
    from waterair.envs.env import WaterAirEnv
    from waterair.physics.surface import WaveSurface
    from waterair.training.builders import env_config

    cfg = compose_config("config", ["env.wind=12", "reward.a=5", "env.sea.n_dir=4"])
    assert cfg.reward.a == 5 and cfg.env.wind_range is None and cfg.env.sea.wind == 12
    drawn, sample = [], WaveSurface.from_uniforms.__func__

    def recorded(cls, sea, batch_size, *args, wind=None, **kwargs):
        drawn.append(torch.full((batch_size,), sea.wind) if wind is None else wind.float())
        return sample(cls, sea, batch_size, *args, wind=wind, **kwargs)

    monkeypatch.setattr(WaveSurface, "from_uniforms", classmethod(recorded))
    env = WaterAirEnv(env_config(cfg, num_envs=6, max_steps=2, compile_kernel=False, seed=3))
    env.rollout(5, break_when_any_done=False)  # resets, then every link again after steps 2 and 4
    assert len(drawn) >= 3 and set(torch.cat(drawn).tolist()) == {12.0}
    assert compose_config("config").env.wind_range == [4.0, 20.0]  # without env.wind, the default draws
