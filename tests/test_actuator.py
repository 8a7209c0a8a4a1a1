"""Pointing actuators (waterair.physics.actuator) against the second-order closed form and their limits, float64."""

import math

import pytest
import torch

from waterair.physics.actuator import Axis, AxisState, PairState, command, respond, respond_pair

F64 = torch.float64


def _step_response(t: float, f_n: float, zeta: float) -> float:
    """θ(t) / u of θ'' = ω²(u − θ) − 2ζωθ' from rest: the textbook forms for ζ < 1, = 1, > 1."""
    w = 2 * math.pi * f_n
    if zeta < 1:
        wd = w * math.sqrt(1 - zeta**2)
        return 1 - math.exp(-zeta * w * t) * (math.cos(wd * t) + zeta / math.sqrt(1 - zeta**2) * math.sin(wd * t))
    if zeta == 1:
        return 1 - math.exp(-w * t) * (1 + w * t)
    r1, r2 = -w * (zeta - math.sqrt(zeta**2 - 1)), -w * (zeta + math.sqrt(zeta**2 - 1))
    return 1 + (r2 * math.exp(r1 * t) - r1 * math.exp(r2 * t)) / (r1 - r2)


def _run(axis: Axis, targets, dt: float) -> list[AxisState]:
    state, out = AxisState(torch.zeros(1, dtype=F64), torch.zeros(1, dtype=F64)), []
    for target in targets:
        state = respond(axis, state, torch.tensor([target], dtype=F64), dt)
        out.append(state)
    return out


@pytest.mark.parametrize("zeta", [0.3, 0.7, 1.0, 2.0])
def test_a_step_follows_the_second_order_closed_form(zeta):
    axis, dt = Axis(natural_frequency=4.0, damping=zeta), 0.01
    states = _run(axis, [0.2] * 40, dt)
    for n, state in enumerate(states, start=1):
        assert state.angle.item() == pytest.approx(0.2 * _step_response(n * dt, 4.0, zeta), rel=1e-9, abs=1e-13)


@pytest.mark.parametrize(("f_n", "zeta", "dt"), [(8.0, 0.7, 0.05), (585.0, 0.4, 0.05), (2.0, 1.0, 0.05),
                                                  (2.0, 3.0, 0.05), (1e5, 10.0, 10.0), (1e5, 0.01, 1e-6)])  # fmt: skip
def test_the_closed_form_transition_is_the_matrix_exponential_and_never_overflows(f_n, zeta, dt):
    axis = Axis(natural_frequency=f_n, damping=zeta)
    w = axis.omega
    expected = torch.linalg.matrix_exp(torch.tensor([[0.0, 1.0], [-(w**2), -2 * zeta * w]], dtype=F64) * dt)
    got = torch.tensor(axis.transition(dt), dtype=F64)
    assert torch.isfinite(got).all()
    assert torch.allclose(got, expected, rtol=1e-9, atol=1e-10 * expected.abs().max().item())


def test_a_held_ramp_is_the_sum_of_its_steps():
    axis, dt = Axis(natural_frequency=3.0, damping=0.6), 0.05
    targets = [0.01 * (n + 1) for n in range(30)]  # a ramp, each command held for its step
    states = _run(axis, targets, dt)
    for n, state in enumerate(states, start=1):  # superposition: a step of 0.01 starting at each step
        expected = sum(0.01 * _step_response((n - j) * dt, 3.0, 0.6) for j in range(n))
        assert state.angle.item() == pytest.approx(expected, rel=1e-9)


def test_a_rate_and_acceleration_limited_slew_never_exceeds_them_and_arrives_no_sooner_than_they_allow():
    axis, dt = Axis(range=0.8, rate=2.0, acceleration=20.0, natural_frequency=8.0, damping=0.9), 0.05
    states = _run(axis, [0.6] * 40, dt)
    rates = [0.0] + [s.rate.item() for s in states]
    assert max(abs(r) for r in rates) <= 2.0
    assert all(abs(b - a) <= 20.0 * dt + 1e-12 for a, b in zip(rates, rates[1:], strict=False))
    arrived = next(n for n, s in enumerate(states, start=1) if abs(s.angle.item() - 0.6) < 0.01)
    assert arrived * dt >= 0.59 / 2.0  # 0.6 rad at 2 rad/s: no sooner than 0.3 s
    assert abs(states[-1].angle.item() - 0.6) < 1e-3  # and it gets there
    unlimited = _run(Axis(range=0.8, natural_frequency=8.0, damping=0.9), [0.6] * 40, dt)
    assert max(abs(s.rate.item()) for s in unlimited) > 2.0  # the limit is what held it


def test_a_small_command_on_a_limited_axis_is_the_exact_response():
    limited, free = Axis(rate=5.0, acceleration=500.0, natural_frequency=2.0), Axis(natural_frequency=2.0)
    a, b = _run(limited, [0.001] * 10, 0.05), _run(free, [0.001] * 10, 0.05)
    assert [s.angle.item() for s in a] == [s.angle.item() for s in b]


@pytest.mark.parametrize("dtype", [torch.float32, F64])
def test_where_no_limit_binds_every_link_takes_the_exact_response_bit_for_bit(dtype):
    """Many links, each well inside the default gimbal's rate and acceleration limits: each is the unlimited
    axis's response to the last bit. Taking rate + (free rate - rate) for the free rate, the sub-steps once
    found a limit binding on about one sub-step in 15 (two thirds of the links) and replaced the exact response
    by their approximation."""
    limited = Axis(rate=2.1, acceleration=35.0, natural_frequency=8.0)
    free = Axis(natural_frequency=8.0)
    g = torch.Generator().manual_seed(5)
    angle, rate = 0.01 * torch.randn(4096, generator=g, dtype=dtype), 0.05 * torch.randn(4096, generator=g, dtype=dtype)
    target = angle + 0.002 * torch.randn(4096, generator=g, dtype=dtype)
    got, want = (
        respond(limited, AxisState(angle, rate), target, 0.05),
        respond(free, AxisState(angle, rate), target, 0.05),
    )
    assert want.rate.abs().max() < 0.5 * limited.rate  # nowhere near the rate limit, nor (35 rad/s²) the acceleration's
    assert torch.equal(got.angle, want.angle) and torch.equal(got.rate, want.rate)


def test_the_range_and_the_resolution_hold():
    axis = Axis(range=0.02, natural_frequency=50.0, damping=0.3, resolution=1e-4)
    states = _run(axis, [0.5, -0.5, 0.5, 0.0123456], 0.001)
    assert all(abs(s.angle.item()) <= 0.02 for s in states)
    assert command(axis, torch.tensor([0.0123456], dtype=F64)).item() == pytest.approx(0.0123, abs=1e-15)
    assert command(axis, torch.tensor([0.3], dtype=F64)).item() == 0.02


def test_a_fine_mirror_on_a_slow_gimbal_points_where_commanded_within_its_range():
    gimbal = Axis(range=0.8, rate=1.5, acceleration=10.0, natural_frequency=5.0, damping=0.8)
    mirror = Axis(range=0.026, natural_frequency=800.0, damping=0.7)
    zero = AxisState(torch.zeros(1, dtype=F64), torch.zeros(1, dtype=F64))
    state = PairState(zero, zero)
    state = respond_pair(gimbal, mirror, state, torch.tensor([0.01], dtype=F64), 0.05)
    assert state.angle.item() == pytest.approx(0.01, abs=1e-6)  # within the mirror's reach: there at once
    state = respond_pair(gimbal, mirror, state, torch.tensor([0.3], dtype=F64), 0.05)
    assert abs(state.mirror.angle.item()) <= 0.026 and state.angle.item() < 0.3  # the gimbal still slewing
