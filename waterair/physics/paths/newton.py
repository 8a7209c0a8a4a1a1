"""Newton's method on Fermat's principle for the refracted path (docs/model.md §3, solver 1).

The received ray refracts at a surface point P = (x, y, η(x, y, t)). P is a stationary point (for
the primary path, a minimum) of the optical path length

    L(x, y) = n_w |P − T| + n_a |R − P|,

and ∇L = 0 is exactly Snell's law about the local normal. The solver is damped Newton on ∇L = 0
with the analytic surface derivatives, an Armijo backtracking line search on L and a
positive-definite shift where the Hessian is not.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import NamedTuple

import torch

from waterair.core.validation import check_int, check_range
from waterair.physics.optics import RefractiveIndices
from waterair.physics.paths.solution import Iterate, PathProblem, PathSolution
from waterair.physics.surface import Harmonics, harmonic_sums


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
        check_int("max_backtracks", self.max_backtracks, 0, 60)
        check_step_keys(self.tol, self.armijo, self.max_step)


def check_step_keys(tol: float | None, armijo: float, max_step: float) -> None:
    """Validate the keys every Newton solver has (:class:`NewtonOptions`, ``FixedNewtonOptions``): ``tol`` in
    (0, 1] or None, ``armijo`` in (0, 0.5) and ``max_step`` > 0 (m)."""
    if tol is not None:
        check_range("tol", tol, 0.0, 1.0, low_open=True)
    check_range("armijo", armijo, 0.0, 0.5, low_open=True, high_open=True)
    check_range("max_step", max_step, 0.0, low_open=True, unit="m")


class FermatTerms(NamedTuple):
    """L (m), ∇L ``[m, 2]``, ∇²L as (L_xx, L_xy, L_yy) ``[m, 3]`` (1/m), the surface point P ``[m, 3]`` (m) and
    its slopes (η_x, η_y) ``[m, 2]`` at a batch of surface points (:func:`fermat_terms`)."""

    length: torch.Tensor
    grad: torch.Tensor
    hess: torch.Tensor
    point: torch.Tensor
    slope: torch.Tensor

    def select(self, index: torch.Tensor) -> FermatTerms:
        return FermatTerms(*(v[index] for v in self))

    def assign(self, index: torch.Tensor, other: FermatTerms) -> None:
        for mine, theirs in zip(self, other, strict=True):
            mine[index] = theirs


def _fermat(problem: PathProblem, xy: torch.Tensor, compiled: bool) -> FermatTerms:
    """L, ∇L and ∇²L at surface points ``xy`` ``[m, 2]`` of ``problem``'s paths (see :func:`fermat_terms`)."""
    time = torch.as_tensor(problem.t, dtype=xy.dtype, device=xy.device).expand(xy.shape[0]).contiguous()
    sea, ends = problem.surface.harmonics, (xy, time, problem.tx, problem.rx)
    if not compiled:
        return fermat_terms(sea, *ends, *problem.indices)
    return call_compiled(_compiled_fermat(), sea, ends, *problem.indices)


MIN_COMPILED_ROWS = 4
"""The fewest rows a compiled path kernel is called with: torch specialises a size of 0 or 1, and one equal to a
fixed size of the inputs (2 for (x, y), 3 for a position) shares its symbol and is specialised with it: a working
set of one, two or three links would compile the kernel again, for that size only (~10 s each on 2 cores)."""


def call_compiled(kernel, sea: Harmonics, inputs: tuple[torch.Tensor, ...], *settings):
    """``kernel(sea, *inputs, *settings)`` for a compiled path kernel with dynamic shapes, its outputs ``[m, ...]``
    (a named tuple, as the kernel's) for inputs of ``m`` rows, so that it keeps one graph whatever ``m`` is.

    Fewer than :data:`MIN_COMPILED_ROWS` rows are repeated up to it (the extra rows' results dropped), and views
    are copied: torch guards a view's size against its base's, so a start point sliced from a wider tensor, then
    one that is not a view, each compiled the kernel again (three graphs at a compiled environment's first reset).
    """
    rows = inputs[0].shape[0]
    if 0 < rows < MIN_COMPILED_ROWS:
        repeat = torch.arange(MIN_COMPILED_ROWS, device=inputs[0].device) % rows
        outputs = kernel(Harmonics(*(v[repeat] for v in sea)), *(v[repeat] for v in inputs), *settings)
        return type(outputs)(*(v[:rows] for v in outputs))
    sea = Harmonics(*(v.clone() if v._is_view() else v for v in sea))
    return kernel(sea, *(v.clone() if v._is_view() else v for v in inputs), *settings)


def fermat_terms(sea: Harmonics, xy, t, tx, rx, n_w: float, n_a: float) -> FermatTerms:
    """Evaluate L(x, y), its gradient and Hessian (docs/model.md §3) in closed form.

    With u1 = (P − T)/r1, u2 = (R − P)/r2, w = n_w u1 − n_a u2 and the tangents P_x = (1, 0, η_x),
    P_y = (0, 1, η_y):  ∂L/∂a = w · P_a,  ∂²L/∂a∂b = Σ_i (n_i/r_i)[P_a·P_b − (u_i·P_a)(u_i·P_b)]
    + w_z η_ab. A pure tensor function (the ``sea``'s components ``[m, K]``, ``xy`` ``[m, 2]``, ``t``
    ``[m]``, ``tx``/``rx`` ``[m, 3]``), so that ``torch.compile`` can fuse the surface sums and
    this algebra into one kernel. Returns :class:`FermatTerms`.
    """
    sums = harmonic_sums(sea, xy[:, :1], xy[:, 1:], t, 2)
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
    return FermatTerms(n_w * r1 + n_a * r2, grad, hess, point, torch.stack((dx, dy), dim=-1))


@functools.cache
def _compiled_fermat():
    return torch.compile(fermat_terms, dynamic=True)


def newton_direction(hess, grad, point, tx, rx, indices: RefractiveIndices, max_step: float) -> torch.Tensor:
    """Newton direction on a Hessian shifted to be positive definite, capped at ``max_step`` (m).

    ``hess`` (L_xx, L_xy, L_yy) ``[m, 3]``, ``grad`` ``[m, 2]``, ``point`` P ``[m, 3]``, between ``tx`` and ``rx``
    ``[m, 3]``; a pure tensor function.
    """
    n_w, n_a = indices
    hxx, hxy, hyy = hess.unbind(-1)
    r1 = torch.linalg.vector_norm(point - tx, dim=-1)
    r2 = torch.linalg.vector_norm(rx - point, dim=-1)
    floor = 1e-2 * (n_w / r1 + n_a / r2)  # a tenth-order fraction of the flat-sea curvature
    half_trace = 0.5 * (hxx + hyy)
    lam_min = half_trace - torch.sqrt((0.5 * (hxx - hyy)) ** 2 + hxy**2)
    shift = (floor - lam_min).clamp(min=0.0)
    a, c = hxx + shift, hyy + shift
    det = a * c - hxy**2
    gx, gy = grad.unbind(-1)
    step = -torch.stack((c * gx - hxy * gy, a * gy - hxy * gx), dim=-1) / det.unsqueeze(-1)
    length = torch.linalg.vector_norm(step, dim=-1, keepdim=True)
    return step * (max_step / length.clamp(min=max_step))


def solve_newton(problem: PathProblem, init, opts: NewtonOptions, compiled: bool = False) -> PathSolution:
    """The primary path from the start points ``init`` ``[B, 2]`` (m); see :func:`waterair.physics.paths.solve_path`."""
    return problem.path(iterate_newton(problem, init, opts, compiled))


def iterate_newton(problem: PathProblem, init, opts: NewtonOptions, compiled: bool = False) -> Iterate:
    """Adaptive Newton iterations from ``init`` ``[B, 2]`` (m)."""
    tx = problem.tx
    batch, dtype = tx.shape[0], tx.dtype
    tol = opts.tol if opts.tol is not None else (1e-11 if dtype == torch.float64 else 2e-5)
    eps = torch.finfo(dtype).eps
    n_w, n_a = problem.indices

    start = init.to(dtype).contiguous()
    ev = _fermat(problem, start, compiled)
    iterations = torch.zeros(batch, dtype=torch.int64, device=tx.device)
    done = torch.linalg.vector_norm(ev.grad, dim=-1) < tol

    # Working set: the rows still iterating. It is compacted (one gather of the surface) only when
    # it has shrunk 8×, so the gather cost stays below the evaluation cost it saves.
    rows = torch.arange(batch, device=tx.device)
    ws, ws_rows, ws_xy, ws_ev, ws_done = problem, rows, start, ev, done.clone()
    for _ in range(opts.max_iter):
        todo = ~ws_done
        count = int(todo.sum())
        if count == 0:
            break
        if count * 8 <= ws_rows.numel():
            keep = todo.nonzero().squeeze(-1)
            ws, ws_rows, ws_xy, ws_ev = ws.rows(keep), ws_rows[keep], ws_xy[keep], ws_ev.select(keep)
            todo = torch.ones(count, dtype=torch.bool, device=tx.device)

        step = newton_direction(ws_ev.hess, ws_ev.grad, ws_ev.point, ws.tx, ws.rx, problem.indices, opts.max_step)
        step = step * todo.unsqueeze(-1)
        slope = (ws_ev.grad * step).sum(-1)
        fraction = torch.ones_like(slope)
        trial = _fermat(ws, ws_xy + step, compiled)
        # Below the rounding level of L the decrease test is meaningless: take the step.
        negligible = -slope <= 16 * eps * ws_ev.length
        accepted = ~todo | negligible | (trial.length <= ws_ev.length + opts.armijo * slope)
        for _ in range(opts.max_backtracks):
            redo = (~accepted).nonzero().squeeze(-1)
            if redo.numel() == 0:
                break
            fraction[redo] *= 0.5
            part = _fermat(ws.rows(redo), ws_xy[redo] + fraction[redo, None] * step[redo], compiled)
            trial.assign(redo, part)
            accepted[redo] = part.length <= ws_ev.length[redo] + opts.armijo * fraction[redo] * slope[redo]

        # Rows already done took a zero step, so their trial evaluation is their current one.
        ws_xy = ws_xy + fraction.unsqueeze(-1) * step
        ws_ev = trial
        iterations[ws_rows] += todo.long()
        ws_done = torch.linalg.vector_norm(ws_ev.grad, dim=-1) < tol
        done[ws_rows] = ws_done
        ev.assign(ws_rows, ws_ev)

    return Iterate(ev.point, ev.slope, ev.point[:, :2], done, iterations)
