"""The refracted path T → P → R as a result: :class:`PathSolution`, and the calm-sea point.

Both solvers (:mod:`.newton`, :mod:`.centroid`) end in :func:`finish_path`, which turns a surface
point into the path's directions, angles and lengths (docs/model.md §3) and flags invalid paths
(no convergence, a ray meeting the surface from below its tangent plane, total internal
reflection) with ``valid = False``; no output is ever NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import torch
from tensordict import TensorClass

from waterair.physics.optics import N_AIR, N_WATER, RefractiveIndices, angle_between, critical_angle
from waterair.physics.surface import WaveSurface

TRACK_LEASH = 3.0
"""How far (m) a tracked refraction point may stray from the calm-sea point and still be followed where
the exact point is not needed: the light comes from within a metre or so of it at any wind (docs/model.md §4.3)."""


class PathSolution(TensorClass):
    """The primary path for each batch element; every field has leading shape ``[B]``.

    Fields: ``point`` P (m, ``[B, 3]``); ``departure`` u_d = (P − T)/|P − T| and ``arrival``
    u_a = (R − P)/|R − P| (unit, ``[B, 3]``); ``normal`` the unit surface normal at P (``[B, 3]``);
    ``theta1`` incidence angle in water and ``theta2`` refraction angle in air (rad);
    ``d_water`` = |P − T| and ``d_air`` = |R − P| (m); ``valid`` (bool); ``iterations`` (int).
    """

    point: torch.Tensor
    departure: torch.Tensor
    arrival: torch.Tensor
    normal: torch.Tensor
    theta1: torch.Tensor
    theta2: torch.Tensor
    d_water: torch.Tensor
    d_air: torch.Tensor
    valid: torch.Tensor
    iterations: torch.Tensor


@dataclass(frozen=True)
class PathProblem:
    """The paths a solver is asked for: B seas ``surface``, the ends ``tx`` (under water) and ``rx`` (in air),
    each ``[B, 3]`` (m), the time ``t`` (s; a float or ``[B]``) and the refractive ``indices``."""

    surface: WaveSurface
    tx: torch.Tensor
    rx: torch.Tensor
    t: float | torch.Tensor
    indices: RefractiveIndices = field(default_factory=RefractiveIndices)

    def rows(self, index: torch.Tensor | slice) -> PathProblem:
        """The paths ``index`` of this batch (a float time is every row's)."""
        t = self.t[index] if isinstance(self.t, torch.Tensor) and self.t.dim() > 0 else self.t
        return PathProblem(self.surface[index], self.tx[index], self.rx[index], t, self.indices)

    def path(self, stop: Iterate) -> PathSolution:
        """The path through where the iterations ``stop``ped (:func:`finish_path`)."""
        return finish_path(stop, self.tx, self.rx, self.indices)


class Iterate(NamedTuple):
    """Where a solver's Newton iterations stopped, per path: P ``[B, 3]`` (m), the slopes (η_x, η_y) there
    ``[B, 2]``, the (x, y) ``[B, 2]`` (m) from which more iterations would start, ``converged`` ``[B]`` (bool)
    and the ``iterations`` taken ``[B]`` (int64)."""

    point: torch.Tensor
    slope: torch.Tensor
    xy: torch.Tensor
    converged: torch.Tensor
    iterations: torch.Tensor


def flat_sea_point(tx: torch.Tensor, rx: torch.Tensor, n_water: float = N_WATER, n_air: float = N_AIR) -> torch.Tensor:
    """Refraction point on the calm sea z = 0 between ``tx`` (below) and ``rx`` (above), ``[B, 3]`` (m).

    Solves n_w sin θ1 = n_a sin θ2 along the horizontal segment from T to R by bisection
    (the residual is monotone in the distance s from T), 60 halvings.
    """
    horizontal = rx[:, :2] - tx[:, :2]
    distance = torch.linalg.vector_norm(horizontal, dim=-1)
    depth, height = (-tx[:, 2]).clamp(min=0), rx[:, 2].clamp(min=0)
    low, high = torch.zeros_like(distance), distance.clone()
    for _ in range(60):
        s = 0.5 * (low + high)
        residual = n_water * s / torch.hypot(s, depth) - n_air * (distance - s) / torch.hypot(distance - s, height)
        positive = residual > 0
        high = torch.where(positive, s, high)
        low = torch.where(positive, low, s)
    s = 0.5 * (low + high)
    direction = horizontal / distance.clamp(min=torch.finfo(tx.dtype).tiny).unsqueeze(-1)
    xy = tx[:, :2] + s.unsqueeze(-1) * direction
    return torch.cat((xy, torch.zeros_like(s).unsqueeze(-1)), dim=-1)


def flat_sea_point_near(
    tx: torch.Tensor, rx: torch.Tensor, near: torch.Tensor, n_water: float = N_WATER, n_air: float = N_AIR
) -> torch.Tensor:
    """:func:`flat_sea_point` for ends that have moved little since their calm-sea point was ``near`` ``[B, 3]``:
    three Newton steps on the same monotone residual from ``near``'s distance along the new segment (quadratic
    convergence: from a start a few centimetres off, exact to float rounding), clamped to the segment."""
    horizontal = rx[:, :2] - tx[:, :2]
    distance = torch.linalg.vector_norm(horizontal, dim=-1)
    direction = horizontal / distance.clamp(min=torch.finfo(tx.dtype).tiny).unsqueeze(-1)
    depth, height = (-tx[:, 2]).clamp(min=0), rx[:, 2].clamp(min=0)
    s = ((near[:, :2] - tx[:, :2]) * direction).sum(-1).clamp(min=0.0).minimum(distance)
    for _ in range(3):
        water, air = torch.hypot(s, depth), torch.hypot(distance - s, height)
        residual = n_water * s / water - n_air * (distance - s) / air
        slope = n_water * depth**2 / water**3 + n_air * height**2 / air**3
        s = (s - residual / slope.clamp(min=torch.finfo(tx.dtype).tiny)).clamp(min=0.0).minimum(distance)
    xy = tx[:, :2] + s.unsqueeze(-1) * direction
    return torch.cat((xy, torch.zeros_like(s).unsqueeze(-1)), dim=-1)


def finish_path(stop: Iterate, tx, rx, indices: RefractiveIndices) -> PathSolution:
    """Directions, angles and lengths of the path between ``tx`` and ``rx`` ``[B, 3]`` through the point where the
    iterations ``stop``ped (its point, slope, convergence and iterations); flags invalid paths."""
    point, slope, converged, iterations = stop.point, stop.slope, stop.converged, stop.iterations
    n_w, n_a = indices
    normal = torch.cat((-slope, torch.ones_like(slope[:, :1])), dim=-1)
    normal = normal / torch.linalg.vector_norm(normal, dim=-1, keepdim=True)
    d1, d2 = point - tx, rx - point
    d_water, d_air = torch.linalg.vector_norm(d1, dim=-1), torch.linalg.vector_norm(d2, dim=-1)
    departure, arrival = d1 / d_water.unsqueeze(-1), d2 / d_air.unsqueeze(-1)
    theta1, theta2 = angle_between(departure, normal), angle_between(arrival, normal)
    finite = torch.isfinite(point).all(-1) & torch.isfinite(normal).all(-1)
    valid = converged & finite & (theta1 < critical_angle(n_w, n_a)) & (theta2 < math.pi / 2)
    safe = finite.unsqueeze(-1)
    up = torch.zeros_like(point)
    up[:, 2] = 1.0
    return PathSolution(
        point=torch.where(safe, point, up * 0),
        departure=torch.where(safe, departure, up),
        arrival=torch.where(safe, arrival, up),
        normal=torch.where(safe, normal, up),
        theta1=torch.where(finite, theta1, torch.zeros_like(theta1)),
        theta2=torch.where(finite, theta2, torch.zeros_like(theta2)),
        d_water=torch.where(finite, d_water, torch.zeros_like(d_water)),
        d_air=torch.where(finite, d_air, torch.zeros_like(d_air)),
        valid=valid,
        iterations=iterations,
        batch_size=point.shape[:1],
    )


def near_calm_point(path: PathSolution, calm_point: torch.Tensor, leash: float = TRACK_LEASH) -> torch.Tensor:
    """Whether each path's point ``[B]`` is finite and within ``leash`` (m, horizontally) of the calm-sea
    point ``[B, 3]``: where only the neighbourhood of the light matters (the two-scale lattice's
    centre, a warm start), such a point is followed even if its solve has not converged."""
    near = torch.linalg.vector_norm(path.point[:, :2] - calm_point[:, :2], dim=-1) < leash
    return torch.isfinite(path.point).all(-1) & near
