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


def test_the_docs_recipe_for_a_new_channel_model_gives_one_the_env_steps(monkeypatch):
    """docs/model.md §4.7, followed: a model class (the paper's one path at half its light), a ``Channel`` option
    with its name and the model it builds, its entry in ``CHANNELS``, its option file as ``make docs`` writes it;
    nothing else changes, and an environment steps it by name, on the same seas as the model it is made from."""
    from dataclasses import dataclass

    from waterair.cli import reference
    from waterair.physics.channel import CHANNELS, Channel, SinglePath

    @dataclass(frozen=True)
    class HalfPath(SinglePath):
        def light(self, sea, path, ends, time, prepared, generator=None, copies=1):
            light = super().light(sea, path, ends, time, prepared, generator, copies)
            return light._replace(weight=0.5 * light.weight)

    @dataclass(frozen=True)
    class HalfPathChannel(Channel):
        name = "half_path"

        def model(self, optics, two_scale_sea):
            return HalfPath(optics)

    monkeypatch.setitem(CHANNELS, HalfPathChannel.name, HalfPathChannel)
    option = reference.conf_files()[reference.CONF_DIR / "env" / "channel" / "half_path.yaml"]
    assert option.startswith("# @package env.channel\n") and option.endswith("\nname: half_path\n")
    sea = {"spectrum": "jonswap", "n_freq": 16, "n_dir": 8}

    def gains(name: str) -> torch.Tensor:
        env = WaterAirEnv(num_envs=4, seed=3, sea=sea, channel={"name": name})
        td, trace = env.reset(), []
        for _ in range(3):
            td = env.step(td.set("action", torch.zeros(4, 4)))["next"]
            trace.append(td["gain"])
        return torch.stack(trace)

    half, whole = gains("half_path"), gains("single_path")
    assert whole.min() > 0
    torch.testing.assert_close(half, 0.5 * whole)
