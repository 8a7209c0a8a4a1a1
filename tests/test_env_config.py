"""The env group's keys are each checked once, where they are defined, against the range docs/environment.md
documents, and an error names the key path (``env.<key>``): a value valid for the env is never
rejected deeper down (in the physics objects, the channel model or the link budget)."""

import math
import re
import sys
from collections import Counter

import pytest
from conftest import ROOT

from waterair.core import validation
from waterair.envs.config import EnvConfig
from waterair.envs.link import link_budget

NUMBER = r"[-+]?(?:\d+(?:\.\d*)?(?:e[-+]?\d+)?|π/2)"
ROW = re.compile(rf"^\| `(\w+)` \| [^|]* \| [^|]* \| (?:odd, )?([\[(])({NUMBER}), ({NUMBER})([\])])")


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
INTEGER_KEYS = {name for name, field in EnvConfig.__dataclass_fields__.items() if field.type == "int"}


def test_the_documented_ranges_cover_the_physics_keys():
    assert {"wind", "aperture_diameter", "lattice_span", "montecarlo_rays", "divergence", "tx_depth"} <= set(RANGES)


def accepted(key: str, value) -> EnvConfig:
    config = EnvConfig(**{key: value})
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
        assert getattr(accepted(key, value), key) == value
    outside = int(high) + 1 if integer else (high if not high_closed else high + step)
    with pytest.raises(ValueError, match=rf"^env\.{key} = "):
        EnvConfig(**{key: outside})


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
    for overrides in ({}, {"channel": "full", "spectrum": "elfouhaily"}, {"channel": "montecarlo"}):
        calls.clear()
        config = EnvConfig(**overrides)
        config.sea(), config.transceiver(), config.channel_model(), link_budget(None, config)
        assert calls["aperture_diameter"] == 1 and calls["wind"] == 1, calls
        assert max(calls.values()) == 1, {key: count for key, count in calls.items() if count > 1}


def test_an_aperture_the_optics_refuse_is_refused_by_the_config_in_one_line():
    with pytest.raises(ValueError, match=r"^env\.aperture_diameter = 2 is out of range; allowed \(0, 1\] m$"):
        EnvConfig(aperture_diameter=2)


@pytest.mark.parametrize("value", ["auto", "true", 1])
def test_compile_kernel_is_true_or_false_and_the_yamls_auto_is_refused_not_compiled(value):
    # 'auto' is decided by train.py and evaluate.py from the frames they run; a truthy string reaching
    # the env would compile it silently
    with pytest.raises(
        ValueError, match=rf"^env.compile_kernel = {re.escape(repr(value))} is not allowed here; choose"
    ):
        EnvConfig(compile_kernel=value)
    assert EnvConfig(compile_kernel=True).compile_kernel is True and EnvConfig().compile_kernel is False
