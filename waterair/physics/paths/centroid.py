"""The paper's screen (centroid) method for the refracted path (docs/model.md §3, solver 2)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from waterair.core.validation import check_int, check_range
from waterair.physics.optics import refract, unit_vector
from waterair.physics.paths.solution import Iterate, PathProblem, PathSolution, finish_path


@dataclass(frozen=True)
class CentroidOptions:
    """Settings of the paper's screen (centroid) solver.

    Attributes:
        pixels: m, the screen has m × m pixels.
        fov: full angular width of the first screen (rad); the paper uses the receiver FOV.
        shrink: factor by which the pixel pitch shrinks once the centre settles. The paper uses
            10; 5 is the default because it agrees with Newton more often (docs/model.md).
        max_passes: cap on centroid passes (screens traced), all levels together.
        tol: stop when every centre moved less than this angle (rad).
        spot: width of the Gaussian intensity in pixels (see :func:`solve_centroid`).
        intersect_iter: Newton iterations of each ray-surface intersection.
        max_miss: a final miss distance at T above this (m) marks the path invalid.
    """

    pixels: int = 11
    fov: float = 0.34
    shrink: float = 5.0
    max_passes: int = 24
    tol: float = 1e-7
    spot: float = 1.0
    intersect_iter: int = 4
    max_miss: float = 0.01

    def __post_init__(self) -> None:
        check_int("pixels", self.pixels, 2, 256)
        check_range("fov", self.fov, 0.0, math.pi, low_open=True, high_open=True, unit="rad")
        check_range("shrink", self.shrink, 1.0, low_open=True)
        check_int("max_passes", self.max_passes, 1, 200)
        check_range("tol", self.tol, 0.0, low_open=True, unit="rad")
        check_range("spot", self.spot, 0.0, low_open=True)
        check_int("intersect_iter", self.intersect_iter, 1, 100)
        check_range("max_miss", self.max_miss, 0.0, low_open=True, unit="m")


def solve_centroid(problem: PathProblem, init, opts: CentroidOptions, compiled: bool = False) -> PathSolution:
    """The paper's screen method with the corrected centroid (docs/model.md §3, solver 2).

    A virtual screen at unit distance in front of the receiver, centred on the current direction
    estimate, spans ``fov`` with m × m pixels. Each pixel's ray goes from R down to the surface,
    refracts into the water, and gets an intensity from how far it passes from T. The centre moves
    to the intensity centroid (Σ I x / Σ I: the paper's Σ x denominator is a typo); once it moves
    less than half a pixel the pitch shrinks ``shrink``×, and this repeats until the centre stops
    moving (each element keeps its own pitch). The screen basis (e1, e2, centre) plays the role
    of the paper's R_z R_x R_z rotation.

    Intensity is Gaussian, exp(−|A⁻¹ miss|² / 2 spot²), where A is the screen's own local
    Jacobian (miss per pixel, from neighbouring pixels): the emitter "extent" of the paper is
    matched to the current pixel, so the centroid stays unbiased at every refinement even where
    surface curvature stretches the screen-to-miss map anisotropically. A fixed-width Gaussian
    either covers the whole screen (centroid pulled to the centre) or no pixel at all.
    """
    surface, tx, rx, t = problem.surface, problem.tx, problem.rx, problem.t
    n_w, n_a = problem.indices
    batch, dtype, device = tx.shape[0], tx.dtype, tx.device
    start = torch.cat((init, torch.zeros_like(init[:, :1])), dim=-1)
    centre = unit_vector(start - rx)
    offsets = torch.arange(opts.pixels, dtype=dtype, device=device) - 0.5 * (opts.pixels - 1)
    grid_u = offsets.repeat_interleave(opts.pixels)
    grid_v = offsets.repeat(opts.pixels)
    pitch = torch.full((batch, 1), 2.0 * math.tan(0.5 * opts.fov) / opts.pixels, dtype=dtype, device=device)
    reach = (-rx[:, 2:3] / centre[:, 2:3]).expand(-1, opts.pixels**2).contiguous()
    lit = torch.ones(batch, dtype=torch.bool, device=device)
    passes = torch.zeros(batch, dtype=torch.int64, device=device)
    for _ in range(opts.max_passes):
        e1, e2 = _basis(centre)
        screen = grid_u[:, None] * e1.unsqueeze(1) + grid_v[:, None] * e2.unsqueeze(1)
        rays = unit_vector(centre.unsqueeze(1) + pitch.unsqueeze(-1) * screen)
        hit, normal, reach, hit_ok = _intersect(surface, rx, rays, t, reach, opts.intersect_iter, compiled)
        into_water, ok = refract(rays, normal, n_a, n_w)
        to_tx = tx.unsqueeze(1) - hit
        along = (to_tx * into_water).sum(-1)
        miss = to_tx - along.unsqueeze(-1) * into_water
        offset = _pixel_offset(miss, into_water, opts.pixels)
        intensity = torch.exp(-(offset**2).sum(-1) / (2 * opts.spot**2)) * (ok & hit_ok & (along > 0))
        total = intensity.sum(-1)
        lit = total > 0
        weight = intensity / total.clamp(min=torch.finfo(dtype).tiny).unsqueeze(-1)
        du, dv = (weight * grid_u).sum(-1, keepdim=True), (weight * grid_v).sum(-1, keepdim=True)
        moved = torch.hypot(du, dv) * lit.unsqueeze(-1)
        centre = torch.where(lit.unsqueeze(-1), unit_vector(centre + pitch * (du * e1 + dv * e2)), centre)
        passes += 1
        if bool((moved * pitch < opts.tol).all()):
            break
        pitch = torch.where(moved < 0.5, pitch / opts.shrink, pitch)
        reach = reach.mean(-1, keepdim=True).expand(-1, opts.pixels**2).contiguous()

    point, normal, _, hit_ok = _intersect(
        surface, rx, centre.unsqueeze(1), t, reach[:, :1], 3 * opts.intersect_iter, compiled
    )
    point, normal = point.squeeze(1), normal.squeeze(1)
    into_water, ok = refract(centre, normal, n_a, n_w)
    to_tx = tx - point
    along = (to_tx * into_water).sum(-1)
    miss = torch.sqrt(((to_tx**2).sum(-1) - along**2).clamp(min=0))
    converged = lit & hit_ok.squeeze(1) & ok & (along > 0) & (miss < opts.max_miss)
    slope = -normal[:, :2] / normal[:, 2:3]
    return finish_path(Iterate(point, slope, point[:, :2], converged, passes), tx, rx, problem.indices)


def _intersect(surface, origin, rays, t, reach, iterations, compiled: bool):
    """Newton on s for origin + s·ray hitting the surface; rays ``[B, P, 3]`` going down.

    Returns hit points ``[B, P, 3]``, unit upward normals, the ray lengths s ``[B, P]`` and a
    bool mask of converged (|z − η| < 1e-4 m) intersections.
    """
    s = reach
    for _ in range(iterations):
        x = origin[:, None, 0] + s * rays[..., 0]
        y = origin[:, None, 1] + s * rays[..., 1]
        sample = surface.evaluate(x, y, t, order=1, compiled=compiled)
        gap = origin[:, None, 2] + s * rays[..., 2] - sample.height
        rate = rays[..., 2] - sample.dx * rays[..., 0] - sample.dy * rays[..., 1]
        s = s - gap / torch.where(rate.abs() > 1e-6, rate, -torch.ones_like(rate))
    x = origin[:, None, 0] + s * rays[..., 0]
    y = origin[:, None, 1] + s * rays[..., 1]
    sample = surface.evaluate(x, y, t, order=1, compiled=compiled)
    gap = origin[:, None, 2] + s * rays[..., 2] - sample.height
    hit = torch.stack((x, y, sample.height), dim=-1)
    normal = unit_vector(torch.stack((-sample.dx, -sample.dy, torch.ones_like(x)), dim=-1))
    ok = (gap.abs() < 1e-4) & (s > 0) & torch.isfinite(gap)
    return hit, normal, s, ok


def _pixel_offset(miss: torch.Tensor, direction: torch.Tensor, pixels: int) -> torch.Tensor:
    """Miss vectors ``[B, m², 3]`` expressed in pixels through the screen's local Jacobian, ``[B, m², 2]``.

    The miss vectors are projected onto a plane across the central pixel's refracted ray; their
    change between neighbouring pixels (central differences, per pixel) gives a 2 × 2 Jacobian
    A (m per pixel), and A⁻¹ miss is how far each pixel is from the one whose ray meets T.
    """
    batch = miss.shape[0]
    f1, f2 = _basis(direction[:, (pixels**2) // 2])
    planar = torch.stack(((miss * f1.unsqueeze(1)).sum(-1), (miss * f2.unsqueeze(1)).sum(-1)), dim=-1)
    grid = planar.reshape(batch, pixels, pixels, 2)
    d_u, d_v = torch.gradient(grid, dim=(1, 2))
    a, c = d_u[..., 0], d_u[..., 1]
    b, d = d_v[..., 0], d_v[..., 1]
    tiny = torch.finfo(miss.dtype).tiny
    det = a * d - b * c
    det = torch.where(det.abs() > tiny, det, torch.full_like(det, tiny))
    x, y = grid[..., 0], grid[..., 1]
    offset = torch.stack(((d * x - b * y) / det, (a * y - c * x) / det), dim=-1)
    return offset.reshape(batch, pixels**2, 2)


def _basis(centre: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Two unit vectors orthogonal to ``centre`` ``[B, 3]`` and to each other."""
    helper = torch.zeros_like(centre)
    helper[:, 0] = 1.0
    e2 = unit_vector(torch.linalg.cross(centre, helper, dim=-1))
    e1 = torch.linalg.cross(e2, centre, dim=-1)
    return e1, e2
