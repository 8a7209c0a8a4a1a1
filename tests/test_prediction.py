"""The prediction bound (:mod:`waterair.envs.prediction`): its least-squares predictor against processes whose
next step is a closed form of their past, and the reference between ``tracking`` and the upper bound."""

import math

import pytest
import torch

from tests.conftest import preset_config
from waterair.envs import prediction
from waterair.envs.baselines import PreviousPathTracking
from waterair.envs.config import EnvConfig
from waterair.envs.env import WaterAirEnv
from waterair.envs.prediction import ORDER, PredictionBound, features, fit, point_count
from waterair.evaluation.rollouts import rollout_policies


def sinusoids(frequencies, batch: int, steps: int, seed: int) -> torch.Tensor:
    """``[batch, steps, 4]``: each component a sum of sinusoids of ``frequencies`` (rad per step, one tuple per
    component), random amplitudes and phases per sequence, in float64."""
    generator = torch.Generator().manual_seed(seed)
    t = torch.arange(steps, dtype=torch.float64)
    components = []
    for omegas in frequencies:
        total = torch.zeros(batch, steps, dtype=torch.float64)
        for omega in omegas:
            amplitude = torch.rand(batch, 1, generator=generator, dtype=torch.float64) + 0.5
            phase = 2 * math.pi * torch.rand(batch, 1, generator=generator, dtype=torch.float64)
            total += amplitude * torch.sin(omega * t + phase)
        components.append(total)
    return 1e-2 * torch.stack(components, dim=-1)


def predicted(weights: torch.Tensor, states: torch.Tensor, calm: torch.Tensor) -> torch.Tensor:
    """The prediction of every step from ORDER + 1 on ``[B, T - ORDER - 1, 4]`` with one group's ``weights``."""
    history = states.unfold(1, ORDER + 1, 1).flip(-1).transpose(-1, -2)[:, :-1]  # newest first
    x = features(history, calm[:, ORDER:-1])
    return history[:, :, 0] + x @ weights.transpose(-1, -2)


FREQUENCIES = ((0.3, 0.71), (0.5,), (0.2, 0.9), (1.1, 0.4))
"""Per component at most ORDER / 2 sinusoids: each then obeys a linear recurrence over ORDER + 1 of its past
values, Π_k (z² − 2 cos ω_k z + 1), which the predictor's moves and level span."""


def test_the_predictor_forecasts_sums_of_sinusoids_to_rounding_on_sequences_it_was_not_fitted_on():
    states = sinusoids(FREQUENCIES, 20, 120, seed=0)
    calm = torch.zeros_like(states)
    weights, _ = fit(states, calm, torch.ones(states.shape[:2], dtype=torch.bool), torch.zeros(20, dtype=torch.long), 1)
    fresh = sinusoids(FREQUENCIES, 4, 80, seed=1)
    error = predicted(weights[0], fresh, torch.zeros_like(fresh)) - fresh[:, ORDER + 1 :]
    assert error.abs().max() < 1e-6 * fresh.abs().max()  # the ridge, on rank-deficient lags
    tracking_error = fresh[:, ORDER + 1 :] - fresh[:, ORDER:-1]
    assert tracking_error.abs().max() > 1e-3 * fresh.abs().max()  # not a process that stands still


def test_each_group_is_fitted_on_its_own_sequences():
    slow, fast = ((0.1,),) * 4, ((0.8,),) * 4
    states = torch.cat((sinusoids(slow, 20, 100, seed=2), sinusoids(fast, 20, 100, seed=3)))
    groups = torch.arange(40) // 20
    weights, _ = fit(states, torch.zeros_like(states), torch.ones(40, 100, dtype=torch.bool), groups, 2)
    test_slow, test_fast = sinusoids(slow, 2, 60, seed=4), sinusoids(fast, 2, 60, seed=5)
    for group, sequence in ((0, test_slow), (1, test_fast)):
        own = predicted(weights[group], sequence, torch.zeros_like(sequence)) - sequence[:, ORDER + 1 :]
        other = predicted(weights[1 - group], sequence, torch.zeros_like(sequence)) - sequence[:, ORDER + 1 :]
        assert own.abs().max() < 1e-6 * sequence.abs().max()
        assert other.abs().max() > 1e-3 * sequence.abs().max()


def test_a_path_that_stands_still_is_predicted_to_stay_and_unusable_steps_are_left_out():
    still = torch.full((3, 40, 4), 0.05, dtype=torch.float64) + torch.arange(3, dtype=torch.float64)[:, None, None]
    calm = torch.zeros_like(still)
    weights, _ = fit(still, calm, torch.ones(3, 40, dtype=torch.bool), torch.zeros(3, dtype=torch.long), 1)
    assert torch.equal(weights, torch.zeros_like(weights))  # tracking: ŝ = s exactly
    moving = sinusoids(FREQUENCIES, 3, 60, seed=6)
    valid = torch.ones(3, 60, dtype=torch.bool)
    valid[1, 30] = False  # a step whose path was not found: its garbage must not enter the fit
    corrupted = moving.clone()
    corrupted[1, 30] = 1e6
    clean, _ = fit(moving, torch.zeros_like(moving), valid, torch.zeros(3, dtype=torch.long), 1)
    garbled, _ = fit(corrupted, torch.zeros_like(moving), valid, torch.zeros(3, dtype=torch.long), 1)
    torch.testing.assert_close(garbled, clean, rtol=1e-9, atol=1e-12)


def test_sequences_too_short_for_a_history_give_tracking():
    """A rollout shorter than ORDER + 2 steps (a tiny scenario) calibrates nothing: W = 0, no gate."""
    short = sinusoids(FREQUENCIES, 3, ORDER + 1, seed=9)
    weights, gates = fit(short, torch.zeros_like(short), torch.ones(3, ORDER + 1, dtype=torch.bool),
                         torch.zeros(3, dtype=torch.long), 1)  # fmt: skip
    assert weights.shape == (1, 4, 4 * ORDER + 5) and not weights.any() and torch.isinf(gates).all()


def test_jumps_between_refraction_points_neither_enter_the_fit_nor_are_extrapolated():
    """Sinusoids with a jump now and then (the light on another refraction point for a step): the gate is GATE
    times the median move, the windows with a jump are left out, and the predictor still forecasts the smooth
    stretches to rounding, where a fit over every window is thrown off by the jumps."""
    smooth_part = sinusoids(FREQUENCIES, 20, 150, seed=7)
    jumps = torch.zeros_like(smooth_part)
    generator = torch.Generator().manual_seed(8)
    for sequence in range(20):
        at = torch.randint(ORDER + 2, 150, (3,), generator=generator)
        for step in at.tolist():
            jumps[sequence, step] += 0.2 * (torch.rand(4, generator=generator, dtype=torch.float64) - 0.5)
    states, calm, valid = smooth_part + jumps, torch.zeros_like(smooth_part), torch.ones(20, 150, dtype=torch.bool)
    groups = torch.zeros(20, dtype=torch.long)
    weights, gates = fit(states, calm, valid, groups, 1)
    moves = prediction.end_moves(states[:, 1:] - states[:, :-1])
    window = ORDER + 2
    torch.testing.assert_close(gates, prediction.GATE * moves[:, window - 2 :].median().reshape(1), rtol=0.2, atol=0)
    history = states.unfold(1, ORDER + 1, 1).flip(-1).transpose(-1, -2)[:, :-1]
    truth = states[:, ORDER + 1 :]
    clean = prediction.smooth(torch.cat((truth.unsqueeze(2), history), dim=2), gates[0])  # no jump, target's too
    error = predicted(weights[0], states, calm) - truth
    assert clean.float().mean() > 0.5 and error[clean].abs().max() < 1e-6 * smooth_part.abs().max()
    prediction_gate, prediction.GATE = prediction.GATE, math.inf
    try:
        ungated, _ = fit(states, calm, valid, groups, 1)
    finally:
        prediction.GATE = prediction_gate
    assert (predicted(ungated[0], states, calm) - truth)[clean].abs().max() > 1e-4


def test_a_links_scenario_point_is_its_index_modulo_the_listed_values():
    config = preset_config("quadrant", "ideal", 12)
    assert point_count(config) == 1  # every link draws its own: one pooled predictor
    listed = config.replace(wind_values=(4.0, 12.0, 20.0), offset_values=(0.1, 0.2, 0.3), wind_range=None,
                            offset_range=None)  # fmt: skip
    assert point_count(listed) == 3


STILL = {"motion": {"kind": "static"}, "actuator": {"kind": "ideal"}, "action_mode": "absolute"}
"""Ends that stand still and point at once, where commanded: tracking and the bound act through nothing but the
sea."""
POINT = {"wind": 12.0, "wind_range": None, "offset_range": None, "divergence_values": (0.01,)}


def rollout(config, policy_class, steps: int):
    env = WaterAirEnv(config)
    policy = policy_class(env)
    env.set_seed(5)
    with torch.no_grad():
        return env.rollout(steps, policy, break_when_any_done=False)


@pytest.fixture
def few_calibration_links(monkeypatch):
    monkeypatch.setattr(prediction, "CALIBRATION_LINKS", 8)


def test_on_a_frozen_sea_the_prediction_bound_points_as_tracking(few_calibration_links):
    """A sea that does not move over the episode (dt 1 ns), the ends still: the paths stay but for the solver's
    tolerance, and the bound points as ``tracking`` does to that tolerance."""
    config = preset_config("quadrant", "ideal", 4, **STILL, **POINT, dt=1e-9, max_steps=30)
    ours, theirs = rollout(config, PredictionBound, 30), rollout(config, PreviousPathTracking, 30)
    assert theirs["action"][:, 1:].sub(theirs["action"][:, :-1]).abs().max() < 1e-6  # the paths stand still
    torch.testing.assert_close(ours["action"], theirs["action"], rtol=0, atol=1e-6)
    torch.testing.assert_close(ours["next", "gain"], theirs["next", "gain"], rtol=1e-5, atol=0)


def test_in_an_evaluation_it_lies_between_tracking_and_the_upper_bound_calibrated_per_point(monkeypatch):
    """Through the evaluation's rollouts on the moving defaults (it points in the world, as ``tracking``), a 10 mrad
    beam at 4 and 12 m/s: one predictor per scenario point, fitted on CALIBRATION_LINKS links over as many steps
    as the rollout (a crossing drone calibrated where it crosses); at each point, once its history is full, ahead
    of tracking's step of delay in mean gain and behind the upper bound."""
    monkeypatch.setattr(prediction, "CALIBRATION_LINKS", 4)
    calibrated = []
    fitted = prediction.fit
    monkeypatch.setattr(prediction, "fit", lambda states, *a: calibrated.append(states.shape) or fitted(states, *a))
    config = EnvConfig().replace(optics={"divergence": 0.01}, compile_kernel=False)
    points = [(4.0, 0.1, 0.0), (12.0, 0.1, 0.0)]
    runs = rollout_policies(config, [("tracking", "tracking"), ("bound", "prediction_bound")], points, 4, 60, seed=3)
    assert calibrated == [torch.Size([2 * 4, 61, 4])]  # two points' links, the reset's path and 60 steps
    tracked, predicted_gain, bound = (
        runs[label][key][..., ORDER + 1 :].mean((0, 2))
        for label, key in (("tracking", "gain"), ("bound", "gain"), ("bound", "gain_upper_bound"))
    )
    assert (tracked < predicted_gain).all() and (predicted_gain < bound).all(), (tracked, predicted_gain, bound)


def test_the_predictor_forecasts_sums_of_sinusoids_several_steps_ahead_to_rounding():
    """Over a horizon of 3 steps (an end whose reading comes 2 steps late): the recurrence of the sinusoids carries
    any number of steps, and the path known 3 steps before is far off."""
    states = sinusoids(FREQUENCIES, 20, 120, seed=10)
    valid, groups = torch.ones(states.shape[:2], dtype=torch.bool), torch.zeros(20, dtype=torch.long)
    weights, _ = fit(states, torch.zeros_like(states), valid, groups, 1, 3)
    fresh = sinusoids(FREQUENCIES, 4, 80, seed=11)
    history = fresh.unfold(1, ORDER + 1, 1).flip(-1).transpose(-1, -2)[:, :-3]  # newest first, 3 steps before
    forecast = history[:, :, 0] + features(history, torch.zeros_like(history[:, :, 0])) @ weights[0].T
    truth = fresh[:, ORDER + 3 :]
    assert (forecast - truth).abs().max() < 1e-6 * fresh.abs().max()
    assert (history[:, :, 0] - truth).abs().max() > 1e-2 * fresh.abs().max()
    assert not torch.allclose(weights, fit(states, torch.zeros_like(states), valid, groups, 1)[0])


def test_each_ends_delay_is_a_step_its_readings_latency_and_its_actuators_lag():
    """The receiver's reading comes ``latency_steps`` late, the transmitter's beacon at once; a gimbal alone trails a
    turning command by its ramp lag, 2ζ/ω_n less half the step it holds the command over (zero-order hold); a fine
    mirror by nothing a step can see."""
    ideal = preset_config("quadrant", "ideal", 4, **STILL)
    assert prediction.delays(ideal) == (1.0, 1.0)
    assert prediction.delays(ideal.replace(latency_steps=2)) == (1.0, 3.0)
    mirrored = ideal.replace(actuator={"kind": "gimbal_fsm"}, latency_steps=1)
    assert prediction.delays(mirrored) == (1.0, 2.0) and prediction.delays(mirrored.replace(dt=0.005)) == (1.0, 2.0)
    dt = 1e-4
    gimbal = ideal.replace(actuator={"kind": "gimbal"}, dt=dt)
    ramp = 2 * gimbal.actuator.gimbal_damping / (2 * math.pi * gimbal.actuator.gimbal_natural_frequency) - dt / 2
    transmitter, receiver = prediction.delays(gimbal)
    assert receiver == transmitter and transmitter - 1 == pytest.approx(ramp / dt, rel=1e-3)
    assert prediction.spanned(2.25) == ((2, 0.75), (3, 0.25)) and prediction.spanned(3.0) == ((3, 1.0),)


def test_a_late_reading_is_forecast_over_its_delay_and_the_other_end_is_left_as_it_was(few_calibration_links):
    """The receiver's reading 2 steps late: the bound forecasts its pointing over 3 steps, further off the next path
    than over 1 and nearer than the path it knows (its predictors zeroed: the path 3 steps old), once its history
    is full; the transmitter, whose beacon is never late, points exactly as with no latency. 12 m/s, 4 links."""
    config = preset_config("quadrant", "ideal", 4, **STILL, **POINT, max_steps=80)
    late = config.replace(latency_steps=2)

    def unpredicted(env):
        bound = PredictionBound(env)
        assert bound.horizons == [1, 3]
        bound.coefficients = {k: torch.zeros_like(w) for k, w in bound.coefficients.items()}
        return bound

    def errors(config, policy):  # each end's pointing off the path of its step, rms [2], and the pointing
        run = rollout(config, policy, 80)["next"][:, ORDER + 3 :]
        miss = (run["tilt"] - prediction.tilts(run["departure"], run["arrival"])).unflatten(-1, (2, 2))
        return miss.square().sum(-1).mean((0, 1)).sqrt(), run["tilt"]

    (now, pointed_now), (later, pointed_later), (known, _) = (
        errors(c, policy) for c, policy in ((config, PredictionBound), (late, PredictionBound), (late, unpredicted))
    )
    assert now[1] < later[1] < known[1], (now, later, known)
    assert torch.equal(pointed_later[..., :2], pointed_now[..., :2])
