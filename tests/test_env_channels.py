"""The environment on each channel model (env/channel, docs/environment.md): specs, finiteness, the
bound and the paper's model kept as it was."""

import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from torchrl.envs.utils import check_env_specs

from waterair.envs.env import WaterAirEnv

SEA = {"jonswap": {"n_freq": 12, "n_dir": 6}, "elfouhaily": {"n_wavenumbers": 12, "n_dir": 6}}
"""Coarse seas."""
CHANNEL = {"single_path": {}, "full": {}, "montecarlo": {"rays": 200}, "counting": {"rays": 200, "facets": 4}}
"""Each channel's own keys: few rays."""


def small(channel: str, spectrum: str, **sea) -> dict:
    """The env keys of ``channel`` on a coarse ``spectrum`` sea with ``sea``'s keys."""
    return {"channel": {"name": channel, **CHANNEL[channel]}, "sea": {"spectrum": spectrum, **SEA[spectrum], **sea}}


@pytest.mark.parametrize("channel", ["full", "montecarlo", "counting"])
@pytest.mark.parametrize("spectrum", ["jonswap", "elfouhaily"])
def test_check_env_specs_for_each_channel(channel, spectrum):
    env = WaterAirEnv(num_envs=3, seed=0, observation_extras=("spot",), **small(channel, spectrum))
    check_env_specs(env)


@settings(max_examples=8, deadline=None)
@given(
    channel=st.sampled_from(["single_path", "full", "montecarlo", "counting"]),
    spectrum=st.sampled_from(["jonswap", "elfouhaily"]),
    wind=st.floats(0.5, 40.0),
    offset=st.floats(0.0, 2.0),
    seed=st.integers(0, 2**31 - 1),
)
def test_no_nan_or_inf_on_any_channel_whatever_the_sea(channel, spectrum, wind, offset, seed):
    env = WaterAirEnv(num_envs=4, seed=seed, geometry={"offset_ratio": offset}, **small(channel, spectrum, wind=wind))
    actions = 2.0 * torch.rand(4, 4, 4, generator=torch.Generator().manual_seed(seed % 1000)) - 1.0
    td = env.reset()
    for action in actions:
        td = env.step(td.set("action", action))["next"]
        for key in ("observation", "reward", "gain", "gain_upper_bound", "intensity"):
            assert torch.isfinite(td[key]).all(), key
        assert (td["gain"] <= td["gain_upper_bound"] * (1 + 1e-4) + 1e-30).all()


def test_the_full_channels_upper_bound_does_not_depend_on_the_policy():
    """Two envs on the same seas, pointed differently for 5 steps, see the same upper bound (the
    lattice and the bound depend on the sea and the ends only), and different gains."""
    base = {"num_envs": 8, "seed": 2, "sea": {"spectrum": "elfouhaily", "n_dir": 8}}
    first, second = WaterAirEnv(**base), WaterAirEnv(**base)
    a, b = first.reset(), second.reset()
    for _ in range(5):
        a = first.step(a.set("action", torch.zeros(8, 4)))["next"]
        b = second.step(b.set("action", 0.5 * torch.ones(8, 4)))["next"]
    torch.testing.assert_close(a["gain_upper_bound"], b["gain_upper_bound"])
    assert not torch.allclose(a["gain"], b["gain"])
