"""The ends' own motion in the step (env.motion, waterair.envs.platforms): the oscillators' exact step, the calm-sea
point of moved ends, where the ends are and what their controllers know of it, and the attitudes' rotation of
each end's pointing, each against a closed form or a computation here in float64."""

from __future__ import annotations

import math

import pytest
import torch

from waterair.envs.config import EnvConfig
from waterair.envs.drives import flat_tilts
from waterair.envs.env import WaterAirEnv
from waterair.evaluation.rollouts import kinematic, rollout_policies
from waterair.physics.motion import (
    MOTION_WIDTH,
    Motion,
    Oscillator,
    attitudes,
    motion_start,
    motion_step,
    orbital_motion,
    rotation,
)
from waterair.physics.paths import flat_sea_point, flat_sea_point_near

F64 = torch.float64
SMALL = dict(num_envs=4, sea={"n_wavenumbers": 12, "n_dir": 8}, seed=3, dtype="float64", max_steps=40)
STILL = dict(drift_horizontal=0.0, drift_vertical=0.0, drone_attitude=0.0, vehicle_attitude=0.0, imu_error=0.0,
             vehicle_response=0.0)  # fmt: skip
"""A ``hover`` whose every process is zero: the ends stand still, through every line of the moving step."""


def _correlation(lag: float, period: float, zeta: float) -> float:
    """Corr(x(t + lag), x(t)) of a stationary oscillator ẍ = −ω²x − 2ζωẋ + noise, ζ < 1 (the textbook form)."""
    w = 2 * math.pi / period
    wd = w * math.sqrt(1 - zeta**2)
    return math.exp(-zeta * w * lag) * (math.cos(wd * lag) + zeta / math.sqrt(1 - zeta**2) * math.sin(wd * lag))


@pytest.mark.parametrize("dt", [0.005, 0.05, 2.0])
def test_an_oscillator_step_keeps_its_stationary_covariance_and_correlates_as_the_closed_form(dt):
    oscillator = Oscillator(sigma=0.7, period=3.0, damping=0.4)
    phi, lower = oscillator.transition(dt)
    w = 2 * math.pi / oscillator.period
    stationary = torch.diag(torch.tensor([0.7**2, (w * 0.7) ** 2], dtype=F64))
    assert torch.allclose(phi @ stationary @ phi.T + lower @ lower.T, stationary, rtol=1e-12, atol=1e-14)
    assert phi[0, 0].item() == pytest.approx(_correlation(dt, 3.0, 0.4), rel=1e-10, abs=1e-13)


def _path(motion: Motion, links: int, steps: int) -> torch.Tensor:
    """``steps`` of ``motion`` for ``links`` from a stationary start: each end's attitude and reading ``[m, T, 8]``
    after the drift ``[m, T, 3]``, as one ``[m, T, 11]``."""
    generator = torch.Generator().manual_seed(1)
    draw = lambda: torch.randn(links, MOTION_WIDTH, generator=generator, dtype=F64)  # noqa: E731
    state, rows = motion_start(motion, draw()), []
    for _ in range(steps):
        rows.append(torch.cat((state[:, :3], attitudes(state)), dim=-1))
        state = motion_step(motion, state, draw(), 0.05)
    return torch.stack(rows, dim=1)


def test_a_motion_has_each_process_s_standard_deviation_and_its_inertial_reading_the_error_s():
    motion = Motion(kind="hover")
    path = _path(motion, 4000, 120)
    spread = path.std(dim=(0, 1))
    sigmas = [motion.drift_horizontal] * 2 + [motion.drift_vertical] + [motion.vehicle_attitude] * 2
    assert spread[:3].tolist() == pytest.approx(sigmas[:3], rel=0.03)
    assert spread[3:5].tolist() == pytest.approx(sigmas[3:], rel=0.03)
    assert spread[7:9].tolist() == pytest.approx([motion.drone_attitude] * 2, rel=0.03)
    error = torch.cat((path[..., 5:7] - path[..., 3:5], path[..., 9:11] - path[..., 7:9]), dim=-1)
    assert error.std(dim=(0, 1)).tolist() == pytest.approx([motion.imu_error] * 4, rel=0.03)
    lag = 20  # one second: the attitude's correlation as its oscillator's
    drone = path[:, :-lag, 7].flatten(), path[:, lag:, 7].flatten()
    expected = _correlation(lag * 0.05, motion.drone_attitude_period, motion.attitude_damping)
    assert torch.corrcoef(torch.stack(drone))[0, 1].item() == pytest.approx(expected, abs=0.02)


def test_the_calm_sea_point_of_ends_moved_a_little_is_the_bisection_s_from_the_last_one():
    generator = torch.Generator().manual_seed(2)
    tx = torch.cat((torch.randn(64, 2, generator=generator, dtype=F64), -3 - 10 * torch.rand(64, 1, dtype=F64)), -1)
    rx = torch.cat((5 * torch.randn(64, 2, generator=generator, dtype=F64), 2 + 20 * torch.rand(64, 1, dtype=F64)), -1)
    exact = flat_sea_point(tx, rx)
    near = exact + torch.cat((0.05 * torch.randn(64, 2, generator=generator, dtype=F64), torch.zeros(64, 1)), -1)
    assert torch.allclose(flat_sea_point_near(tx, rx, near), exact, rtol=0, atol=1e-12)


def test_still_processes_through_the_moving_step_give_the_still_link():
    still, moving = (WaterAirEnv(EnvConfig(**SMALL, motion=m)) for m in ({}, {"kind": "hover", **STILL}))
    a, b = still.reset(), moving.reset()
    for _ in range(5):
        action = torch.full((4, 4), 0.05, dtype=F64)
        a, b = still.step(a.set("action", action))["next"], moving.step(b.set("action", action.clone()))["next"]
        assert torch.allclose(a["intensity"], b["intensity"], rtol=1e-9, atol=1e-12)
        for key in ("tx_position", "rx_position", "flat_point", "pointed", "observation"):
            assert torch.allclose(a[key], b[key], rtol=0, atol=1e-12), key


def test_the_vehicle_moves_with_the_water_s_orbital_motion_times_its_response_and_the_drone_drifts_off_its_path():
    motion = {"kind": "transit", "vehicle_response": 0.5, "transit_speed": 1.2, "transit_heading_deg": 30.0}
    env = WaterAirEnv(EnvConfig(**SMALL, motion=motion))
    td = env.reset()
    home = env.state.home.clone()
    for _ in range(7):
        td = env.step(td.set("action", torch.zeros(4, 4, dtype=F64)))["next"]
    state, time = env.state, env.state.time
    orbit = orbital_motion(env.surface.harmonics, home[:, 0], time).displacement
    assert torch.allclose(state.tx_position, home[:, 0] + 0.5 * orbit, rtol=0, atol=1e-12)
    heading = math.radians(30.0)
    velocity = torch.tensor([1.2 * math.cos(heading), 1.2 * math.sin(heading), 0.0], dtype=F64)
    path = home[:, 1] + velocity * (time - 0.5 * env.config.max_steps * env.config.dt).unsqueeze(-1)
    assert torch.allclose(td["rx_position"], path, rtol=0, atol=1e-12)  # what the controllers know: the path
    assert torch.allclose(td["tx_position"], home[:, 0], rtol=0, atol=1e-12)  # and the vehicle's station
    drift = state.motion[:, :3]
    assert torch.allclose(state.rx_position, path + drift, rtol=0, atol=1e-12)
    assert drift.norm(dim=-1).min() > 1e-3
    assert torch.allclose(td["flat_point"], flat_sea_point(home[:, 0], path), rtol=0, atol=1e-9)


def test_a_transit_passes_home_at_its_crossing_time_and_a_parked_drone_stands_still_on_the_crossing_s_stretch():
    crossing = {"transit_speed": 1.2, "transit_heading_deg": 30.0, "crossing_time": 0.15}
    transit, parked = (WaterAirEnv(EnvConfig(**SMALL, motion={"kind": k, **crossing})) for k in ("transit", "parked"))
    td, still = transit.reset(), parked.reset()
    home, spot = transit.state.home[:, 1].clone(), parked.state.home[:, 1].clone()
    heading = math.radians(30.0)
    direction = torch.tensor([math.cos(heading), math.sin(heading), 0.0], dtype=F64)
    along = (spot - home) @ direction
    assert torch.allclose(spot - home, along.unsqueeze(-1) * direction, rtol=0, atol=1e-12)  # on the path
    assert along.abs().max() <= 1.2 * 0.15 and along.unique().numel() == 4  # within its stretch, a spot per link
    assert torch.equal(parked.state.home[:, 2], torch.zeros_like(spot))  # and standing there
    for _ in range(3):
        td = transit.step(td.set("action", torch.zeros(4, 4, dtype=F64)))["next"]
        still = parked.step(still.set("action", torch.zeros(4, 4, dtype=F64)))["next"]
        assert torch.allclose(still["rx_position"], spot, rtol=0, atol=1e-12)
    assert transit.state.time[0].item() == pytest.approx(0.15)
    assert torch.allclose(td["rx_position"], home, rtol=0, atol=1e-12)  # over home at 0.15 s


def test_a_link_s_motion_is_keyed_to_it_and_its_replicas_share_it():
    config = dict(SMALL, num_envs=8, replicas=2, motion={"kind": "hover"})
    env = WaterAirEnv(EnvConfig(**config))
    alone = WaterAirEnv(EnvConfig(**dict(config, num_envs=2, replicas=1, link_offset=1)))
    td, single = env.reset(), alone.reset()
    for _ in range(4):
        assert torch.equal(env.state.motion[:4], env.state.motion[4:])
        assert torch.equal(alone.state.motion[0], env.state.motion[1])
        assert env.state.motion[:4].unique(dim=0).shape[0] == 4  # and links differ
        td = env.step(td.set("action", torch.zeros(8, 4, dtype=F64)))["next"]
        single = alone.step(single.set("action", torch.zeros(2, 4, dtype=F64)))["next"]


def _world_direction(tilt, attitude, read, up: bool) -> torch.Tensor:
    """Where an end commanded to ``tilt`` ``[n, 2]`` points in the world: the command through the attitude its
    sensor reads, then its true attitude (``[n, 2]`` roll, pitch each), in float64."""
    z = torch.sqrt(1 - (tilt**2).sum(-1, keepdim=True))
    command = torch.cat((tilt, z if up else -z), -1)
    zero = torch.zeros_like(tilt[:, 0])
    true, seen = rotation(attitude[:, 0], attitude[:, 1], zero), rotation(read[:, 0], read[:, 1], zero)
    return torch.einsum("nij,nkj,nk->ni", true, seen, command)


@pytest.mark.parametrize("imu_error", [0.0, 0.01])
def test_each_end_points_through_its_attitude_and_a_perfect_inertial_reading_takes_it_out(imu_error):
    motion = dict(STILL, kind="hover", drone_attitude=0.05, vehicle_attitude=0.04, imu_error=imu_error)
    env = WaterAirEnv(EnvConfig(**SMALL, motion=motion))
    td = env.reset()
    command = torch.tensor([[0.1, -0.05, -0.08, 0.02]], dtype=F64).expand(4, 4)
    for _ in range(3):
        td = env.step(td.set("action", command / env.config.max_tilt))["next"]
    row = attitudes(env.state.motion)
    tx = _world_direction(command[:, :2], row[:, 0:2], row[:, 2:4], up=True)
    rx = _world_direction(command[:, 2:], row[:, 4:6], row[:, 6:8], up=False)
    assert torch.equal(td["pointed"], td["tilt"])  # the ends know they point where they were told
    # the light leaves along the world's pointing: its misalignment from the path is the angle to the departure
    alpha_d = torch.acos((tx * td["departure"]).sum(-1).clamp(max=1.0))
    assert torch.allclose(td["alpha_d"], alpha_d, rtol=1e-9, atol=1e-9)
    assert torch.allclose(td["alpha_a"], torch.acos((-rx * td["arrival"]).sum(-1).clamp(max=1.0)), atol=1e-9)
    error = (tx[:, :2] - command[:, :2]).norm(dim=-1)
    if imu_error == 0.0:
        assert error.max() < 1e-12  # R_true R_readᵀ = I: the compensation leaves no pointing error
    else:  # the reading's error, a few mrad, is the pointing's
        assert error.min() > 1e-4


def test_the_kinematic_reference_points_where_it_is_told_in_the_world_whatever_the_attitude():
    members = [("tracking", "tracking"), ("snell", "flat_snell")]
    assert kinematic(EnvConfig(motion={"kind": "hover"}), members) == ({"actuated": False}, {})  # evaluation's
    motion = dict(STILL, kind="hover", drone_attitude=0.05, imu_error=0.02)
    env = WaterAirEnv(EnvConfig(**SMALL, motion=motion, actuated=False))
    td = env.reset()
    command = torch.tensor([[0.1, -0.05, -0.08, 0.02]], dtype=F64).expand(4, 4)
    td = env.step(td.set("action", command / env.config.max_tilt))["next"]
    tx = torch.cat((command[:, :2], torch.sqrt(1 - (command[:, :2] ** 2).sum(-1, keepdim=True))), -1)
    assert torch.allclose(td["alpha_d"], torch.acos((tx * td["departure"]).sum(-1).clamp(max=1.0)), atol=1e-9)


def test_a_hovering_drone_costs_flat_sea_snell_intensity_it_cannot_see():
    still, moving = (WaterAirEnv(EnvConfig(**SMALL, motion=m)) for m in ({}, {"kind": "hover"}))
    lost = []
    for env in (still, moving):
        td, total = env.reset(), 0.0
        for _ in range(30):
            action = flat_tilts(td["flat_point"], td["tx_position"], td["rx_position"]) / env.config.max_tilt
            td = env.step(td.set("action", action))["next"]
            assert torch.isfinite(td["observation"]).all() and torch.isfinite(td["intensity"]).all()
            total += td["intensity"].mean().item()
        lost.append(total)
    assert lost[1] < lost[0]


@pytest.mark.parametrize(("key", "value"), [("kind", "flying"), ("drift_horizontal", -1.0), ("imu_time", 0.0),
                                            ("vehicle_response", 1.5)])  # fmt: skip
def test_a_motion_key_out_of_range_names_itself(key, value):
    with pytest.raises(ValueError, match=rf"env\.motion\.{key}"):
        EnvConfig(motion={"kind": "hover", key: value})


def test_the_quadrant_tracker_reads_its_spot_in_its_own_body_and_loses_only_what_the_unknown_drift_moves():
    """The quadrant tracker back-projects its reading from where the drone should be (the path: the drift is
    unknown to every controller). With the drone and the vehicle tilting by 3° and 2° and read perfectly, and the
    vehicle in the sea's orbital motion, it holds its still-ends ratio: the spot is read in the drone's body and
    turned into the world through its reading. With the drone's drift (σ 0.5 m at 10 m, its back-projected point
    as far off, ~ω_D at the transmitter) it loses the link, while the beacon tracker, which reads a direction
    and needs no position, holds (measured at S1's point: 0.967 without the drift, 0.24 with it)."""
    tilted = dict(STILL, drone_attitude=0.05, vehicle_attitude=0.035, vehicle_response=1.0)
    config = EnvConfig(sea={"n_wavenumbers": 12, "n_dir": 8}, seed=5, dtype="float64", action_mode="absolute",
                       observation_extras=("spot", "spot_valid", "beacon", "beacon_valid"))  # fmt: skip
    members, ratios = [("aoa", "aoa_tracker"), ("beacon", "beacon_tracker")], {}
    for name, motion in (("still", {}), ("tilted", tilted), ("drifting", dict(STILL, drift_horizontal=0.5))):
        moving = config.replace(motion={"kind": "hover", **motion}) if motion else config
        runs = rollout_policies(moving, members, [(12.0, 0.1, 0.0)], 4, 60, seed=3)
        for label, run in runs.items():
            ratios[name, label] = (run["gain"][..., 10:].mean() / run["gain_upper_bound"][..., 10:].mean()).item()
    assert ratios["still", "aoa"] > 0.9, ratios
    assert abs(ratios["tilted", "aoa"] - ratios["still", "aoa"]) < 0.02, ratios
    assert ratios["drifting", "aoa"] < ratios["still", "aoa"] - 0.2 < ratios["drifting", "beacon"] - 0.2, ratios
