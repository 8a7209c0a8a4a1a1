"""Residual actions, frame stacking and the pointing reward term (docs/environment.md)."""

from __future__ import annotations

import math

import pytest
import torch

from waterair.envs.baselines import FlatSeaSnell, PreviousPathTracking
from waterair.envs.config import EnvConfig
from waterair.envs.controllers import AoATracker
from waterair.envs.drives import flat_tilts
from waterair.envs.env import WaterAirEnv
from waterair.envs.rewards import Reward

SMALL = dict(num_envs=6, sea={"n_wavenumbers": 12, "n_dir": 8}, seed=4)
SENSING = dict(
    observation_extras=("spot", "spot_valid", "geometry"),
    latency_steps=1,
    intensity_noise=0.05,
    intensity_noise_floor=0.001,
    spot_noise_rad=0.001,
    spot_threshold=0.01,
    offset_range=(0.0, 0.5),
    offset_azimuth_range=(-180.0, 180.0),
)


def zero_action(td):
    return td.set("action", torch.zeros(td.batch_size[0], 4))


def test_a_zero_residual_on_flat_snell_points_both_ends_along_the_calm_sea_path():
    env = WaterAirEnv(EnvConfig(action_mode="residual", dtype="float64", **SMALL, **SENSING))
    env.rollout(1, zero_action)
    tilt = env.tilt.double()
    tx, rx = env.state.tx_position.double(), env.state.rx_position.double()
    for row in range(env.batch_size[0]):
        up = torch.cat((tilt[row, :2], torch.sqrt(1 - tilt[row, :2].square().sum()).unsqueeze(0)))
        down = torch.cat((tilt[row, 2:], -torch.sqrt(1 - tilt[row, 2:].square().sum()).unsqueeze(0)))
        # both rays meet z = 0 at one point, and that point satisfies Snell's law: n_w sin θ1 = n_a sin θ2
        hit_up = tx[row] + (-tx[row, 2] / up[2]) * up
        hit_down = rx[row] + (-rx[row, 2] / down[2]) * down
        assert torch.allclose(hit_up, hit_down, atol=1e-6)
        sin1, sin2 = up[:2].norm(), down[:2].norm()
        assert float(env.optics.n_water * sin1) == pytest.approx(float(env.optics.n_air * sin2), abs=1e-9)
        assert sin2 > sin1 or (rx[row, :2] - tx[row, :2]).norm() < 1e-9  # refraction bends away from the normal


def test_a_zero_residual_on_the_aoa_base_is_the_aoa_tracker():
    config = EnvConfig(action_mode="residual", residual_base="aoa_tracker", **SMALL, **SENSING)
    env = WaterAirEnv(config)
    tracker = AoATracker(env)
    steps = env.rollout(20, tracker)
    # the tracker's own pointing, expressed as a residual on the aoa base, is no correction at all
    assert steps["action"].abs().max() < 1e-5
    flat = WaterAirEnv(config.replace(residual_base="flat_snell"))
    assert flat.rollout(20, AoATracker(flat))["action"].abs().max() > 0.01


@pytest.mark.parametrize("policy", [FlatSeaSnell, PreviousPathTracking])
def test_baselines_point_the_same_in_residual_and_absolute_mode_once_acquired(policy):
    gains = []
    for mode in ("absolute", "residual"):
        env = WaterAirEnv(EnvConfig(action_mode=mode, residual_deg=45.0, **SMALL, **SENSING))
        gains.append(env.rollout(15, policy(env))["next", "gain"])
    acquired = SENSING["latency_steps"] + 1  # the residual applies from the first reading of the own pointing
    torch.testing.assert_close(gains[0][:, acquired:], gains[1][:, acquired:], rtol=1e-4, atol=1e-9)
    flat = WaterAirEnv(EnvConfig(action_mode="absolute", **SMALL, **SENSING))
    before = flat.rollout(acquired, FlatSeaSnell(flat))["next", "gain"]
    torch.testing.assert_close(gains[1][:, :acquired], before, rtol=1e-4, atol=1e-9)  # the base's pointing


@pytest.mark.parametrize("latency", [0, 2])
def test_while_only_the_parked_reading_has_arrived_the_ends_take_the_base_pointing(latency):
    sensing = {**SENSING, "latency_steps": latency, "offset_range": (0.05, 0.15)}  # near: the parked beam is seen
    env = WaterAirEnv(EnvConfig(action_mode="residual", residual_base="aoa_tracker", **SMALL, **sensing))
    td = env.reset()
    assert td["observation"][:, env.config.observation_layout["spot_valid"]].any()  # readings the parking ignores
    flat = flat_tilts(env.state.flat_point, env.state.tx_position, env.state.rx_position)
    tilts = []
    generator = torch.Generator().manual_seed(0)
    for _ in range(latency + 2):
        td["action"] = torch.rand(6, 4, generator=generator) * 2 - 1
        td = env.step(td)["next"]
        tilts.append(td["tilt"])
    for tilt in tilts[: latency + 1]:  # the readings of the parked gimbals steer nothing: flat-sea Snell
        torch.testing.assert_close(tilt, flat.to(tilt.dtype), rtol=0, atol=1e-6)
    assert (tilts[latency + 1] - flat).abs().max() > 0.01  # then the tracker and the residual take over


def test_stacked_frames_hold_the_earlier_observations_newest_first():
    frames = 3
    stacked = WaterAirEnv(EnvConfig(frames=frames, **SMALL, **SENSING))
    single = WaterAirEnv(EnvConfig(frames=1, **SMALL, **SENSING))
    size = single.observation_size
    assert stacked.observation_size == frames * size
    action = torch.rand(12, SMALL["num_envs"], 4, generator=torch.Generator().manual_seed(0)) * 2 - 1
    traces = []
    for env in (stacked, single):
        td, observations = env.reset(), []
        observations.append(td["observation"])
        for t in range(action.shape[0]):
            td = env.step(td.set("action", action[t]))["next"]
            observations.append(td["observation"])
        traces.append(torch.stack(observations))
    stack, flat = traces
    torch.testing.assert_close(stack[..., :size], flat)  # the newest frame is the plain observation
    for t in range(stack.shape[0]):
        for k in range(frames):
            torch.testing.assert_close(stack[t, :, k * size : (k + 1) * size], flat[max(t - k, 0)])


def test_a_reset_leaves_the_stacks_it_handed_out_unchanged():
    # TorchRL's step_and_maybe_reset keeps the step's ("next", "observation") without a copy: a
    # reset that wrote in place would turn a finished episode's last observation into the next's first.
    env = WaterAirEnv(EnvConfig(frames=2, **SMALL))
    td = env.reset()
    for _ in range(3):
        td = env.step(td.set("action", torch.rand(6, 4) * 2 - 1))["next"]
    held, copy = td["observation"], td["observation"].clone()
    restarted = env.reset(td.clone().set("_reset", torch.ones(6, 1, dtype=torch.bool)))
    torch.testing.assert_close(held, copy, rtol=0, atol=0)
    assert not torch.equal(restarted["observation"], copy)


def test_a_partial_reset_restarts_only_its_rows_stacks():
    env = WaterAirEnv(EnvConfig(frames=2, **SMALL))
    td = env.reset()
    for _ in range(3):
        td = env.step(td.set("action", torch.rand(6, 4) * 2 - 1))["next"]
    before = td["observation"].clone()
    mask = torch.zeros(6, 1, dtype=torch.bool)
    mask[1] = True
    out = env.reset(td.set("_reset", mask))
    size = env.config.frame_size
    assert torch.equal(out["observation"][1, :size], out["observation"][1, size:])
    assert torch.equal(out["observation"][0], before[0])


def test_the_pointing_term_is_the_misalignment_of_both_ends_from_the_path():
    reward = Reward(pointing=0.05)
    config = EnvConfig(dtype="float64", **SMALL, **SENSING)
    env = WaterAirEnv(config, reward=reward)
    generator = torch.Generator().manual_seed(1)
    actions = torch.rand(30, 6, 4, generator=generator, dtype=torch.float64) * 2 - 1
    steps = env.rollout(30, lambda td: td.set("action", actions[int(env.state.steps[0])]))
    nxt = steps["next"]
    valid = nxt["path_valid"].double()
    misalignment = (nxt["alpha_d"] / config.optics.divergence + nxt["alpha_a"] / config.optics.half_fov) * valid
    intensity = nxt["intensity"]
    le = torch.log1p(10 * intensity) + torch.log10(100 * intensity.clamp(min=1e-3)) + torch.exp(0.7 * intensity)
    expected = 0.1 * le
    torch.testing.assert_close(nxt["reward"].squeeze(-1), expected - 0.05 * misalignment)
    # random pointing mostly misses: where no light arrives the reward still falls with the miss
    dark = intensity < 1e-9
    assert dark.sum() > 20
    order = torch.argsort(misalignment[dark])
    assert torch.all(torch.diff(nxt["reward"].squeeze(-1)[dark][order]) <= 1e-12)
    assert nxt["reward"][dark].std() > 0.01


def test_residual_keys_are_validated():
    with pytest.raises(ValueError, match=r"env.residual_base = 'snell'"):
        EnvConfig(residual_base="snell")
    with pytest.raises(ValueError, match=r"env.frames = 0"):
        EnvConfig(frames=0)
    with pytest.raises(ValueError, match=r"env.residual_deg = 90"):
        EnvConfig(residual_deg=90.0)
    assert math.isclose(EnvConfig(frames=4, observation_extras=("spot",)).observation_size, 4 * 10)


def test_residual_beams_caps_the_transmitters_correction_at_its_links_divergences_and_its_action_inverts_it():
    """With ``env.residual_beams`` k, a full residual moves each link's transmitter k·ω_D from the base (at most
    sin(residual_deg)) and its receiver sin(residual_deg); ``action_for_pointing`` gives back the action, link by
    link; without it both move sin(residual_deg)."""
    spread = (0.005, 0.01, 0.05)
    config = EnvConfig(
        action_mode="residual", residual_deg=1.0, divergence_values=spread, dtype="float64", **SMALL, **SENSING
    )
    reach = math.sin(math.radians(1.0))
    for beams, tx_reach in ((None, [reach] * 3), (1.0, [0.005, 0.01, reach])):
        env = WaterAirEnv(config.replace(residual_beams=beams))
        td = env.rollout(SENSING["latency_steps"] + 1, zero_action)[..., -1]["next"]  # past the parked reading
        action = torch.tensor([[1.0, -1.0, -1.0, 1.0]]).expand(6, 4) * torch.linspace(0.2, 1.0, 6).unsqueeze(-1)
        base = td["base_tilt"].double()
        moved = env.step(td.set("action", action))["next", "tilt"].double() - base
        expected = torch.tensor(tx_reach * 2, dtype=torch.float64)  # the six links cycle through the divergences
        torch.testing.assert_close(moved[:, :2], action[:, :2].double() * expected.unsqueeze(-1), rtol=1e-9, atol=0)
        torch.testing.assert_close(moved[:, 2:], action[:, 2:].double() * reach, rtol=1e-9, atol=0)
        up, down = base[:, :2] + moved[:, :2], base[:, 2:] + moved[:, 2:]
        directions = (
            torch.cat((v, sign * (1 - v.square().sum(-1, keepdim=True)).sqrt()), -1)
            for v, sign in ((up, 1), (down, -1))
        )
        again = env.action_for_pointing(*directions, base=base, divergence=td["divergence"])
        torch.testing.assert_close(again, action.double(), rtol=1e-9, atol=1e-12)
    with pytest.raises(ValueError, match=r"env.residual_beams = 0"):
        EnvConfig(residual_beams=0.0)
