"""Rewards of the normalised intensity (docs/model.md §7)."""

import math

import pytest
import torch
from conftest import compose_config
from hypothesis import given
from hypothesis import strategies as st

from waterair.envs.rewards import INTENSITY_REWARDS, Reward, le_reward_terms
from waterair.physics.link import LinkBudget, fec_power, received_power, snr
from waterair.training.builders import make_env
from waterair.training.config import validate

SMALL_ENV = ["env.num_envs=4", "env.sea.n_wavenumbers=12", "env.sea.n_dir=8", "env.compile_kernel=false"]


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


def test_snr_reward_is_zero_at_the_fec_limit_minus_slope_in_the_dark_and_log_snr_above():
    link = LinkBudget()
    reward = Reward(name="snr", slope=2.0, link=link)
    limit = fec_power(link) / link.received_power_per_gain  # the gain at the FEC limit (1/m²)
    gain = torch.tensor([0.0, 0.5 * limit, limit, 10.0 * limit, 1e3 * limit], dtype=torch.float64)
    values = reward(gain / 0.0186, None, gain)
    noise = (link.background_power, link.receiver, link.bandwidth)
    power = received_power(gain, link)
    log_snr = torch.log10(snr(power[2:], *noise) / snr(power[2:3], *noise))
    torch.testing.assert_close(values[2:], log_snr, rtol=1e-9, atol=1e-12)
    assert values[0].item() == pytest.approx(-2.0) and values[1].item() == pytest.approx(-1.0)
    assert values[2].item() == pytest.approx(0.0, abs=1e-9)
    # strictly increasing and finite from no light to far above the limit, float32 as the env runs it
    sweep = torch.cat((torch.zeros(1), torch.logspace(-4, 2, 400) * limit)).float()
    out = reward(sweep, None, sweep)
    assert torch.isfinite(out).all() and (out.diff() > 0).all()


def test_snr_reward_needs_the_link_and_a_positive_slope():
    with pytest.raises(ValueError, match=r"^reward.name = 'snr' needs the link group"):
        Reward(name="snr")
    with pytest.raises(ValueError, match=r"^reward.slope = 0.0 is out of range"):
        Reward(name="snr", slope=0.0, link=LinkBudget())
    with pytest.raises(ValueError, match=r"^reward.name = 'snr' is a reward of the gain"):
        Reward(name="snr", link=LinkBudget())(torch.ones(2))


def test_reward_snr_from_the_command_line_steps_the_env_on_the_links_budget():
    cfg = compose_config("config", ["reward=snr", "link.power_w=0.2", *SMALL_ENV])
    validate(cfg)
    env = make_env(cfg)
    reward = env.base_env.reward_fn
    assert reward.name == "snr" and reward.link.power_w == 0.2 and reward.pointing == 0.05
    steps = env.rollout(3, break_when_any_done=False)
    nxt = steps["next"]
    config = env.base_env.config
    # the defaults give each link its own beam: the misalignment in its beam widths, the power through its beam
    divergence = nxt["divergence"]
    assert config.divergence_range is not None and divergence.unique().numel() > 1
    beams = nxt["alpha_d"] / divergence.to(nxt["alpha_d"].dtype)
    misalignment = (beams + nxt["alpha_a"] / config.optics.half_fov) * nxt["path_valid"]
    expected = reward.of_gain(nxt["gain"], divergence) - 0.05 * misalignment
    torch.testing.assert_close(nxt["reward"].squeeze(-1), expected)
    with pytest.raises(ValueError, match=r"^link.power_w = -1"):
        validate(compose_config("config", ["reward=snr", "link.power_w=-1", *SMALL_ENV]))


def test_a_reward_is_chosen_by_name_from_the_registry_and_a_new_one_is_one_entry(monkeypatch):
    intensity = torch.tensor([0.0, 0.5, 2.0])
    terms = le_reward_terms(intensity, Reward())
    torch.testing.assert_close(Reward()(intensity), 0.1 * (terms[0] + terms[1] + terms[2]))
    with pytest.raises(ValueError, match="reward.name = 'square'"):
        Reward(name="square")
    monkeypatch.setitem(INTENSITY_REWARDS, "square", lambda reward, intensity: intensity**2)
    torch.testing.assert_close(Reward(name="square", pointing=0.5)(intensity, torch.ones(3)), intensity**2 - 0.5)
