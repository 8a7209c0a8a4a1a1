"""Baseline policies through the same rollout as an agent (docs/environment.md)."""

import pytest
import torch
from conftest import paper_physics

from waterair.envs.baselines import BASELINES, FlatSeaSnell, NoAlignment, StraightFacing
from waterair.envs.env import WaterAirEnv


def test_baselines_point_where_they_say():
    env = WaterAirEnv(num_envs=2, seed=0, geometry={"offset_ratio": 0.3}, **paper_physics(n_freq=8, n_dir=4))
    td = env.reset()
    straight = StraightFacing(env)(td.clone())["action"]
    line = env.state.rx_position - env.state.tx_position
    line = line / line.norm(dim=-1, keepdim=True)
    torch.testing.assert_close(straight[:, :2] * env.config.max_tilt, line[:, :2])
    torch.testing.assert_close(straight[:, 2:] * env.config.max_tilt, -line[:, :2])
    assert (NoAlignment(env)(td.clone())["action"] == 0).all()
    # Under water the flat-sea ray is steeper than the straight line (refraction bends it toward
    # the normal), so the transmitter tilts less; in the air the receiver tilts more.
    flat = FlatSeaSnell(env)(td.clone())["action"]
    assert (flat[:, 0] < straight[:, 0]).all() and (flat[:, 0] > 0).all()
    assert (flat[:, 2] < straight[:, 2]).all()


@pytest.mark.slow
def test_s1_ordering_of_mean_gain():
    """S1's sea and link (12 m/s, 2e4 m, 20 m vertical, 10 % offset) on a coarser sea, 16 realisations
    over 10 s, the same seas for all (the order holds with a 10 % margin between the two aligners)."""
    env = WaterAirEnv(
        num_envs=16,
        geometry={"offset_ratio": 0.1},
        max_steps=500,
        **paper_physics(wind=12.0, fetch=2e4, n_freq=32, n_dir=16),
    )
    mean_gain, upper = {}, None
    for name in ("no_alignment", "straight_facing", "flat_snell"):
        env.set_seed(2024)
        rollout = env.rollout(200, BASELINES[name](env), break_when_any_done=False)
        mean_gain[name] = rollout["next", "gain"].mean().item()
        ub = rollout["next", "gain_upper_bound"].mean().item()
        assert upper is None or ub == pytest.approx(upper, rel=1e-6)  # same seas
        upper = ub
    assert upper >= mean_gain["flat_snell"] >= mean_gain["straight_facing"] >= mean_gain["no_alignment"]
