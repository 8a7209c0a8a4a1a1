"""The refracted optical path T → P → R through a wave surface (docs/model.md §3, paper Sec. III).

Three solvers find the same path: ``newton`` (default; :mod:`.newton`), ``newton_fixed``, the same
iteration with a fixed number of masked steps for one compiled graph (:mod:`.fixed`), and the
paper's ``centroid`` screen method (:mod:`.centroid`). :func:`solve_path` picks one.
"""

from __future__ import annotations

import torch

from waterair.core.validation import check_choice
from waterair.physics.optics import WATER_AIR, RefractiveIndices
from waterair.physics.paths.centroid import CentroidOptions, solve_centroid
from waterair.physics.paths.fixed import FixedNewtonOptions, solve_newton_fixed
from waterair.physics.paths.newton import NewtonOptions, solve_newton
from waterair.physics.paths.solution import (
    TRACK_LEASH,
    Iterate,
    PathProblem,
    PathSolution,
    finish_path,
    flat_sea_point,
    flat_sea_point_near,
    near_calm_point,
)
from waterair.physics.surface import WaveSurface

SolverOptions = NewtonOptions | FixedNewtonOptions | CentroidOptions
"""The options of one solver: which solver they are the options of picks it."""
METHODS: dict[str, type[SolverOptions]] = {
    "newton": NewtonOptions,
    "newton_fixed": FixedNewtonOptions,
    "centroid": CentroidOptions,
}
"""The solvers by name, each with the type of its options."""


def solve_path(
    surface: WaveSurface,
    tx: torch.Tensor,
    rx: torch.Tensor,
    t: float | torch.Tensor,
    method: str | SolverOptions = "newton",
    init: torch.Tensor | None = None,
    *,
    indices: RefractiveIndices = WATER_AIR,
    compiled: bool = False,
) -> PathSolution:
    """Find the primary refracted path from ``tx`` (under water) to ``rx`` (in air) at time ``t``.

    Args:
        surface: B sea realisations.
        tx, rx: transmitter and receiver positions (m), ``[B, 3]`` or ``[3]``.
        t: time (s), float or ``[B]``.
        method: the solver by name, ``"newton"``, ``"newton_fixed"`` or ``"centroid"`` (with its default
            options), or its options: :class:`NewtonOptions`, :class:`FixedNewtonOptions` or
            :class:`CentroidOptions`.
        init: start point (x, y) on the surface, ``[B, 2]`` (m); None starts from the flat-sea
            solution. Pass the previous step's ``point[:, :2]`` to warm-start.
        indices: the refractive indices either side of the surface.
        compiled: evaluate the surface through ``torch.compile`` (a one-off compile per process,
            then about the cost of one sin+cos pass per evaluation on CPU); the result matches
            the eager evaluation to rounding. The choice holds for this call only.
    """
    options = METHODS[check_choice("method", method, METHODS)]() if isinstance(method, str) else method
    batch = surface.batch_size[0]
    dtype, device = surface.omega.dtype, surface.omega.device
    tx = torch.as_tensor(tx, dtype=dtype, device=device).expand(batch, 3).contiguous()
    rx = torch.as_tensor(rx, dtype=dtype, device=device).expand(batch, 3).contiguous()
    problem = PathProblem(surface, tx, rx, t, RefractiveIndices(*indices))
    if init is None:
        init = flat_sea_point(tx, rx, *indices)[:, :2]
    if isinstance(options, NewtonOptions):
        return solve_newton(problem, init, options, compiled)
    if isinstance(options, FixedNewtonOptions):
        return solve_newton_fixed(problem, init, options, compiled)
    return solve_centroid(problem, init, options, compiled)


__all__ = [
    "METHODS",
    "TRACK_LEASH",
    "CentroidOptions",
    "FixedNewtonOptions",
    "Iterate",
    "NewtonOptions",
    "PathProblem",
    "PathSolution",
    "SolverOptions",
    "finish_path",
    "flat_sea_point",
    "flat_sea_point_near",
    "near_calm_point",
    "solve_path",
]
