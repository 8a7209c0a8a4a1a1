"""The angle-and-rate Kalman filter (waterair.envs.kalman) against the textbook matrix form written here in float64,
kalman_tracker (waterair.envs.controllers) against the beacon tracker it filters, and the kalman_tracker residual
base (waterair.envs.bases) against the controller."""

from __future__ import annotations

import math

import pytest
import torch
from test_beacon import LATE, TWO_ENDED, paper_physics

from waterair.envs import kalman, tracks
from waterair.envs.config import EnvConfig
from waterair.envs.controllers import BeaconTracker, KalmanTracker
from waterair.envs.env import WaterAirEnv
from waterair.evaluation.rollouts import rollout_policies
from waterair.physics.actuator import Actuator, Axis

F64 = torch.float64


def _textbook(readings, dt, q, r, p0):
    """x = F x, P = F P Fᵀ + q g gᵀ; K = P Hᵀ / (H P Hᵀ + r), x += K (z − H x), P = (I − K H) P; one link."""
    f = torch.tensor([[1.0, dt], [0.0, 1.0]], dtype=F64)
    g = torch.tensor([[dt * dt / 2], [dt]], dtype=F64)
    h = torch.tensor([[1.0, 0.0]], dtype=F64)
    x, p, out = torch.tensor([[readings[0]], [0.0]], dtype=F64), torch.diag(torch.tensor([r, p0], dtype=F64)), []
    for z in readings[1:]:
        x, p = f @ x, f @ p @ f.T + q * g @ g.T
        k = p @ h.T / (h @ p @ h.T + r)
        x, p = x + k * (z - h @ x), (torch.eye(2, dtype=F64) - k @ h) @ p
        out.append((x[:, 0].clone(), p.clone()))
    return out


def test_the_filter_is_the_textbook_kalman_filter():
    generator = torch.Generator().manual_seed(0)
    readings = torch.cumsum(torch.randn(3, 30, generator=generator, dtype=F64) * 0.01, dim=1)  # three links
    q, r, p0 = torch.tensor([4.0, 0.5, 9.0], dtype=F64), torch.tensor([1e-6, 1e-4, 1e-8], dtype=F64), 0.3
    track = kalman.begin(readings[:, 0], r, torch.full((3,), p0, dtype=F64))
    expected = [_textbook(readings[n].tolist(), 0.05, q[n].item(), r[n].item(), p0) for n in range(3)]
    for step in range(1, 30):
        track, inside = kalman.update(kalman.predict(track, 0.05, q), readings[:, step], r, gate=1e9)
        assert inside.all()
        for n in range(3):
            state, covariance = expected[n][step - 1]
            torch.testing.assert_close(track.state[n], state, rtol=1e-10, atol=1e-15)
            torch.testing.assert_close(track.covariance[n], covariance, rtol=1e-10, atol=1e-18)


def test_on_a_noisy_ramp_the_track_learns_the_rate_and_predicts_better_than_the_last_reading():
    generator, dt, noise = torch.Generator().manual_seed(1), 0.05, 1e-3
    times = torch.arange(80, dtype=F64) * dt
    truth = 0.02 + 0.2 * times.unsqueeze(0).expand(500, -1)  # 500 links, 0.2 rad/s
    readings = truth + noise * torch.randn(truth.shape, generator=generator, dtype=F64)
    variance = torch.full((500,), noise**2, dtype=F64)
    track = kalman.begin(readings[:, 0], variance, torch.full((500,), 1.0, dtype=F64))
    ahead, last = [], []
    for step in range(1, 79):
        track, _ = kalman.update(kalman.predict(track, dt, torch.full((500,), 1e-4, dtype=F64)), readings[:, step],
                                 variance, gate=4.0)  # fmt: skip
        if step > 40:
            ahead.append(kalman.ahead(track, dt) - truth[:, step + 1])
            last.append(readings[:, step] - truth[:, step + 1])
    assert (track.state[:, 1] - 0.2).abs().mean() < 0.01
    assert torch.stack(ahead).square().mean().sqrt() < 0.2 * torch.stack(last).square().mean().sqrt()


def test_a_jump_beyond_the_gate_is_refused():
    track = kalman.begin(
        torch.zeros(2, dtype=F64), torch.full((2,), 1e-6, dtype=F64), torch.full((2,), 1e-6, dtype=F64)
    )
    track = kalman.predict(track, 0.05, torch.zeros(2, dtype=F64))
    spread = math.sqrt(track.covariance[0, 0, 0].item() + 1e-6)
    _, inside = kalman.update(track, torch.tensor([3.9 * spread, 4.1 * spread], dtype=F64), torch.full((2,), 1e-6,
                              dtype=F64), gate=4.0)  # fmt: skip
    assert inside.tolist() == [True, False]


def test_a_sampled_axis_lags_a_ramp_by_its_closed_form_and_a_fast_one_not_at_all():
    axis, dt = Axis(natural_frequency=8.0, damping=0.7), 0.05
    angle = rate = 0.0
    (p00, p01), (p10, p11) = axis.transition(dt)
    for step in range(1, 400):  # each step commands the ramp's value at its end
        angle, rate = step * dt + p00 * (angle - step * dt) + p01 * rate, p10 * (angle - step * dt) + p11 * rate
    assert math.isclose(axis.sampled_lag(dt), step * dt - angle, rel_tol=1e-9)
    slow = Axis(natural_frequency=2.0, damping=0.7)
    assert math.isclose(slow.sampled_lag(1e-3), 2 * 0.7 / slow.omega - 0.5e-3, rel_tol=1e-4)  # continuous, less Δt/2
    assert abs(Actuator(kind="gimbal_fsm").lag(dt)) < 1e-9 and Actuator().lag(dt) == 0.0


def test_on_a_calm_sea_the_kalman_tracker_points_as_the_beacon_tracker_once_its_readings_settle():
    """A calm sea, no noise: the readings move only while the ends acquire (the centroid's lean toward the beam's
    axis), so the filter points within 0.02 mrad of the tracker and ever closer to it."""
    config = EnvConfig(num_envs=4, seed=2, dtype="float64", observation_extras=TWO_ENDED, sea={"flat": True})
    env = WaterAirEnv(config.replace(latency_steps=1))
    kalman_tracker, tracker = KalmanTracker(env), BeaconTracker(env)
    td, apart = env.reset(), []
    for _ in range(12):
        ahead, now = torch.stack(kalman_tracker.directions(td)), torch.stack(tracker.directions(td))
        apart.append((ahead - now).abs().max().item())
        action = env.action_for_pointing(now[0], now[1], td["tilt"], td.get("base_tilt", None))
        td = env.step(td.set("action", action))["next"]
    assert apart[0] < 1e-12 and max(apart) < 2e-5  # its first reading is the tracker's
    assert all(b < a for a, b in zip(apart[2:], apart[3:], strict=False)) and apart[-1] < 0.3 * max(apart)


def test_pointing_ahead_through_slewing_gimbals_the_kalman_tracker_beats_the_beacon_tracker():
    """The paper's physics, a 10 mrad beam, the drone's readings one step late, both noisy, an 8 Hz gimbal at each
    end: ratio to the bound above the beacon tracker's at every wind (measured +0.04, +0.13, +0.15 at 4, 12, 20 m/s)."""
    config = EnvConfig().replace(
        **paper_physics(n_freq=16, n_dir=8), observation_extras=TWO_ENDED, compile_kernel=False, **LATE
    )
    points = [(4.0, 0.1, 0.0), (12.0, 0.1, 0.0), (20.0, 0.1, 0.0)]
    members = [("tracker", "beacon_tracker"), ("kalman", "kalman_tracker")]
    config = config.replace(optics={"divergence": 0.01}, actuator={"kind": "gimbal"})
    runs = rollout_policies(config, members, points, 8, 60, seed=3)
    ratio = {label: run["gain"].double().mean((0, 2)) / run["gain_upper_bound"].double().mean((0, 2)) for
             label, run in runs.items()}  # fmt: skip
    assert bool((ratio["kalman"] > ratio["tracker"] + 0.03).all()), ratio


def test_following_a_drone_at_constant_velocity_the_kalman_tracker_has_no_steady_lag_and_the_reactive_one_its_own():
    """A calm sea, ideal sensing two steps late, the drone crossing at 1.5 m/s, nothing else moving: the reactive
    tracker's receiver trails the arrival by the angle it turns over the readings' age, (latency + 1) Δt times its
    rate; the filter, which learns that rate, trails by a small part of it."""
    still = dict(drift_horizontal=0.0, drift_vertical=0.0, drone_attitude=0.0, vehicle_attitude=0.0, imu_error=0.0,
                 vehicle_response=0.0, transit_speed=1.5)  # fmt: skip
    config = EnvConfig(num_envs=2, seed=2, dtype="float64", observation_extras=TWO_ENDED, sea={"flat": True},
                       latency_steps=2, max_steps=80, motion={"kind": "transit", **still})  # fmt: skip
    errors = {}
    for name, kind in (("reactive", BeaconTracker), ("kalman", KalmanTracker)):
        env = WaterAirEnv(config)
        controller, td, trace = kind(env), env.reset(), []
        for _ in range(60):
            tx_dir, rx_dir = controller.directions(td)
            td = env.step(td.set("action", env.action_for_pointing(tx_dir, rx_dir, td["tilt"], td.get("base_tilt"))))
            td = td["next"]
            trace.append((td["alpha_a"].clone(), td["arrival"].clone()))
        errors[name] = torch.stack([alpha for alpha, _ in trace[-20:]]).mean().item()
        turn = torch.stack([arrival for _, arrival in trace[-21:]])
        rate = torch.acos((turn[1:] * turn[:-1]).sum(-1).clamp(max=1.0)).mean().item() / env.config.dt
    lag = rate * (config.latency_steps + 1) * config.dt
    assert errors["reactive"] == pytest.approx(lag, rel=0.25)
    assert errors["kalman"] < 0.2 * errors["reactive"]


@pytest.mark.parametrize("phi", [0.1, 0.8, 2.0])
def test_the_share_of_the_rate_that_carries_over_is_sin_phi_over_phi_for_a_sampled_sinusoid_and_whole_for_a_ramp(phi):
    """x_k = sin(k φ) with its exact rate: Σ a b / Σ b² over many steps tends to E[cos θ (sin(θ + φ) − sin θ)] φ /
    (φ² E[cos² θ]) = sin φ / φ; a ramp carries over whole, a reading that only jitters back and forth not at all."""
    steps = torch.arange(4000, dtype=torch.float64)
    x, foretold = torch.sin(steps * phi), torch.cos(steps * phi) * phi  # the rate at k, times the step (1)
    sums = kalman.Carry(torch.zeros(()), torch.zeros(()))
    for k in range(1, steps.numel()):
        sums = kalman.carry(sums, x[k] - x[k - 1], foretold[k - 1], 1.0)
    assert kalman.share(sums).item() == pytest.approx(math.sin(phi) / phi, abs=2e-3)
    ramp = kalman.carry(kalman.Carry(torch.zeros(()), torch.zeros(())), torch.tensor(0.3), torch.tensor(0.3), 0.9)
    assert kalman.share(ramp).item() == pytest.approx(1.0)
    jitter = kalman.Carry(torch.zeros(()), torch.zeros(()))
    for k in range(50):  # the reading alternates, its rate foretells the last move again
        jitter = kalman.carry(jitter, torch.tensor((-1.0) ** k), torch.tensor((-1.0) ** (k + 1)), 0.95)
    assert kalman.share(jitter).item() == 0.0
    assert kalman.share(kalman.Carry(torch.zeros(()), torch.zeros(()))).item() == 1.0  # nothing foretold yet


def test_an_episode_starts_with_none_of_the_rate_carried_over_so_a_guessed_rate_is_not_pointed_along():
    """Its first readings give the filter a rate that is the sea's prior, not a measurement: pointed along at once,
    a noisy start loses the acquisition. The carried share starts at 0 with one step's weight (not the fallback of
    nothing foretold, 1), and the first move a settled rate foretells takes it most of the way up."""
    config = EnvConfig(num_envs=3, seed=4, observation_extras=TWO_ENDED, compile_kernel=False)
    env = WaterAirEnv(config.replace(**paper_physics(n_freq=8, n_dir=4)))
    tracker = KalmanTracker(env)
    td = env.reset()
    tracker.directions(td)
    assert tracker.tracks is not None
    carried = tracker.tracks.carried
    assert bool((carried.foretold > 0).all()) and bool((kalman.share(carried) == 0).all())
    prior = carried.foretold  # faded once: one step's weight, λ (rate Δt)²
    move = 3.0 * prior.sqrt()  # a move three times the prior's step, foretold exactly
    after = kalman.carry(carried, move, move, 1.0)
    assert torch.allclose(kalman.share(after), torch.full_like(prior, 9.0 / 10.0))


def test_a_track_started_again_by_a_jump_points_ahead_only_once_it_has_held_ready_readings(monkeypatch):
    """The drone crossing a calm sea at 1.5 m/s, ideal sensing: the filter points the receiver ahead of its
    reading by about a step's turn. At step 30 the reading jumps by 20 mrad (as where the light moves to another
    refraction point): the track starts again, and until READY readings in a row have fallen within its gate it
    points at its filtered angle, within a tenth of a step's turn of the reading, not along a rate it took from
    the jump; then ahead again."""
    still = dict(drift_horizontal=0.0, drift_vertical=0.0, drone_attitude=0.0, vehicle_attitude=0.0, imu_error=0.0,
                 vehicle_response=0.0, transit_speed=1.5)  # fmt: skip
    config = EnvConfig(num_envs=2, seed=2, dtype="float64", observation_extras=TWO_ENDED, sea={"flat": True},
                       max_steps=80, motion={"kind": "transit", **still})  # fmt: skip
    env = WaterAirEnv(config)
    jump, readings = 30, []
    read = BeaconTracker.directions

    def jumped(self, tensordict):  # the receiver's reading, 20 mrad off from step `jump` on
        tx, rx = read(self, tensordict)
        if len(readings) >= jump:
            rx = torch.nn.functional.normalize(rx + torch.tensor([0.02, 0.0, 0.0], dtype=rx.dtype), dim=-1)
        readings.append(rx)
        return tx, rx

    monkeypatch.setattr(BeaconTracker, "directions", jumped)
    controller, td, ahead = KalmanTracker(env), env.reset(), []
    for _ in range(50):
        tx_dir, rx_dir = controller.directions(td)
        ahead.append(torch.linalg.vector_norm(rx_dir - readings[-1], dim=-1).max().item())
        td = env.step(td.set("action", env.action_for_pointing(tx_dir, rx_dir, td["tilt"], td.get("base_tilt"))))
        td = td["next"]
    turn = torch.linalg.vector_norm(readings[jump - 1] - readings[jump - 2], dim=-1).max().item()
    assert 0.5 * turn < ahead[jump - 1] < 2.0 * turn  # before the jump: ahead by about a step's turn
    held = ahead[jump : jump + KalmanTracker.READY]  # the jump's step, then until READY readings within the gate
    assert max(held) < 0.1 * turn, held
    assert min(ahead[jump + KalmanTracker.READY + 2 :]) > 0.5 * turn, ahead  # ahead again


def test_the_kalman_tracker_base_inside_the_step_points_where_the_controller_does_links_reset_alone_included():
    """Residual actions of 0 on ``env.residual_base=kalman_tracker``: the base's tilts each step are the controller's
    on the same observations, link by link (float64), the ends moving, a gimbal with a fine mirror at each end, the
    drone's readings two steps late and both noisy, and two links reset on their own mid-episode (the tracks the
    state keeps start again there, and only there). The filter matters: it points up to mrad off the beacon
    tracker's reading."""
    config = EnvConfig(num_envs=4, seed=5, dtype="float64", observation_extras=TWO_ENDED, compile_kernel=False,
                       action_mode="residual", residual_base="kalman_tracker", latency_steps=2,
                       spot_noise_rad=1e-3, beacon_noise_rad=1e-3, motion={"kind": "hover"},
                       actuator={"kind": "gimbal_fsm"})  # fmt: skip
    env = WaterAirEnv(config.replace(**paper_physics(n_freq=8, n_dir=4)))
    controller, reactive, td = KalmanTracker(env), BeaconTracker(env), env.reset()
    apart = []
    for step in range(45):
        expected = torch.cat([each[:, :2] for each in controller.directions(td)], -1)
        torch.testing.assert_close(td["base_tilt"], expected, rtol=0, atol=1e-12)
        apart.append((expected - torch.cat([each[:, :2] for each in reactive.directions(td)], -1)).abs().max())
        td = env.step(td.set("action", torch.zeros(4, 4, dtype=F64)))["next"]
        if step == 25:
            td = env.reset(td.clone().set("_reset", torch.tensor([True, False, True, False]).unsqueeze(-1)))
    assert max(apart) > 1e-4, apart


@pytest.mark.parametrize(
    ("own", "ways", "tracked"),
    [
        ("kalman_tracker", ({"residual_base": "beacon_tracker"}, {"residual_base": "aoa_tracker"}), True),
        ("aoa_tracker", ({}, {"action_mode": "absolute", "residual_base": "kalman_tracker"}), False),
        ("aoa_tracker", ({}, {"residual_base": "kalman_tracker"}), True),
    ],
    ids=["its-own-base-read", "a-replicas-unread", "a-replicas-residual"],
)
def test_the_state_keeps_tracks_where_a_kalman_base_is_read_whatever_the_replicas_ways(own, ways, tracked):
    """The batch's own base is read every step (its tilts are reported in every action mode), a replica's only where
    it acts residually: the step keeps and follows the tracks exactly then, and steps either way."""
    config = EnvConfig(num_envs=4, seed=1, observation_extras=TWO_ENDED, compile_kernel=False, action_mode="residual",
                       residual_base=own, replicas=2, replica_actions=ways, max_steps=6)  # fmt: skip
    env = WaterAirEnv(config.replace(**paper_physics(n_freq=8, n_dir=4)))
    td = env.reset()
    for _ in range(4):
        td = env.step(td.set("action", torch.zeros(4, 4)))["next"]
    assert (env.constants.tracks is not None) == tracked
    assert env.state.tracks.shape[1:] == ((2, 2, tracks.WIDTH) if tracked else (0,))
    assert bool(torch.isfinite(td["base_tilt"]).all() and torch.isfinite(td["observation"]).all())
    if tracked:  # followed: every link's tracks hold the readings since its reset
        assert bool((tracks.Tracks.unpacked(env.state.tracks).held > 0).any())
