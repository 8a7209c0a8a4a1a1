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
"""

from __future__ import annotations

import math
from typing import NamedTuple

import torch

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
