"""Rewards of the normalised intensity (docs/model.md §7)."""

import math

import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from waterair.envs.rewards import Reward, le_reward_terms


@given(
    a=st.floats(1e-3, 1e3),
    b=st.floats(1e-3, 1e6),
    c=st.floats(0.0, 5.0),
    gain=st.floats(1e-3, 10.0),
    bias=st.floats(-10.0, 10.0),
    low=st.floats(0.0, 9.99),
    gap=st.floats(1e-3, 10.0),
)
def test_le_reward_is_strictly_increasing_and_finite(a, b, c, gain, bias, low, gap):
    reward = Reward(a=a, b=b, c=c, gain=gain, bias=bias)
    high = min(low + gap, 10.0)
    values = reward(torch.tensor([0.0, low, high], dtype=torch.float64))
    assert torch.isfinite(values).all()
    if high > low:
        assert values[2] > values[1]


def test_le_reward_matches_the_formula_above_the_floor():
    reward = Reward(a=2.0, b=50.0, c=0.5, gain=3.0, bias=-1.0, floor=1e-3)
    for intensity in (0.01, 0.5, 2.0):
        want = 3.0 * (math.log(2.0 * intensity + 1) + math.log10(50.0 * intensity) + math.exp(0.5 * intensity)) - 1.0
        assert reward(torch.tensor(intensity, dtype=torch.float64)).item() == pytest.approx(want, rel=1e-12)


def test_default_terms_have_the_same_order_of_magnitude():
    """Over I in [0.05, 2] each LE term's range is within a factor 3 of the others'."""
    intensity = torch.linspace(0.05, 2.0, 50, dtype=torch.float64)
    spans = [term.max() - term.min() for term in le_reward_terms(intensity, Reward())]
    assert max(spans) / min(spans) < 3.0


def test_linear_and_log_rewards():
    intensity = torch.tensor([0.0, 0.5, 2.0], dtype=torch.float64)
    torch.testing.assert_close(Reward(name="linear")(intensity), intensity)
    log = Reward(name="log", floor=1e-4)(intensity)
    torch.testing.assert_close(log, torch.log10(torch.tensor([1e-4, 0.5, 2.0], dtype=torch.float64)))


@pytest.mark.parametrize(
    "kwargs,key",
    [
        ({"b": 0.0}, "reward.b"),
        ({"b": -1.0}, "reward.b"),
        ({"a": 0.0}, "reward.a"),
        ({"c": -0.1}, "reward.c"),
        ({"gain": 0.0}, "reward.gain"),
        ({"floor": 0.0}, "reward.floor"),
        ({"name": "cubic"}, "reward.name"),
    ],
)
def test_invalid_coefficients_are_config_errors(kwargs, key):
    with pytest.raises(ValueError) as info:
        Reward(**kwargs)
    assert str(info.value).startswith(f"{key} = ")
