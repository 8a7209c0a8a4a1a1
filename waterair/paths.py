"""The refracted optical path T → P → R through a wave surface (SPEC §3, paper Sec. III).

The received ray refracts at a surface point P = (x, y, η(x, y, t)). By Fermat's principle P is a
stationary point (for the primary path, a minimum) of the optical path length

    L(x, y) = n_w |P − T| + n_a |R − P|,

and ∇L = 0 is exactly Snell's law about the local normal. Two solvers find it:

* ``newton`` (default): damped Newton on ∇L = 0 with the analytic surface derivatives, an Armijo
  backtracking line search on L and a positive-definite shift where the Hessian is not.
* ``centroid``: the paper's screen method, kept for fidelity (see :func:`_solve_centroid`).

Invalid paths (no convergence, a ray meeting the surface from below its tangent plane, total
internal reflection) are flagged with ``valid = False``; no output is ever NaN.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import torch
from tensordict import tensorclass

from waterair._validation import check_choice, check_int, check_range
from waterair.optics import N_AIR, N_WATER, angle_between, critical_angle, refract
from waterair.surface import WaveSurface, compiled_kernel_enabled, harmonic_sums

METHODS = ("newton", "centroid")


@tensorclass
class PathSolution:
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
class NewtonOptions:
    """Settings of the Newton solver.

    Attributes:
        max_iter: iteration cap (cold starts need ~5, warm starts 1-3).
        tol: convergence threshold on |∇L| (dimensionless); None picks 1e-11 for float64 and
            2e-5 for float32 (float32 phases of ω t ≈ 250 rad carry ~1e-5 rad of rounding).
        armijo: sufficient-decrease constant of the line search.
        max_backtracks: step halvings tried before a step is taken anyway.
        max_step: damping: the longest horizontal Newton step (m).
    """

    max_iter: int = 40
    tol: float | None = None
    armijo: float = 1e-4
    max_backtracks: int = 10
    max_step: float = 2.0

    def __post_init__(self) -> None:
        check_int("max_iter", self.max_iter, 1, 10_000)
        if self.tol is not None:
            check_range("tol", self.tol, 0.0, 1.0, low_open=True)
        check_range("armijo", self.armijo, 0.0, 0.5, low_open=True, high_open=True)
        check_int("max_backtracks", self.max_backtracks, 0, 60)
        check_range("max_step", self.max_step, 0.0, low_open=True, unit="m")


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
        spot: width of the Gaussian intensity in pixels (see :func:`_solve_centroid`).
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


def solve_path(
    surface: WaveSurface,
    tx: torch.Tensor,
    rx: torch.Tensor,
    t: float | torch.Tensor,
    method: str = "newton",
    init: torch.Tensor | None = None,
    *,
    n_water: float = N_WATER,
    n_air: float = N_AIR,
    options: NewtonOptions | CentroidOptions | None = None,
) -> PathSolution:
    """Find the primary refracted path from ``tx`` (under water) to ``rx`` (in air) at time ``t``.

    Args:
        surface: B sea realisations.
        tx, rx: transmitter and receiver positions (m), ``[B, 3]`` or ``[3]``.
        t: time (s), float or ``[B]``.
        method: ``"newton"`` or ``"centroid"``.
        init: start point (x, y) on the surface, ``[B, 2]`` (m); None starts from the flat-sea
            solution. Pass the previous step's ``point[:, :2]`` to warm-start.
        n_water, n_air: refractive indices.
        options: :class:`NewtonOptions` or :class:`CentroidOptions` matching ``method``.
    """
    check_choice("method", method, METHODS)
    batch = surface.batch_size[0]
    dtype, device = surface.omega.dtype, surface.omega.device
    tx = torch.as_tensor(tx, dtype=dtype, device=device).expand(batch, 3).contiguous()
    rx = torch.as_tensor(rx, dtype=dtype, device=device).expand(batch, 3).contiguous()
    if init is None:
        init = flat_sea_point(tx, rx, n_water, n_air)[:, :2]
    if method == "newton":
        return _solve_newton(surface, tx, rx, t, init, n_water, n_air, options or NewtonOptions())
    return _solve_centroid(surface, tx, rx, t, init, n_water, n_air, options or CentroidOptions())


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


# --- Newton ------------------------------------------------------------------------------------


@dataclass
class _Fermat:
    """L, ∇L, ∇²L and the geometry at a batch of surface points (all leading shape ``[m]``)."""

    length: torch.Tensor
    grad: torch.Tensor
    hess: torch.Tensor
    point: torch.Tensor
    slope: torch.Tensor

    def select(self, index: torch.Tensor) -> _Fermat:
        return _Fermat(*(getattr(self, f)[index] for f in ("length", "grad", "hess", "point", "slope")))

    def assign(self, index: torch.Tensor, other: _Fermat) -> None:
        for f in ("length", "grad", "hess", "point", "slope"):
            getattr(self, f)[index] = getattr(other, f)


def _fermat(surface, xy, t, tx, rx, n_w, n_a) -> _Fermat:
    """L, ∇L and ∇²L at surface points ``xy`` ``[m, 2]`` (see :func:`fermat_terms`)."""
    time = torch.as_tensor(t, dtype=xy.dtype, device=xy.device).expand(xy.shape[0]).contiguous()
    inputs = (surface.omega, surface.phase, surface.kx, surface.ky, surface.amplitude, xy, time, tx, rx)
    if not compiled_kernel_enabled():
        return _Fermat(*fermat_terms(*inputs, n_w, n_a))
    if xy.shape[0] == 1:
        # torch.compile specialises size 1: a lone row would compile a second graph (~1 s) the
        # first time a working set shrinks to it. Evaluate it twice instead and keep one.
        inputs = tuple(v.expand(2, *v.shape[1:]).contiguous() for v in inputs)
        return _Fermat(*(v[:1] for v in _compiled_fermat()(*inputs, n_w, n_a)))
    return _Fermat(*_compiled_fermat()(*inputs, n_w, n_a))


def fermat_terms(omega, phase, kx, ky, amplitude, xy, t, tx, rx, n_w: float, n_a: float):
    """Evaluate L(x, y), its gradient and Hessian (SPEC §3) in closed form.

    With u1 = (P − T)/r1, u2 = (R − P)/r2, w = n_w u1 − n_a u2 and the tangents P_x = (1, 0, η_x),
    P_y = (0, 1, η_y):  ∂L/∂a = w · P_a,  ∂²L/∂a∂b = Σ_i (n_i/r_i)[P_a·P_b − (u_i·P_a)(u_i·P_b)]
    + w_z η_ab. A pure tensor function (surface components ``[m, K]``, ``xy`` ``[m, 2]``, ``t``
    ``[m]``, ``tx``/``rx`` ``[m, 3]``), so that ``torch.compile`` can fuse the surface sums and
    this algebra into one kernel. Returns (L, ∇L ``[m, 2]``, (L_xx, L_xy, L_yy) ``[m, 3]``,
    P ``[m, 3]``, (η_x, η_y) ``[m, 2]``).
    """
    sums = harmonic_sums(omega, phase, kx, ky, amplitude, xy[:, :1], xy[:, 1:], t, 2)
    eta, dx, dy, dxx, dxy, dyy = (v.squeeze(-1) for v in sums)
    point = torch.stack((xy[:, 0], xy[:, 1], eta), dim=-1)
    d1, d2 = point - tx, rx - point
    r1, r2 = torch.linalg.vector_norm(d1, dim=-1), torch.linalg.vector_norm(d2, dim=-1)
    u1, u2 = d1 / r1.unsqueeze(-1), d2 / r2.unsqueeze(-1)
    w = n_w * u1 - n_a * u2
    grad = torch.stack((w[:, 0] + w[:, 2] * dx, w[:, 1] + w[:, 2] * dy), dim=-1)
    u1a, u1b = u1[:, 0] + u1[:, 2] * dx, u1[:, 1] + u1[:, 2] * dy
    u2a, u2b = u2[:, 0] + u2[:, 2] * dx, u2[:, 1] + u2[:, 2] * dy
    c1, c2 = n_w / r1, n_a / r2
    hxx = c1 * (1 + dx**2 - u1a**2) + c2 * (1 + dx**2 - u2a**2) + w[:, 2] * dxx
    hxy = c1 * (dx * dy - u1a * u1b) + c2 * (dx * dy - u2a * u2b) + w[:, 2] * dxy
    hyy = c1 * (1 + dy**2 - u1b**2) + c2 * (1 + dy**2 - u2b**2) + w[:, 2] * dyy
    hess = torch.stack((hxx, hxy, hyy), dim=-1)
    return n_w * r1 + n_a * r2, grad, hess, point, torch.stack((dx, dy), dim=-1)


@functools.cache
def _compiled_fermat():
    return torch.compile(fermat_terms, dynamic=True)


def _newton_step(ev: _Fermat, tx, rx, n_w, n_a, max_step: float) -> torch.Tensor:
    """Newton direction on a Hessian shifted to be positive definite, capped at ``max_step`` (m)."""
    hxx, hxy, hyy = ev.hess.unbind(-1)
    r1 = torch.linalg.vector_norm(ev.point - tx, dim=-1)
    r2 = torch.linalg.vector_norm(rx - ev.point, dim=-1)
    floor = 1e-2 * (n_w / r1 + n_a / r2)  # a tenth-order fraction of the flat-sea curvature
    half_trace = 0.5 * (hxx + hyy)
    lam_min = half_trace - torch.sqrt((0.5 * (hxx - hyy)) ** 2 + hxy**2)
    shift = (floor - lam_min).clamp(min=0.0)
    a, c = hxx + shift, hyy + shift
    det = a * c - hxy**2
    gx, gy = ev.grad.unbind(-1)
    step = -torch.stack((c * gx - hxy * gy, a * gy - hxy * gx), dim=-1) / det.unsqueeze(-1)
    length = torch.linalg.vector_norm(step, dim=-1, keepdim=True)
    return step * (max_step / length.clamp(min=max_step))


def _solve_newton(surface, tx, rx, t, init, n_w, n_a, opts: NewtonOptions) -> PathSolution:
    batch, dtype = tx.shape[0], tx.dtype
    tol = opts.tol if opts.tol is not None else (1e-11 if dtype == torch.float64 else 2e-5)
    eps = torch.finfo(dtype).eps
    t_all = t if isinstance(t, torch.Tensor) and t.dim() > 0 else None

    start = init.to(dtype).contiguous()
    ev = _fermat(surface, start, t, tx, rx, n_w, n_a)
    iterations = torch.zeros(batch, dtype=torch.int64, device=tx.device)
    done = torch.linalg.vector_norm(ev.grad, dim=-1) < tol

    # Working set: the rows still iterating. It is compacted (one gather of the surface) only when
    # it has shrunk 8×, so the gather cost stays below the evaluation cost it saves.
    rows = torch.arange(batch, device=tx.device)
    ws_surface, ws_tx, ws_rx, ws_t = surface, tx, rx, t
    ws_rows, ws_xy, ws_ev, ws_done = rows, start, ev, done.clone()
    for _ in range(opts.max_iter):
        todo = ~ws_done
        count = int(todo.sum())
        if count == 0:
            break
        if count * 8 <= ws_rows.numel():
            keep = todo.nonzero().squeeze(-1)
            ws_surface, ws_tx, ws_rx = ws_surface[keep], ws_tx[keep], ws_rx[keep]
            ws_rows, ws_xy, ws_ev = ws_rows[keep], ws_xy[keep], ws_ev.select(keep)
            ws_t = t_all[ws_rows] if t_all is not None else t
            todo = torch.ones(count, dtype=torch.bool, device=tx.device)

        step = _newton_step(ws_ev, ws_tx, ws_rx, n_w, n_a, opts.max_step) * todo.unsqueeze(-1)
        slope = (ws_ev.grad * step).sum(-1)
        fraction = torch.ones_like(slope)
        trial = _fermat(ws_surface, ws_xy + step, ws_t, ws_tx, ws_rx, n_w, n_a)
        # Below the rounding level of L the decrease test is meaningless: take the step.
        negligible = -slope <= 16 * eps * ws_ev.length
        accepted = ~todo | negligible | (trial.length <= ws_ev.length + opts.armijo * slope)
        for _ in range(opts.max_backtracks):
            redo = (~accepted).nonzero().squeeze(-1)
            if redo.numel() == 0:
                break
            fraction[redo] *= 0.5
            sub_t = ws_t[redo] if isinstance(ws_t, torch.Tensor) and ws_t.dim() > 0 else ws_t
            part = _fermat(
                ws_surface[redo],
                ws_xy[redo] + fraction[redo, None] * step[redo],
                sub_t,
                ws_tx[redo],
                ws_rx[redo],
                n_w,
                n_a,
            )
            trial.assign(redo, part)
            accepted[redo] = part.length <= ws_ev.length[redo] + opts.armijo * fraction[redo] * slope[redo]

        # Rows already done took a zero step, so their trial evaluation is their current one.
        ws_xy = ws_xy + fraction.unsqueeze(-1) * step
        ws_ev = trial
        iterations[ws_rows] += todo.long()
        ws_done = torch.linalg.vector_norm(ws_ev.grad, dim=-1) < tol
        done[ws_rows] = ws_done
        ev.assign(ws_rows, ws_ev)

    return _finish(ev.point, ev.slope, tx, rx, done, iterations, n_w, n_a)


def _finish(point, slope, tx, rx, converged, iterations, n_w, n_a) -> PathSolution:
    """Directions, angles and lengths of the path through ``point``; flags invalid paths."""
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


# --- centroid (paper) --------------------------------------------------------------------------


def _solve_centroid(surface, tx, rx, t, init, n_w, n_a, opts: CentroidOptions) -> PathSolution:
    """The paper's screen method with the corrected centroid (SPEC §3, solver 2).

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
    batch, dtype, device = tx.shape[0], tx.dtype, tx.device
    start = torch.cat((init, torch.zeros_like(init[:, :1])), dim=-1)
    centre = _unit(start - rx)
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
        rays = _unit(centre.unsqueeze(1) + pitch.unsqueeze(-1) * screen)
        hit, normal, reach, hit_ok = _intersect(surface, rx, rays, t, reach, opts.intersect_iter)
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
        centre = torch.where(lit.unsqueeze(-1), _unit(centre + pitch * (du * e1 + dv * e2)), centre)
        passes += 1
        if bool((moved * pitch < opts.tol).all()):
            break
        pitch = torch.where(moved < 0.5, pitch / opts.shrink, pitch)
        reach = reach.mean(-1, keepdim=True).expand(-1, opts.pixels**2).contiguous()

    point, normal, _, hit_ok = _intersect(surface, rx, centre.unsqueeze(1), t, reach[:, :1], 3 * opts.intersect_iter)
    point, normal = point.squeeze(1), normal.squeeze(1)
    into_water, ok = refract(centre, normal, n_a, n_w)
    to_tx = tx - point
    along = (to_tx * into_water).sum(-1)
    miss = torch.sqrt(((to_tx**2).sum(-1) - along**2).clamp(min=0))
    converged = lit & hit_ok.squeeze(1) & ok & (along > 0) & (miss < opts.max_miss)
    slope = -normal[:, :2] / normal[:, 2:3]
    return _finish(point, slope, tx, rx, converged, passes, n_w, n_a)


def _intersect(surface, origin, rays, t, reach, iterations):
    """Newton on s for origin + s·ray hitting the surface; rays ``[B, P, 3]`` going down.

    Returns hit points ``[B, P, 3]``, unit upward normals, the ray lengths s ``[B, P]`` and a
    bool mask of converged (|z − η| < 1e-4 m) intersections.
    """
    s = reach
    for _ in range(iterations):
        x = origin[:, None, 0] + s * rays[..., 0]
        y = origin[:, None, 1] + s * rays[..., 1]
        sample = surface.evaluate(x, y, t, order=1)
        gap = origin[:, None, 2] + s * rays[..., 2] - sample.height
        rate = rays[..., 2] - sample.dx * rays[..., 0] - sample.dy * rays[..., 1]
        s = s - gap / torch.where(rate.abs() > 1e-6, rate, -torch.ones_like(rate))
    x = origin[:, None, 0] + s * rays[..., 0]
    y = origin[:, None, 1] + s * rays[..., 1]
    sample = surface.evaluate(x, y, t, order=1)
    gap = origin[:, None, 2] + s * rays[..., 2] - sample.height
    hit = torch.stack((x, y, sample.height), dim=-1)
    normal = _unit(torch.stack((-sample.dx, -sample.dy, torch.ones_like(x)), dim=-1))
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
    e2 = _unit(torch.linalg.cross(centre, helper, dim=-1))
    e1 = torch.linalg.cross(e2, centre, dim=-1)
    return e1, e2


def _unit(v: torch.Tensor) -> torch.Tensor:
    return v / torch.linalg.vector_norm(v, dim=-1, keepdim=True)
