"""Every refraction point of a link at once: multi-start Newton on Fermat's principle (docs/model.md §1.5).

:func:`solve_path` follows one path, continued from the calm-sea point. A sea with steep short waves
has several stationary points of the optical path length L(x, y) at once (minima, saddles and
maxima: every one is a ray T → P → R). :func:`refraction_points` finds them all within the beam's
reach: plain Newton steps on ∇L = 0 (no line search, so saddles and maxima are found too) from a
grid of starts, then duplicates merged. It is a reference and a census tool, not a per-step solver:
its cost is the number of starts times the iterations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from tensordict import TensorClass

from waterair.physics.optics import WATER_AIR, RefractiveIndices, angle_between, critical_angle
from waterair.physics.paths.newton import fermat_terms
from waterair.physics.paths.solution import PathProblem
from waterair.physics.surface import Harmonics, WaveSurface

MERGE_DISTANCE = 1e-4
"""Two converged starts closer than this (m) are the same refraction point."""


class RefractionPoints(TensorClass):
    """Up to P refraction points per link, ``[B, P]`` leading shape, padded where a link has fewer.

    ``point`` P (m, ``[B, P, 3]``), ``slope`` (η_x, η_y) at P (``[B, P, 2]``), ``hessian`` (L_xx,
    L_xy, L_yy) of the optical path length (1/m, ``[B, P, 3]``), ``departure`` unit u_d
    (``[B, P, 3]``), ``theta1`` incidence angle (rad), ``valid`` (bool: a converged, transmitted,
    distinct point within the beam's reach); ``count`` ``[B]`` the number of valid points.
    """

    point: torch.Tensor
    slope: torch.Tensor
    hessian: torch.Tensor
    departure: torch.Tensor
    theta1: torch.Tensor
    valid: torch.Tensor

    @property
    def count(self) -> torch.Tensor:
        return self.valid.sum(-1)


@dataclass(frozen=True)
class CensusOptions:
    """Settings of the census.

    Attributes:
        spacing: distance between starts on the surface (m); it must be below the shortest resolved
            wavelength's quarter for a full census.
        iterations: Newton steps from each start; ``max_step`` caps each step (m).
        chunk: starts × harmonics evaluated at once (memory).
    """

    spacing: float = 0.05
    iterations: int = 30
    max_step: float = 0.1
    chunk: int = 2**22


def refraction_points(
    surface: WaveSurface,
    tx: torch.Tensor,
    rx: torch.Tensor,
    t: float,
    axis: torch.Tensor,
    reach: float,
    *,
    indices: RefractiveIndices = WATER_AIR,
    options: CensusOptions | None = None,
) -> RefractionPoints:
    """All refraction points of each link whose departure lies within ``reach`` (rad) of ``axis``.

    Args:
        surface: B sea realisations.
        tx, rx: transmitter and receiver positions (m), ``[B, 3]``.
        t: time (s).
        axis: unit transmitter axis ``[B, 3]`` (pointing up).
        reach: half-angle of the beam's reach around ``axis`` (rad), e.g. 3 ω_D.
        indices: the refractive indices either side of the surface.
        options: the starts' spacing, the Newton steps and the memory (:class:`CensusOptions`; None: its defaults).
    """
    options = options or CensusOptions()
    batch, dtype, device = tx.shape[0], tx.dtype, tx.device
    spacing = options.spacing
    centre = tx + (-tx[:, 2:] / axis[:, 2:]) * axis  # where the axis meets z = 0
    radius = float((-tx[:, 2] / axis[:, 2]).max()) * math.tan(reach) + 2 * spacing
    line = torch.arange(-radius, radius + spacing / 2, spacing, dtype=dtype, device=device)
    grid = torch.stack(torch.meshgrid(line, line, indexing="ij"), -1).reshape(-1, 2)
    grid = grid[torch.linalg.vector_norm(grid, dim=-1) <= radius]
    starts = grid.shape[0]
    per_chunk = max(1, options.chunk // max(1, starts * surface.num_harmonics))
    problem = PathProblem(surface, tx, rx, t, indices)
    rows = []
    for first in range(0, batch, per_chunk):
        links = slice(first, min(batch, first + per_chunk))
        rows.append(_newton_all(problem.rows(links), centre[links, :2], grid, options))
    xy, slope, hessian, point, converged = (torch.cat(parts, 0) for parts in zip(*rows, strict=True))
    departure = (point - tx.unsqueeze(1)) / torch.linalg.vector_norm(point - tx.unsqueeze(1), dim=-1, keepdim=True)
    normal = torch.cat((-slope, torch.ones_like(slope[..., :1])), -1)
    normal = normal / torch.linalg.vector_norm(normal, dim=-1, keepdim=True)
    theta1 = angle_between(departure, normal)
    within = angle_between(departure, axis.unsqueeze(1).expand_as(departure)) <= reach
    keep = converged & within & (theta1 < critical_angle(*indices)) & torch.isfinite(point).all(-1)
    return _merge(xy, slope, hessian, point, departure, theta1, keep)


def _newton_all(problem: PathProblem, centre, grid, options: CensusOptions):
    """Plain Newton on ∇L = 0 from ``centre + grid``: (xy, slope, hessian, P, converged), each ``[b, S, ·]``."""
    tx, rx = problem.tx, problem.rx
    batch, starts = tx.shape[0], grid.shape[0]
    xy = (centre.unsqueeze(1) + grid.unsqueeze(0)).reshape(-1, 2)
    sea = Harmonics(*(v.repeat_interleave(starts, 0) for v in problem.surface.harmonics))
    time = torch.full((batch * starts,), float(problem.t), dtype=tx.dtype, device=tx.device)
    tx_rows, rx_rows = tx.repeat_interleave(starts, 0), rx.repeat_interleave(starts, 0)
    tol = 1e-9 if tx.dtype == torch.float64 else 2e-5
    for _ in range(options.iterations):
        terms = fermat_terms(sea, xy, time, tx_rows, rx_rows, *problem.indices)
        hxx, hxy, hyy = terms.hess.unbind(-1)
        det = hxx * hyy - hxy**2
        safe = torch.where(det.abs() > 1e-12, det, torch.full_like(det, 1e-12))
        gx, gy = terms.grad.unbind(-1)
        step = -torch.stack((hyy * gx - hxy * gy, hxx * gy - hxy * gx), -1) / safe[:, None]
        length = torch.linalg.vector_norm(step, dim=-1, keepdim=True)
        xy = xy + step * (options.max_step / length.clamp(min=options.max_step))
    terms = fermat_terms(sea, xy, time, tx_rows, rx_rows, *problem.indices)
    converged = torch.linalg.vector_norm(terms.grad, dim=-1) < tol
    shape = (batch, starts)
    return (
        xy.reshape(*shape, 2),
        terms.slope.reshape(*shape, 2),
        terms.hess.reshape(*shape, 3),
        terms.point.reshape(*shape, 3),
        converged.reshape(shape),
    )


def _merge(xy, slope, hessian, point, departure, theta1, keep) -> RefractionPoints:
    """Distinct kept points per link, in the order found, padded to the largest count.

    Each round takes every link's first remaining start and drops the starts within
    :data:`MERGE_DISTANCE` of it, so the rounds number the most points any link has.
    """
    batch = keep.shape[0]
    remaining = keep.clone()
    rows = torch.arange(batch, device=keep.device)
    picks, found = [], []
    while bool(remaining.any()):
        first = remaining.to(torch.int8).argmax(-1)
        has = remaining[rows, first]
        near = torch.linalg.vector_norm(xy - xy[rows, first].unsqueeze(1), dim=-1) < MERGE_DISTANCE
        remaining &= ~(near & has.unsqueeze(-1))
        picks.append(first)
        found.append(has)
    if not picks:
        picks, found = [torch.zeros_like(rows)], [torch.zeros_like(rows, dtype=torch.bool)]
    take = torch.stack(picks, -1)
    count = take.shape[1]

    def gather(values: torch.Tensor) -> torch.Tensor:
        index = take.reshape(batch, count, *([1] * (values.dim() - 2))).expand(batch, count, *values.shape[2:])
        return torch.gather(values, 1, index)

    return RefractionPoints(
        point=gather(point),
        slope=gather(slope),
        hessian=gather(hessian),
        departure=gather(departure),
        theta1=gather(theta1),
        valid=torch.stack(found, -1),
        batch_size=[batch, count],
    )
