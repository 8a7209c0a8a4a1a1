"""The env group's keys are each checked once, where they are defined, against the range docs/environment.md
documents, and an error names the key path (``env.<key>``, ``env.sea.<key>``): a value valid for the env is
never rejected deeper down (in the physics objects, the channel model or the link budget). The flat keys of
the first releases still build the same config."""

import dataclasses
import math
import re
import sys
from collections import Counter

import pytest
from conftest import ROOT

from waterair.core import validation
from waterair.envs.config import EnvConfig
from waterair.envs.link import link_budget
from waterair.physics.channel import Beacon, LinkGeometry, Transceiver
from waterair.physics.sea import ElfouhailySea, JonswapSea

NUMBER = r"[-+]?(?:\d+(?:\.\d*)?(?:e[-+]?\d+)?|π/2)"
ROW = re.compile(rf"^\| `([\w.]+)` \| [^|]* \| [^|]* \| (?:odd, )?([\[(])({NUMBER}), ({NUMBER})([\])])")


def documented_ranges() -> dict[str, tuple[float, float, bool, bool]]:
    """Each scalar env key with a numeric range in docs/environment.md: (low, high, low closed, high closed)."""
    ranges = {}
    for line in (ROOT / "docs" / "environment.md").read_text().splitlines():
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


def test_the_documented_ranges_cover_the_physics_keys():
    physics = {"sea.wind", "optics.aperture_diameter", "lattice_span", "montecarlo_rays", "optics.divergence"}
    assert physics | {"geometry.tx_depth", "sea.n_wavenumbers", "sea.gamma", "optics.attenuation"} <= set(RANGES)
    assert {"sea.n_dir", "lattice_nodes", "max_steps"} <= INTEGER_KEYS and "sea.wind" not in INTEGER_KEYS


def config_with(key: str, value) -> EnvConfig:
    """EnvConfig with ``key`` (a path such as ``sea.wind``) set to ``value``, from a mapping as Hydra gives it."""
    if "." not in key:
        return EnvConfig.from_mapping({key: value})
    group, name = key.split(".")
    keys = {name: value, **({"spectrum": SEA_OF[key]} if key in SEA_OF else {})}
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
        if key == "lattice_nodes" and value % 2 == 0:
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
        {"channel": "full", "sea": {"spectrum": "elfouhaily", "wind": 12.0}},
        {"channel": "montecarlo", "sea": {"wind": 12.0}},
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


def flat(config: EnvConfig) -> dict:
    """``config`` as the first releases wrote it: every physics key flat beside the interface keys."""
    values = config.to_mapping()
    for group in ("sea", "geometry", "optics"):
        values.update(values.pop(group))
    return values


def test_the_flat_keys_of_old_configs_build_the_same_config():
    nested = EnvConfig.from_mapping(
        {"sea": {"spectrum": "elfouhaily", "wind": 7.0, "n_dir": 16}, "geometry": {"offset_ratio": 0.3}, "num_envs": 4}
    )
    old = flat(nested) | {"gamma": 3.3, "n_freq": 64}  # old configs listed both seas' own keys
    assert EnvConfig.from_mapping(old) == nested
    assert nested.replace(wind=9.0).sea == dataclasses.replace(nested.sea, wind=9.0)
    assert nested.replace(sea={"wind": 9.0}) == nested.replace(wind=9.0)
    assert nested.replace(aperture_diameter=0.1).optics.aperture_diameter == 0.1


def test_naming_another_sea_keeps_the_conditions_and_takes_that_seas_own_discretisation():
    ocean = EnvConfig.from_mapping({"sea": {"spectrum": "elfouhaily", "wind": 7.0, "n_wavenumbers": 12}})
    paper = ocean.replace(sea={"spectrum": "jonswap"})
    assert paper.sea == JonswapSea(wind=7.0)
    assert ocean.replace(spectrum="jonswap") == paper


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
    from omegaconf import OmegaConf

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
        channel = ("lattice_nodes", "lattice_span", "montecarlo_rays", "montecarlo_facets")
        assert {key: env[key] for key in channel} == {key: getattr(EnvConfig(), key) for key in channel}


@pytest.mark.parametrize("entry", ["config", "evaluate"])
def test_the_defaults_are_the_measured_slope_sea_and_the_full_channel_and_the_paper_is_one_preset_away(entry):
    # train.py (config) and evaluate.py compose the same physics as the env class on its own
    from conftest import compose_config

    default = compose_config(entry).env
    assert (default.sea.spectrum, default.channel) == ("elfouhaily", "full")
    assert (EnvConfig().sea, EnvConfig().channel) == (ElfouhailySea(), "full")
    assert EnvConfig.from_mapping({"sea": {"wind": 8.0}}).sea == ElfouhailySea(wind=8.0)  # a sea that names none
    assert (default.lattice_nodes, default.lattice_span) == (EnvConfig().lattice_nodes, EnvConfig().lattice_span)
    paper = compose_config(entry, ["+experiment=paper"]).env
    assert (paper.sea.spectrum, paper.channel) == ("jonswap", "single_path")
    sea = {key: value for key, value in paper.sea.items() if key != "spectrum"}
    assert JonswapSea(**sea) == JonswapSea()  # the paper's sea as it always was: 64 × 32, γ 3.3


def test_a_saved_config_that_names_no_channel_or_sea_runs_the_physics_it_ran():
    # the releases before the defaults moved left channel and spectrum out when at their defaults
    from waterair.envs.legacy import saved

    old = saved({"num_envs": 4, "sea": {"wind": 8.0}})
    assert EnvConfig.from_mapping(old).channel == "single_path"
    assert EnvConfig.from_mapping(old).sea == JonswapSea(wind=8.0)
    first_release = saved({"wind": 8.0, "offset_ratio": 0.3})  # flat keys, no channel, no spectrum
    assert EnvConfig.from_mapping(first_release).sea == JonswapSea(wind=8.0)
    named = {"channel": "full", "sea": {"spectrum": "elfouhaily", "wind": 8.0}}
    assert saved(named) == named  # a config written since names both: unchanged
