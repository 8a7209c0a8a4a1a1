"""The ends' own motion (waterair.physics.motion) against Airy's closed form, the surface it rides, and the
Ornstein–Uhlenbeck process's own statistics, in float64."""

import math

import pytest
import torch

from waterair.physics import WaveSurface, sea_state
from waterair.physics.motion import Process, orbital_motion, ou_start, ou_step, rotation
from waterair.physics.surface import Harmonics, harmonic_sums

F64 = torch.float64


def _one_harmonic(a=0.4, omega=1.6, direction=0.7, phase=0.3) -> Harmonics:
    k = omega**2 / 9.81
    row = lambda v: torch.tensor([[v]], dtype=F64)  # noqa: E731
    return Harmonics(row(omega), row(phase), row(k * math.cos(direction)), row(k * math.sin(direction)), row(a))


def test_one_harmonic_moves_a_particle_as_airy_says_at_every_depth():
    a, omega, direction, phase = 0.4, 1.6, 0.7, 0.3
    sea = _one_harmonic(a, omega, direction, phase)
    k = omega**2 / 9.81
    for x, y, z, t in ((1.0, -2.0, -3.0, 0.0), (0.5, 4.0, -10.0, 2.7), (-3.0, 0.2, -0.5, 11.1)):
        orbit = orbital_motion(sea, torch.tensor([[x, y, z]], dtype=F64), torch.tensor([t], dtype=F64))
        # Airy: xi = -a e^{kz} sin(k.x - wt + phi) k_hat, zeta = a e^{kz} cos(k.x - wt + phi), with phi = -eps
        theta = k * (x * math.cos(direction) + y * math.sin(direction)) - omega * t - phase
        decay = a * math.exp(k * z)
        expected = [-decay * math.sin(theta) * math.cos(direction), -decay * math.sin(theta) * math.sin(direction),
                    decay * math.cos(theta)]  # fmt: skip
        speed = [decay * omega * math.cos(theta) * math.cos(direction),
                 decay * omega * math.cos(theta) * math.sin(direction), decay * omega * math.sin(theta)]  # fmt: skip
        assert orbit.displacement[0].tolist() == pytest.approx(expected, rel=1e-9, abs=1e-15)
        assert orbit.velocity[0].tolist() == pytest.approx(speed, rel=1e-9, abs=1e-15)


def test_a_sea_moves_its_surface_particles_by_the_surface_height_and_its_deep_ones_by_nothing():
    surface = WaveSurface.sample(sea_state("elfouhaily", wind=12.0, n_dir=16), 4, seed=5, dtype=F64)
    sea = surface.harmonics
    x = torch.tensor([[1.0], [-7.0], [3.0], [0.0]], dtype=F64)
    y = torch.tensor([[0.0], [2.0], [-1.0], [5.0]], dtype=F64)
    t = torch.tensor([0.0, 1.7, 4.2, 9.9], dtype=F64)
    (height,) = harmonic_sums(sea, x, y, t, order=0)
    at_surface = orbital_motion(sea, torch.cat((x, y, torch.zeros_like(x)), dim=-1), t)
    assert torch.allclose(at_surface.displacement[:, 2], height[:, 0], rtol=1e-12, atol=1e-14)
    deep = orbital_motion(sea, torch.cat((x, y, torch.full_like(x, -1.0e4)), dim=-1), t)
    assert deep.displacement.abs().max() == 0.0 and deep.velocity.abs().max() == 0.0
    # the velocity is the displacement's rate: a central difference over 1 ms
    position = torch.cat((x, y, torch.full_like(x, -3.0)), dim=-1)
    later, earlier = (orbital_motion(sea, position, t + s).displacement for s in (1e-3, -1e-3))
    assert torch.allclose((later - earlier) / 2e-3, orbital_motion(sea, position, t).velocity, rtol=1e-5, atol=1e-7)


def test_the_response_factor_scales_the_orbit_and_zero_holds_station():
    sea, position, t = _one_harmonic(), torch.tensor([[2.0, 1.0, -4.0]], dtype=F64), torch.tensor([1.3], dtype=F64)
    full = orbital_motion(sea, position, t)
    half = orbital_motion(sea, position, t, response=0.5)
    assert torch.allclose(half.displacement, 0.5 * full.displacement, rtol=1e-15)
    assert torch.allclose(half.velocity, 0.5 * full.velocity, rtol=1e-15)
    assert orbital_motion(sea, position, t, response=0.0).displacement.abs().max() == 0.0


def test_the_peak_waves_decay_at_ten_metres_as_e_to_minus_k_z():
    # 12 m/s, 20 km fetch: the peak k_p ~ 0.27 rad/m decays to e^{-2.7} ~ 0.07 at 10 m (docs/model.md §12)
    surface = WaveSurface.sample(sea_state("elfouhaily", wind=12.0, fetch=20000.0, n_dir=16), 1, seed=0, dtype=F64)
    sea = surface.harmonics
    k = torch.sqrt(sea.kx**2 + sea.ky**2)
    peak = k[0, sea.amplitude[0].argmax()].item()
    assert 0.2 < peak < 0.35
    variance = lambda depth: (0.5 * sea.amplitude**2 * torch.exp(-2 * k * depth)).sum().item()  # noqa: E731
    assert 0.8 < 4.0 * variance(0.0) ** 0.5 < 1.3  # H_s = 4 sqrt(m0) ~ 1 m
    assert (variance(10.0) / variance(0.0)) ** 0.5 == pytest.approx(math.exp(-peak * 10.0), rel=0.5)


def test_an_ou_process_keeps_its_variance_and_decays_as_its_time_constant_says():
    process, dt = Process(sigma=0.8, tau=2.0), 0.05
    generator = torch.Generator().manual_seed(1)
    value = ou_start(process, torch.randn(200_000, generator=generator, dtype=F64))
    start = value.clone()
    for _ in range(40):  # 2 s = one time constant
        value = ou_step(process, value, torch.randn(200_000, generator=generator, dtype=F64), dt)
    assert value.std().item() == pytest.approx(0.8, rel=0.01)
    correlation = torch.corrcoef(torch.stack((start, value)))[0, 1].item()
    assert correlation == pytest.approx(math.exp(-1.0), abs=0.01)
    # without noise it decays exactly, and one step of 2 dt is two of dt
    quiet = torch.ones(1, dtype=F64)
    twice = ou_step(process, ou_step(process, quiet, torch.zeros(1, dtype=F64), dt), torch.zeros(1, dtype=F64), dt)
    assert twice.item() == pytest.approx(math.exp(-2 * dt / 2.0), rel=1e-14)
    assert ou_step(process, quiet, torch.zeros(1, dtype=F64), 2 * dt).item() == pytest.approx(twice.item(), rel=1e-14)


def test_an_ou_spectrum_integrates_to_its_variance():
    process = Process(sigma=0.3, tau=0.4)
    f = torch.linspace(0.0, 2000.0, 2_000_001, dtype=F64)
    area = torch.trapezoid(process.spectrum(f), f).item()
    assert area == pytest.approx(0.09, rel=1e-3)  # the tail beyond 2 kHz holds 2/(pi^2 f tau) of it, 0.03 %


def test_attitude_rotations_are_rotations_and_compose_in_aerospace_order():
    generator = torch.Generator().manual_seed(3)
    roll, pitch, yaw = (torch.rand(6, generator=generator, dtype=F64) * 2 - 1 for _ in range(3))
    r = rotation(roll, pitch, yaw)
    assert torch.allclose(r @ r.transpose(1, 2), torch.eye(3, dtype=F64).expand(6, 3, 3), atol=1e-14)
    assert torch.allclose(torch.linalg.det(r), torch.ones(6, dtype=F64), atol=1e-14)
    zero = torch.zeros(6, dtype=F64)
    about = lambda axis, angle: torch.linalg.matrix_exp(  # noqa: E731
        torch.einsum("ijk,k->ij", _levi_civita(), -torch.eye(3, dtype=F64)[axis]) * angle.view(-1, 1, 1)
    )
    composed = about(2, yaw) @ about(1, pitch) @ about(0, roll)
    assert torch.allclose(r, composed, atol=1e-13)
    # a body turned by +0.1 rad about y (its x axis tipped below the horizon, z up) sees the world's x axis 0.1 rad
    # above its own
    body = rotation(zero[:1], torch.full((1,), 0.1, dtype=F64), zero[:1]).transpose(1, 2) @ torch.tensor(
        [1.0, 0.0, 0.0], dtype=F64
    )
    assert body[0].tolist() == pytest.approx([math.cos(0.1), 0.0, math.sin(0.1)], abs=1e-15)


def _levi_civita() -> torch.Tensor:
    eps = torch.zeros(3, 3, 3, dtype=F64)
    for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        eps[i, j, k], eps[i, k, j] = 1.0, -1.0
    return eps
