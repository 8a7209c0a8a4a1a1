"""The ends' own motion: a body in the sea's orbital motion, and the Gaussian processes of a hovering drone
(docs/model.md §12).

**Orbital motion** (linear, Airy, deep-water theory). The surface is η = Σ a cos ψ, ψ = ω t + ε − k·x
(:mod:`waterair.physics.surface`). A water particle whose mean position is x at depth z < 0 moves by

    ξ = Σ a e^{|k| z} sin ψ · k/|k|   (horizontal),   ζ = Σ a e^{|k| z} cos ψ   (vertical),

at velocity ξ̇ = Σ a ω e^{|k| z} cos ψ · k/|k|, ζ̇ = −Σ a ω e^{|k| z} sin ψ: the gradient of the potential
Φ = Σ (a ω / |k|) e^{|k| z} sin(k·x − ω t − ε), whatever the dispersion relation (it enters only through the
harmonics' ω and k), so the same holds for the capillary-gravity waves of the measured-slope sea, which decay
within centimetres. At z = 0 the vertical motion is η itself. The same harmonics, with the same phases, as the
surface: the vehicle heaves with the very waves its beam crosses.

**Ornstein–Uhlenbeck processes**, the hovering drone's position drift and attitude jitter: dx = −x/τ dt +
σ √(2/τ) dW, stationary with standard deviation σ and one-sided spectrum S(f) = 4 σ² τ / (1 + (2π f τ)²).
Stepped exactly (:func:`ou_step`): x' = ρ x + σ √(1 − ρ²) n, ρ = e^{−Δt/τ}, n standard normal (drawn by the
caller, keyed: :mod:`waterair.core.hashing`), so any Δt gives the process's own statistics.

**Damped oscillators driven by white noise**, where a path must be smooth (a position, an attitude: a body has
inertia, so its velocity is finite): ẍ = −ω² x − 2 ζ ω ẋ + q w, stationary with Var x = σ², Var ẋ = ω² σ², the
two uncorrelated. Stepped exactly (:class:`Oscillator`): (x, ẋ)' = Φ (x, ẋ) + L n, Φ = exp(A Δt) and
L Lᵀ = P − Φ P Φᵀ, P the stationary covariance, both in float64.

:class:`Motion` is both ends' motion as a configuration names it (``env.motion.*``); :func:`trajectory` draws an
episode of it from standard normals, and :func:`place` puts the ends where it says at a time.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import NamedTuple

import torch

from waterair.core.validation import check_choice, check_range
from waterair.physics.surface import Harmonics


class Orbit(NamedTuple):
    """A particle's displacement from its mean position (m) and its velocity (m/s), ``[B, 3]`` each."""

    displacement: torch.Tensor
    velocity: torch.Tensor


def orbital_motion(sea: Harmonics, position: torch.Tensor, time: torch.Tensor, response: float = 1.0) -> Orbit:
    """The orbital motion of the water particles whose mean positions are ``position`` ``[B, 3]`` (m, z < 0
    below the mean surface) at ``time`` ``[B]`` (s), in the seas ``sea`` (``[B, K]`` harmonics), times the body's
    ``response``: 1 for a body that moves with the water, 0 for one that holds station."""
    x, y, z = (position[:, i : i + 1] for i in range(3))
    k = torch.sqrt(sea.kx**2 + sea.ky**2)
    decay = response * sea.amplitude * torch.exp(k * z.clamp(max=0.0))
    psi = sea.omega * time.unsqueeze(-1) + sea.phase - sea.kx * x - sea.ky * y
    sine, cosine = torch.sin(psi), torch.cos(psi)
    nonzero = k.clamp(min=torch.finfo(k.dtype).tiny)
    ux, uy = sea.kx / nonzero, sea.ky / nonzero
    displacement = torch.stack(
        ((decay * sine * ux).sum(-1), (decay * sine * uy).sum(-1), (decay * cosine).sum(-1)), dim=-1
    )
    speed = decay * sea.omega
    velocity = torch.stack(
        ((speed * cosine * ux).sum(-1), (speed * cosine * uy).sum(-1), -(speed * sine).sum(-1)), dim=-1
    )
    return Orbit(displacement, velocity)


class Process(NamedTuple):
    """An Ornstein–Uhlenbeck process per axis: its stationary standard deviation ``sigma`` and time constant
    ``tau`` (s); scalars or tensors that broadcast against the process's values."""

    sigma: float | torch.Tensor
    tau: float | torch.Tensor

    def correlation(self, dt: float):
        """ρ = e^{−Δt/τ}: the correlation of two values ``dt`` apart."""
        if isinstance(self.tau, torch.Tensor):
            return torch.exp(-dt / self.tau)
        return math.exp(-dt / self.tau)

    def spectrum(self, frequency):
        """The one-sided power spectral density S(f) (units² / Hz) at ``frequency`` (Hz)."""
        return 4.0 * self.sigma**2 * self.tau / (1.0 + (2.0 * math.pi * frequency * self.tau) ** 2)


def ou_start(process: Process, noise: torch.Tensor) -> torch.Tensor:
    """A stationary start: σ n for standard normal ``noise``."""
    return process.sigma * noise


def ou_step(process: Process, value: torch.Tensor, noise: torch.Tensor, dt: float) -> torch.Tensor:
    """The process ``dt`` (s) after ``value``, exactly: ρ x + σ √(1 − ρ²) n for standard normal ``noise``."""
    rho = process.correlation(dt)
    return rho * value + process.sigma * (1.0 - rho**2) ** 0.5 * noise


def rotation(roll: torch.Tensor, pitch: torch.Tensor, yaw: torch.Tensor) -> torch.Tensor:
    """The body-to-world rotations ``[B, 3, 3]`` of attitudes ``[B]`` each (rad): R = R_z(yaw) R_y(pitch) R_x(roll),
    aerospace order; a vector v in the body's frame is R v in the world's, a world vector w is Rᵀ w in the body's."""
    cr, sr, cp, sp, cy, sy = (f(a) for a in (roll, pitch, yaw) for f in (torch.cos, torch.sin))
    rows = (
        (cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr),
        (sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr),
        (-sp, cp * sr, cp * cr),
    )
    return torch.stack([torch.stack(row, dim=-1) for row in rows], dim=-2)


@dataclass(frozen=True)
class Oscillator:
    """A damped oscillator driven by white noise, stationary: standard deviation ``sigma`` of its value, natural
    ``period`` 2π/ω (s), ``damping`` ζ."""

    sigma: float
    period: float
    damping: float

    @functools.cache  # noqa: B019 (frozen and hashable: one pair of matrices per oscillator and step)
    def transition(self, dt: float) -> tuple[torch.Tensor, torch.Tensor]:
        """Φ and L ``[2, 2]`` float64: (x, ẋ) after ``dt`` is Φ (x, ẋ) + L n, n two standard normals."""
        w, z = 2.0 * math.pi / self.period, self.damping
        a = torch.tensor([[0.0, 1.0], [-(w**2), -2.0 * z * w]], dtype=torch.float64)
        phi = torch.linalg.matrix_exp(a * dt)
        stationary = torch.diag(torch.tensor([self.sigma**2, (w * self.sigma) ** 2], dtype=torch.float64))
        if self.sigma == 0.0:  # a still process: nothing added
            return phi, torch.zeros(2, 2, dtype=torch.float64)
        added = stationary - phi @ stationary @ phi.T
        return phi, torch.linalg.cholesky(0.5 * (added + added.T))

    def start(self, noise: torch.Tensor) -> torch.Tensor:
        """A stationary start ``[..., 2]`` (value, rate) from two standard normals ``noise`` ``[..., 2]``."""
        scale = torch.tensor([self.sigma, 2.0 * math.pi / self.period * self.sigma], dtype=noise.dtype)
        return noise * scale.to(noise.device)


MOTIONS = ("static", "hover", "transit")
"""How the ends move (``env.motion.kind``): not at all; the drone hovering and the vehicle in the sea's orbital
motion; the same with the drone crossing the link at a constant velocity."""
TRAJECTORY_COLUMNS = ("drift_x", "drift_y", "drift_z", "tx_roll", "tx_pitch", "tx_imu_roll", "tx_imu_pitch",
                      "rx_roll", "rx_pitch", "rx_imu_roll", "rx_imu_pitch")  # fmt: skip
"""A trajectory's columns (:func:`trajectory`): the drone's drift from its path (m), each end's attitude and what its
inertial sensor reads of it (rad)."""
DRAWS_PER_STEP = 18
"""The standard normals a trajectory takes per step: two for each of its seven oscillators (the drift's three axes,
each end's roll and pitch), one for each of the four inertial sensors' errors."""


@dataclass(frozen=True)
class Motion:
    """Both ends' own motion (docs/model.md §12: the presets' sources).

    Attributes:
        kind: one of :data:`MOTIONS`; ``static`` ignores the rest.
        drift_horizontal, drift_vertical: the drone's position hold error, σ per horizontal axis and vertically (m).
        drift_period, drift_damping: its hold loop's natural period (s) and damping.
        drone_attitude, drone_attitude_period: the drone's roll and pitch jitter, σ (rad) and period (s).
        vehicle_response: how much of the water's orbital motion at its depth the vehicle takes, in [0, 1].
        vehicle_attitude, vehicle_attitude_period: the vehicle's roll and pitch, σ (rad) and period (s).
        attitude_damping: both ends' attitude loops' damping.
        imu_error, imu_time: each end's inertial sensor's roll and pitch error, σ (rad), and its time constant (s).
        transit_speed, transit_heading_deg: ``transit``: the drone's ground speed (m/s) and heading (deg from +x);
            its path crosses its home position at the episode's middle.
    """

    kind: str = "static"
    drift_horizontal: float = 0.5
    drift_vertical: float = 0.2
    drift_period: float = 10.0
    drift_damping: float = 0.7
    drone_attitude: float = 0.0175
    drone_attitude_period: float = 1.0
    vehicle_response: float = 1.0
    vehicle_attitude: float = 0.035
    vehicle_attitude_period: float = 6.0
    attitude_damping: float = 0.5
    imu_error: float = 0.0035
    imu_time: float = 100.0
    transit_speed: float = 1.5
    transit_heading_deg: float = 0.0

    def __post_init__(self) -> None:
        check_choice("kind", self.kind, MOTIONS)
        for name, high, unit in (("drift_horizontal", 100.0, "m"), ("drift_vertical", 100.0, "m"),
                                 ("drone_attitude", 0.5, "rad"), ("vehicle_attitude", 0.5, "rad"),
                                 ("imu_error", 0.5, "rad"), ("transit_speed", 50.0, "m/s"),
                                 ("vehicle_response", 1.0, "")):  # fmt: skip
            check_range(name, getattr(self, name), 0.0, high, unit=unit)
        for name in ("drift_period", "drone_attitude_period", "vehicle_attitude_period", "imu_time"):
            check_range(name, getattr(self, name), 0.0, 1.0e4, low_open=True, unit="s")
        for name in ("drift_damping", "attitude_damping"):
            check_range(name, getattr(self, name), 0.0, 10.0, low_open=True)
        check_range("transit_heading_deg", self.transit_heading_deg, -360.0, 360.0, unit="deg")

    @property
    def moves(self) -> bool:
        """Whether either end moves (``static``: the earlier, still link)."""
        return self.kind != "static"

    @property
    def oscillators(self) -> tuple[Oscillator, ...]:
        """The trajectory's seven oscillators: the drift's x, y, z, the vehicle's roll and pitch, the drone's."""
        drift = (self.drift_horizontal, self.drift_horizontal, self.drift_vertical)
        vehicle = Oscillator(self.vehicle_attitude, self.vehicle_attitude_period, self.attitude_damping)
        drone = Oscillator(self.drone_attitude, self.drone_attitude_period, self.attitude_damping)
        return (*(Oscillator(s, self.drift_period, self.drift_damping) for s in drift), vehicle, vehicle, drone, drone)

    def velocity(self, dtype: torch.dtype = torch.float64) -> torch.Tensor:
        """The drone's transit velocity ``[3]`` (m/s): zero but for ``transit``."""
        speed = self.transit_speed if self.kind == "transit" else 0.0
        heading = math.radians(self.transit_heading_deg)
        return torch.tensor([speed * math.cos(heading), speed * math.sin(heading), 0.0], dtype=dtype)


def trajectory(motion: Motion, normals: torch.Tensor, dt: float) -> torch.Tensor:
    """An episode of the drift and the attitudes ``[m, T, 11]`` (:data:`TRAJECTORY_COLUMNS`) at the steps 0 … T − 1
    of ``dt`` (s), from standard normals ``normals`` ``[m, T, DRAWS_PER_STEP]`` (float64); each process starts
    stationary. An inertial sensor reads its end's attitude plus an Ornstein–Uhlenbeck error."""
    oscillators, imu = motion.oscillators, Process(motion.imu_error, motion.imu_time)
    pairs, kicks = normals.split((14, 4), dim=-1)
    pairs = pairs.unflatten(-1, (7, 2))
    transitions = [o.transition(dt) for o in oscillators]
    phi = torch.stack([p for p, _ in transitions]).to(normals.dtype)
    lower = torch.stack([low for _, low in transitions]).to(normals.dtype)
    state = torch.stack([o.start(pairs[:, 0, i]) for i, o in enumerate(oscillators)], dim=1)  # [m, 7, 2]
    error = ou_start(imu, kicks[:, 0])
    values, errors = [state[..., 0]], [error]
    for step in range(1, normals.shape[1]):
        state = torch.einsum("kij,mkj->mki", phi, state) + torch.einsum("kij,mkj->mki", lower, pairs[:, step])
        error = ou_step(imu, error, kicks[:, step], dt)
        values.append(state[..., 0])
        errors.append(error)
    value, error = torch.stack(values, dim=1), torch.stack(errors, dim=1)  # [m, T, 7], [m, T, 4]
    tx, rx = value[..., 3:5], value[..., 5:7]
    return torch.cat((value[..., :3], tx, tx + error[..., :2], rx, rx + error[..., 2:]), dim=-1)
