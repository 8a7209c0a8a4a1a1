"""The refracted optical path T → P → R through a wave surface (docs/model.md §3, paper Sec. III).

Three solvers find the same path: ``newton`` (default; :mod:`.newton`), ``newton_fixed``, the same
iteration with a fixed number of masked steps for one compiled graph (:mod:`.fixed`), and the
paper's ``centroid`` screen method (:mod:`.centroid`). :func:`solve_path` picks one.
"""

from __future__ import annotations

from typing import TypeVar

import torch

from waterair.core.validation import check_choice
from waterair.physics.optics import N_AIR, N_WATER
from waterair.physics.paths.centroid import CentroidOptions, solve_centroid
from waterair.physics.paths.fixed import FixedNewtonOptions, solve_newton_fixed
from waterair.physics.paths.newton import NewtonOptions, solve_newton
from waterair.physics.paths.solution import TRACK_LEASH, PathSolution, finish_path, flat_sea_point, near_calm_point
from waterair.physics.surface import WaveSurface

METHODS = ("newton", "newton_fixed", "centroid")
OptionsT = TypeVar("OptionsT", NewtonOptions, FixedNewtonOptions, CentroidOptions)


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
    options: NewtonOptions | FixedNewtonOptions | CentroidOptions | None = None,
    compiled: bool = False,
) -> PathSolution:
    """Find the primary refracted path from ``tx`` (under water) to ``rx`` (in air) at time ``t``.

    Args:
        surface: B sea realisations.
        tx, rx: transmitter and receiver positions (m), ``[B, 3]`` or ``[3]``.
        t: time (s), float or ``[B]``.
        method: ``"newton"``, ``"newton_fixed"`` or ``"centroid"``.
        init: start point (x, y) on the surface, ``[B, 2]`` (m); None starts from the flat-sea
            solution. Pass the previous step's ``point[:, :2]`` to warm-start.
        n_water, n_air: refractive indices.
        options: :class:`NewtonOptions`, :class:`FixedNewtonOptions` or :class:`CentroidOptions`
            matching ``method``.
        compiled: evaluate the surface through ``torch.compile`` (a one-off compile per process,
            then about the cost of one sin+cos pass per evaluation on CPU); the result matches
            the eager evaluation to rounding. The choice holds for this call only.
    """
    check_choice("method", method, METHODS)
    batch = surface.batch_size[0]
    dtype, device = surface.omega.dtype, surface.omega.device
    tx = torch.as_tensor(tx, dtype=dtype, device=device).expand(batch, 3).contiguous()
    rx = torch.as_tensor(rx, dtype=dtype, device=device).expand(batch, 3).contiguous()
    if init is None:
        init = flat_sea_point(tx, rx, n_water, n_air)[:, :2]
    if method == "newton":
        return solve_newton(surface, tx, rx, t, init, n_water, n_air, _options(options, NewtonOptions), compiled)
    if method == "newton_fixed":
        fixed = _options(options, FixedNewtonOptions)
        return solve_newton_fixed(surface, tx, rx, t, init, n_water, n_air, fixed, compiled)
    return solve_centroid(surface, tx, rx, t, init, n_water, n_air, _options(options, CentroidOptions), compiled)


def _options(options, kind: type[OptionsT]) -> OptionsT:
    """``options``, or the defaults of ``kind``; options of the other solver are an error."""
    if options is None:
        return kind()
    if not isinstance(options, kind):
        raise ValueError(f"options = {type(options).__name__}(...) does not fit this method; pass {kind.__name__}")
    return options


__all__ = [
    "METHODS",
    "TRACK_LEASH",
    "CentroidOptions",
    "FixedNewtonOptions",
    "NewtonOptions",
    "PathSolution",
    "finish_path",
    "flat_sea_point",
    "near_calm_point",
    "solve_path",
]
