"""Mean square slopes: what a sea holds (resolved and unresolved) and what Cox & Munk measured (docs/model.md §1.4).

Slopes are dimensionless; "upwind" is the slope component along the wind direction, "crosswind"
the one across it. The sea's values are integrals of its spectrum (float64 quadrature); the
measured ones are the clean-surface fits of Cox and Munk (1954).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import torch

from waterair.physics.sea.elfouhaily import K_M, curvature_spectrum, spreading_ratio

UPPER_WAVENUMBER = 40.0 * K_M
"""Where the slope integrals stop (rad/m): the short-wave term falls as exp[−¼(k/k_m − 1)²], below
1e-80 of its peak here, so the integral has converged to float64 precision."""
QUADRATURE_POINTS = 4001
"""Points of the log-spaced trapezoid rule of :func:`elfouhaily_slope_variance` (converged to 1e-6)."""


@dataclass(frozen=True)
class MeanSquareSlope:
    """A sea's mean square slopes (dimensionless), resolved by its harmonics and carried below its cutoff.

    Attributes:
        resolved_upwind, resolved_crosswind: slope variances of the simulated harmonics along and
            across the wind (their expectation over realisations).
        unresolved_upwind, unresolved_crosswind: slope variances of the waves shorter than the
            cutoff, which the channel applies as an angular spread (docs/model.md §1.3); 0 for the
            paper's sea.
    """

    resolved_upwind: float
    resolved_crosswind: float
    unresolved_upwind: float = 0.0
    unresolved_crosswind: float = 0.0

    @property
    def upwind(self) -> float:
        """σ_u², resolved + unresolved."""
        return self.resolved_upwind + self.unresolved_upwind

    @property
    def crosswind(self) -> float:
        """σ_c², resolved + unresolved."""
        return self.resolved_crosswind + self.unresolved_crosswind

    @property
    def resolved(self) -> float:
        """Resolved mss, both components."""
        return self.resolved_upwind + self.resolved_crosswind

    @property
    def unresolved(self) -> float:
        """Unresolved mss, both components."""
        return self.unresolved_upwind + self.unresolved_crosswind

    @property
    def total(self) -> float:
        """Total mss σ_u² + σ_c²."""
        return self.upwind + self.crosswind


class CoxMunk(NamedTuple):
    """Cox & Munk's (1954) clean-surface mean square slopes at one wind speed (dimensionless)."""

    upwind: float
    crosswind: float
    total: float


def cox_munk(wind: float) -> CoxMunk:
    """Clean-surface fits of Cox and Munk (1954, JOSA 44:838), eq. (1.15), at U (m/s, measured at 12.5 m).

    σ_u² = 3.16e-3 U, σ_c² = 0.003 + 1.92e-3 U, mss = 0.003 + 5.12e-3 U (the total is its own fit,
    so it differs from σ_u² + σ_c² by 4e-5 U). Measured for 1-14 m/s; used here up to 20 m/s.
    """
    return CoxMunk(3.16e-3 * wind, 0.003 + 1.92e-3 * wind, 0.003 + 5.12e-3 * wind)


def elfouhaily_slope_variance(
    low: torch.Tensor, high: torch.Tensor | float, wind: torch.Tensor, fetch: float
) -> tuple[torch.Tensor, torch.Tensor]:
    """Up- and crosswind slope variance of the Elfouhaily spectrum between wavenumbers ``low`` and ``high``, eq. (1.14).

    σ_u² = ∫ B(k) ½ (1 + Δ(k)/2) d(ln k),  σ_c² = ∫ B(k) ½ (1 − Δ(k)/2) d(ln k): the spreading
    Φ = (1/2π)(1 + Δ cos 2φ) puts ½(1 ± Δ/2) of each wavenumber's slope variance along and across
    the wind. A log-spaced float64 trapezoid rule.

    Args: low, high: wavenumbers (rad/m), ``[n]`` or scalars (``high`` may be ``inf``: the whole
    tail); wind: U10 (m/s) ``[n]``; fetch F (m). Returns two float64 ``[n]`` tensors.
    """
    wind = wind.to(torch.float64)
    low = torch.as_tensor(low, dtype=torch.float64).expand_as(wind)
    high = torch.as_tensor(high, dtype=torch.float64).clamp(max=UPPER_WAVENUMBER).expand_as(wind)
    fraction = torch.linspace(0.0, 1.0, QUADRATURE_POINTS, dtype=torch.float64)
    log_k = torch.log(low).unsqueeze(-1) + fraction * torch.log(high / low).clamp(min=0.0).unsqueeze(-1)
    k = torch.exp(log_k)
    curvature = curvature_spectrum(k, wind.unsqueeze(-1), fetch)
    delta = spreading_ratio(k, wind.unsqueeze(-1), fetch)
    upwind = torch.trapezoid(curvature * 0.5 * (1.0 + 0.5 * delta), log_k, dim=-1)
    crosswind = torch.trapezoid(curvature * 0.5 * (1.0 - 0.5 * delta), log_k, dim=-1)
    return upwind, crosswind


def rotated_covariance(upwind: torch.Tensor, crosswind: torch.Tensor, direction_deg: torch.Tensor) -> torch.Tensor:
    """Slope covariance (σ_xx, σ_xy, σ_yy) ``[n, 3]`` in the x-y frame, the wind toward ``direction_deg`` (from +x)."""
    angle = torch.deg2rad(direction_deg.to(upwind.dtype))
    cos, sin = torch.cos(angle), torch.sin(angle)
    xx = upwind * cos**2 + crosswind * sin**2
    yy = upwind * sin**2 + crosswind * cos**2
    xy = (upwind - crosswind) * cos * sin
    return torch.stack((xx, xy, yy), dim=-1)


def discrete_direction_factors(weights: torch.Tensor, theta: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Shares of slope variance along and across the wind, Σ_j w_j cos²θ_j and Σ_j w_j sin²θ_j.

    ``weights`` ``[..., n_dir]`` sum to 1 over the direction bins centred at ``theta`` ``[n_dir]`` (rad
    from the wind): what a discretised sea puts along each axis (½(1 ± Δ/2) for n_dir ≥ 3).
    """
    cos2 = torch.cos(theta) ** 2
    along = (weights * cos2).sum(-1)
    return along, 1.0 - along


__all__ = [
    "CoxMunk",
    "MeanSquareSlope",
    "cox_munk",
    "discrete_direction_factors",
    "elfouhaily_slope_variance",
    "rotated_covariance",
]
