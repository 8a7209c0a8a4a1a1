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

:class:`Motion` is both ends' motion as a configuration names it (``env.motion.*``); :func:`motion_start` and
:func:`motion_step` draw and step its state from standard normals.
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


MOTIONS = ("static", "hover", "transit", "parked")
"""How the ends move (``env.motion.kind``): not at all; the drone hovering and the vehicle in the sea's orbital
motion; the same with the drone crossing the link at a constant velocity; or hovering still at a point of that
crossing drawn per link (the crossing's geometry without its motion: what a transit is compared with)."""
MOTION_WIDTH = 18
"""A motion state's columns (:func:`motion_start`): the seven oscillators' values (the drift's x, y, z (m), the
vehicle's roll and pitch, the drone's (rad)), then their rates, then the four inertial errors (the vehicle's roll
and pitch, the drone's); and the standard normals a step of it takes."""


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
            its path crosses its home position at ``crossing_time`` (s; None: the episode's middle). ``parked``: the
            drone hovers at the point of that path at a time drawn uniformly over [0, 2 × the crossing's].
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
    crossing_time: float | None = None

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
        if self.crossing_time is not None:
            check_range("crossing_time", self.crossing_time, 0.0, 1.0e6, unit="s")

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

    @functools.cache  # noqa: B019 (frozen and hashable: once per configuration and step, outside the step's graph)
    def transitions(self, dt: float) -> tuple[tuple[tuple[float, ...], ...], tuple[tuple[float, ...], ...]]:
        """The oscillators' Φ and L (:meth:`Oscillator.transition`) over ``dt``, as floats: each a tuple of its four
        entries (row by row), each entry a tuple over :attr:`oscillators`."""
        rows = [o.transition(dt) for o in self.oscillators]
        phi = tuple(zip(*(p.flatten().tolist() for p, _ in rows), strict=True))
        lower = tuple(zip(*(low.flatten().tolist() for _, low in rows), strict=True))
        return phi, lower

    def velocity(self, dtype: torch.dtype = torch.float64, parked: bool = False) -> torch.Tensor:
        """The drone's transit velocity ``[3]`` (m/s): zero but for ``transit`` (with ``parked``: also the velocity
        of the path a ``parked`` drone stands on)."""
        moving = self.kind == "transit" or (parked and self.kind == "parked")
        speed = self.transit_speed if moving else 0.0
        heading = math.radians(self.transit_heading_deg)
        return torch.tensor([speed * math.cos(heading), speed * math.sin(heading), 0.0], dtype=dtype)

    def crossing(self, episode: float) -> float:
        """When (s) the transit's path passes over the drone's home, in an episode of ``episode`` s."""
        return 0.5 * episode if self.crossing_time is None else self.crossing_time


def motion_start(motion: Motion, normals: torch.Tensor) -> torch.Tensor:
    """A stationary motion state ``[m, MOTION_WIDTH]`` from standard normals ``normals`` ``[m, MOTION_WIDTH]``."""
    scales = [o.sigma for o in motion.oscillators] + [2.0 * math.pi / o.period * o.sigma for o in motion.oscillators]
    scale = torch.tensor(scales + [motion.imu_error] * 4, dtype=normals.dtype, device=normals.device)
    return normals * scale


def motion_step(
    motion: Motion, state: torch.Tensor, normals: torch.Tensor, dt: float, transitions=None
) -> torch.Tensor:
    """The motion state ``[m, MOTION_WIDTH]`` ``dt`` (s) after ``state``, exactly: each oscillator (x, ẋ) → Φ (x, ẋ)
    + L n, each inertial error ρ e + σ √(1 − ρ²) n, from standard normals ``normals`` ``[m, MOTION_WIDTH]`` (the
    oscillators' two each, then the errors'). ``transitions``: ``motion.transitions(dt)``, where the caller has them
    (a compiled step takes them as constants)."""
    transitions = motion.transitions(dt) if transitions is None else transitions
    phi, lower = (torch.tensor(part, dtype=state.dtype, device=state.device) for part in transitions)
    x, v, error = state[:, :7], state[:, 7:14], state[:, 14:]
    n0, n1 = normals[:, :7], normals[:, 7:14]
    moved_x = phi[0] * x + phi[1] * v + lower[0] * n0
    moved_v = phi[2] * x + phi[3] * v + lower[2] * n0 + lower[3] * n1
    imu = ou_step(Process(motion.imu_error, motion.imu_time), error, normals[:, 14:], dt)
    return torch.cat((moved_x, moved_v, imu), dim=-1)


def attitudes(state: torch.Tensor) -> torch.Tensor:
    """Each end's true attitude and its inertial reading ``[m, 8]`` (rad: the vehicle's roll, pitch, their readings,
    then the drone's) of motion states ``[m, MOTION_WIDTH]``."""
    tx, rx, error = state[:, 3:5], state[:, 5:7], state[:, 14:]
    return torch.cat((tx, tx + error[:, :2], rx, rx + error[:, 2:]), dim=-1)
