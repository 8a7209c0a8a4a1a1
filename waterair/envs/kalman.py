"""A Kalman filter on an angle and its rate, batched: what ``kalman_tracker`` (:mod:`waterair.envs.controllers`)
runs on each end's reading (docs/environment.md, "Classical controllers").

Each component of a reading (a tilt's v_x or v_y, about its angle for the small angles a beam moves by) is a
track of (angle, rate) under piecewise-constant white acceleration (Bar-Shalom, Li and Kirubarajan, *Estimation
with Applications to Tracking and Navigation*, Wiley 2001, ch. 6): over a step Δt the state moves by
F = [[1, Δt], [0, 1]] and gains the covariance σ_a² g gᵀ, g = (Δt²/2, Δt). A reading of variance r updates the
angle; one further than ``gate`` standard deviations of its innovation from the prediction (the light's centroid
jumping between refraction points) starts the track again from it. Every tensor is ``[..., 2]`` for a state,
``[..., 2, 2]`` for a covariance, ``[...]`` for the rest: the functions act elementwise over the leading dimensions.

How much of the estimated rate to point ahead by is learned from the readings themselves (:class:`Carry`): the
least-squares share γ of each step's move x_k − x_{k−1} that the rate before it, times Δt, foretold, over a fading
memory. A constant rate carries over whole (γ = 1); a sinusoid of ω Δt = φ, sampled, by sin φ / φ; light that
turns back within a step (short waves, a centroid moving between refraction points, noise) by little.
"""

from __future__ import annotations

from typing import NamedTuple

import torch


class Track(NamedTuple):
    """The estimate ``state`` (angle, rate) ``[..., 2]`` and its ``covariance`` ``[..., 2, 2]``."""

    state: torch.Tensor
    covariance: torch.Tensor


def begin(reading: torch.Tensor, variance: torch.Tensor, rate_variance: torch.Tensor) -> Track:
    """A track started at ``reading`` ``[...]`` (its ``variance``), at rest (the rate's prior ``rate_variance``)."""
    state = torch.stack((reading, torch.zeros_like(reading)), dim=-1)
    zero = torch.zeros_like(reading)
    covariance = torch.stack((torch.stack((variance, zero), -1), torch.stack((zero, rate_variance), -1)), -2)
    return Track(state, covariance)


def predict(track: Track, dt: float, acceleration_variance: torch.Tensor) -> Track:
    """``track`` carried ``dt`` (s) on, under white acceleration of variance ``acceleration_variance`` ``[...]``
    (rad²/s⁴) held over the step."""
    angle, rate = track.state[..., 0], track.state[..., 1]
    p = track.covariance
    p00 = p[..., 0, 0] + dt * (p[..., 0, 1] + p[..., 1, 0]) + dt * dt * p[..., 1, 1]
    p01 = p[..., 0, 1] + dt * p[..., 1, 1]
    p11 = p[..., 1, 1]
    q = acceleration_variance
    p00, p01, p11 = p00 + q * dt**4 / 4, p01 + q * dt**3 / 2, p11 + q * dt**2
    covariance = torch.stack((torch.stack((p00, p01), -1), torch.stack((p01, p11), -1)), -2)
    return Track(torch.stack((angle + dt * rate, rate), dim=-1), covariance)


def update(track: Track, reading: torch.Tensor, variance: torch.Tensor, gate: float) -> tuple[Track, torch.Tensor]:
    """``track`` after a ``reading`` ``[...]`` of its angle with ``variance``, and where the reading was within
    ``gate`` standard deviations of its innovation (``[...]`` bool): elsewhere the track is left as it was (the
    caller starts it again)."""
    p = track.covariance
    innovation = reading - track.state[..., 0]
    spread = p[..., 0, 0] + variance
    gain = p[..., :, 0] / spread.unsqueeze(-1)  # [..., 2]
    state = track.state + gain * innovation.unsqueeze(-1)
    covariance = p - gain.unsqueeze(-1) * p[..., 0, :].unsqueeze(-2)
    inside = innovation.square() <= gate**2 * spread
    return Track(state, 0.5 * (covariance + covariance.transpose(-1, -2))), inside


def ahead(track: Track, lead: torch.Tensor | float) -> torch.Tensor:
    """The angle ``lead`` (s) on along the estimated rate ``[...]``."""
    return track.state[..., 0] + lead * track.state[..., 1]


def choose(where: torch.Tensor, first: Track, second: Track) -> Track:
    """``first`` where ``where`` ``[...]`` holds, else ``second``."""
    return Track(
        torch.where(where.unsqueeze(-1), first.state, second.state),
        torch.where(where[..., None, None], first.covariance, second.covariance),
    )


class Carry(NamedTuple):
    """The fading sums ``moved`` = Σ λ^j a b and ``foretold`` = Σ λ^j b² ``[...]`` of each step's move a and the
    move its rate foretold, b = rate Δt (:func:`carry`)."""

    moved: torch.Tensor
    foretold: torch.Tensor


def carry(sums: Carry, move: torch.Tensor, foretold: torch.Tensor, decay: float) -> Carry:
    """``sums`` a step on: faded by ``decay`` (λ, in (0, 1]), with the step's ``move`` and the ``foretold`` one."""
    return Carry(decay * sums.moved + move * foretold, decay * sums.foretold + foretold.square())


def share(sums: Carry) -> torch.Tensor:
    """The least-squares share of the rate that carries over, Σ a b / Σ b², within [0, 1] (1 where nothing was
    foretold)."""
    found = sums.moved / sums.foretold.clamp(min=torch.finfo(sums.foretold.dtype).tiny)
    return torch.where(sums.foretold > 0, found, torch.ones_like(found)).clamp(0.0, 1.0)
