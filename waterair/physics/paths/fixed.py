"""Newton's method with a fixed number of masked iterations (docs/model.md §3, solver 1b).

The same damped Newton iteration on Fermat's principle as :mod:`.newton`, shaped for one compiled
graph: every link takes the same ``iterations`` steps, converged links are masked rather than
removed, and the line search is spread over the iterations (a step whose length does not decrease
enough is refused and the next iteration tries half of it). There is no per-iteration Python, no
compaction and no host synchronisation, so ``torch.compile`` fuses the whole solve; each iteration
costs one surface evaluation. Started from a good prediction of the path point (the last two points
extrapolated: it moves smoothly), most links converge in one iteration.

The fixed count does not change the physics: :func:`solve_newton_fixed` hands the few links that
have not converged to the adaptive solver, which finishes them from where they stopped.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace

import torch

from waterair.core.validation import check_int
from waterair.physics.optics import RefractiveIndices
from waterair.physics.paths.newton import (
    NewtonOptions,
    call_compiled,
    check_step_keys,
    fermat_terms,
    iterate_newton,
    newton_direction,
)
from waterair.physics.paths.solution import Iterate, PathProblem, PathSolution
from waterair.physics.surface import Harmonics


@dataclass(frozen=True)
class FixedNewtonOptions:
    """Settings of the fixed-iteration solver.

    Attributes:
        iterations: Newton iterations every link takes (one surface evaluation each, plus one at
            the start point).
        finish: hand links that have not converged after ``iterations`` to the adaptive solver
            (:class:`NewtonOptions`); without it they are flagged invalid.
        tol, armijo, max_step: as in :class:`NewtonOptions`.
    """

    iterations: int = 2
    finish: bool = True
    tol: float | None = None
    armijo: float = 1e-4
    max_step: float = 2.0

    def __post_init__(self) -> None:
        check_int("iterations", self.iterations, 1, 100)
        check_step_keys(self.tol, self.armijo, self.max_step)

    def tolerance(self, dtype: torch.dtype) -> float:
        """The convergence threshold on |∇L| for ``dtype`` (defaults as in :class:`NewtonOptions`)."""
        return self.tol if self.tol is not None else (1e-11 if dtype == torch.float64 else 2e-5)


def fixed_newton_terms(sea: Harmonics, xy, t, tx, rx, indices: RefractiveIndices, opts: FixedNewtonOptions) -> Iterate:
    """``opts.iterations`` masked Newton iterations from ``xy`` ``[m, 2]``; a pure tensor function.

    Arguments as in :func:`waterair.physics.paths.newton.fermat_terms` (its ``n_w``, ``n_a`` the ``indices``),
    ``t`` ``[m]``; the convergence threshold is ``opts.tolerance`` of ``xy``'s dtype.
    """
    n_w, n_a = indices
    eps = torch.finfo(xy.dtype).eps
    tol, armijo, max_step = opts.tolerance(xy.dtype), opts.armijo, opts.max_step
    length, grad, hess, point, slope = fermat_terms(sea, xy, t, tx, rx, n_w, n_a)
    done = torch.linalg.vector_norm(grad, dim=-1) < tol
    fraction = torch.ones_like(length)
    taken = torch.zeros_like(length, dtype=torch.int64)
    for _ in range(opts.iterations):
        todo = ~done
        step = newton_direction(hess, grad, point, tx, rx, indices, max_step) * (fraction * todo).unsqueeze(-1)
        decrease = (grad * step).sum(-1)
        trial_xy = xy + step
        trial = fermat_terms(sea, trial_xy, t, tx, rx, n_w, n_a)
        # Below the rounding level of L the decrease test is meaningless: take the step.
        negligible = -decrease <= 16 * eps * length
        accept = todo & (negligible | (trial.length <= length + armijo * decrease))
        keep = accept.unsqueeze(-1)
        xy = torch.where(keep, trial_xy, xy)
        length = torch.where(accept, trial.length, length)
        grad = torch.where(keep, trial.grad, grad)
        hess = torch.where(keep, trial.hess, hess)
        point = torch.where(keep, trial.point, point)
        slope = torch.where(keep, trial.slope, slope)
        fraction = torch.where(accept | done, torch.ones_like(fraction), 0.5 * fraction)
        taken = taken + todo.long()
        done = torch.linalg.vector_norm(grad, dim=-1) < tol
    return Iterate(point, slope, xy, done, taken)


@functools.cache
def compiled_fixed_newton():
    """``torch.compile(fixed_newton_terms)``, built on first use and shared."""
    return torch.compile(fixed_newton_terms, dynamic=True)


def solve_newton_fixed(problem: PathProblem, init, opts: FixedNewtonOptions, compiled: bool = False) -> PathSolution:
    """The primary path from ``init`` ``[B, 2]`` (m); see :func:`waterair.physics.paths.solve_path`."""
    batch, dtype = problem.tx.shape[0], problem.tx.dtype
    time = torch.as_tensor(problem.t, dtype=dtype, device=problem.tx.device).expand(batch).contiguous()
    problem = replace(problem, t=time)
    stop = iterate_fixed(problem, init.to(dtype), opts, compiled)
    if opts.finish:
        stop = finish_unconverged(problem, stop, opts, compiled)
    return problem.path(stop)


def iterate_fixed(problem: PathProblem, xy, opts: FixedNewtonOptions, compiled: bool) -> Iterate:
    """:func:`fixed_newton_terms` on ``problem``'s paths (its time ``[B]``) from ``xy`` ``[B, 2]``, compiled or
    eagerly."""
    inputs = (xy, torch.as_tensor(problem.t), problem.tx, problem.rx)
    if not compiled:
        return fixed_newton_terms(problem.surface.harmonics, *inputs, problem.indices, opts)
    return call_compiled(compiled_fixed_newton(), problem.surface.harmonics, inputs, problem.indices, opts)


def finish_unconverged(problem: PathProblem, stop: Iterate, opts: FixedNewtonOptions, compiled: bool) -> Iterate:
    """Finish the paths of ``problem`` (its time ``[B]``) whose iterations ``stop``ped unconverged, from there.

    They are gathered and take ``opts.iterations`` more masked iterations, then the adaptive solver
    (:mod:`.newton`) takes the very few still left. One host synchronisation per stage: whether any
    link is left. Returns the updated iterate (its ``xy`` where the iterations of each path stopped).
    """
    left = (~stop.converged).nonzero().squeeze(-1)
    if left.numel() == 0:
        return stop
    point, slope, xy, done, taken = (v.clone() for v in stop)
    sub = problem.rows(left)
    p, s, sub_xy, d, k = iterate_fixed(sub, stop.xy[left], opts, compiled)
    still = (~d).nonzero().squeeze(-1)
    if still.numel():
        adaptive = NewtonOptions(tol=opts.tol, armijo=opts.armijo, max_step=opts.max_step)
        more = iterate_newton(sub.rows(still), sub_xy[still], adaptive, compiled)
        p[still], s[still], sub_xy[still], d[still] = more.point, more.slope, more.xy, more.converged
        k[still] += more.iterations
    point[left], slope[left], xy[left], done[left], taken[left] = p, s, sub_xy, d, taken[left] + k
    return Iterate(point, slope, xy, done, taken)
