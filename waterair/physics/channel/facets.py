"""The facet that refracts a ray from T toward R, and how the receiver's aperture blurs it (docs/model.md §4.3).

A ray leaving T along u1 reaches R along u2 through a surface facet whose normal is parallel to

    w = n_w u1 − n_a u2                                                        (Snell's law, vector form)

so the facet's slope is (−w_x/w_z, −w_y/w_z). Moving the receiver across an aperture of diameter D
changes that slope by |∂ζ/∂R| per metre, whose variance over the disk (D/4 per axis) is the
aperture's blur in slope space. Units: m, dimensionless slopes.
"""

from __future__ import annotations

import math

import torch

from waterair.physics.channel.geometry import Transceiver


def facet_normal(u1: torch.Tensor, u2: torch.Tensor, optics: Transceiver) -> torch.Tensor:
    """w = n_w u1 − n_a u2 ``[..., 3]`` (unnormalised), the normal of the facet that turns u1 into u2."""
    return optics.n_water * u1 - optics.n_air * u2


def aperture_slope_variance(w: torch.Tensor, u2: torch.Tensor, r2: torch.Tensor, optics: Transceiver) -> torch.Tensor:
    """(D/4)² |∂ζ/∂R|² = (D/4 · n_a/r2)² |w·u2| / |w_z|³ ``[...]``: the variance, per axis, of the needed
    facet slope over the aperture (docs/model.md §4.3), for the facet normal ``w`` ``[..., 3]``, the
    arriving direction ``u2`` ``[..., 3]`` and the distance to the receiver ``r2`` (m)."""
    return (optics.aperture_diameter / 4.0 * optics.n_air / r2) ** 2 * (w * u2).sum(-1).abs() / w[..., 2].abs() ** 3


def interception(u1: torch.Tensor, slope: torch.Tensor) -> torch.Tensor:
    """u1·(−ζ_x, −ζ_y, 1) ``[...]``: how much of a ray along ``u1`` ``[..., 3]`` (up) a facet of slope ``ζ``
    ``[..., 2]`` intercepts per unit horizontal area (docs/model.md §4.3). Slope statistics (Cox and Munk)
    are per unit horizontal area; a ray meets the facets of slope ζ in proportion to this, so over facets
    N(ζ̄, Σ) the weight u1·(−ζ, 1) / u1·(−ζ̄, 1) averages to 1. Negative: the facet faces away from the ray."""
    return u1[..., 2] - (slope * u1[..., :2]).sum(-1)


def slope_density(deviation: torch.Tensor, covariance: torch.Tensor) -> torch.Tensor:
    """p_Σ(ζ) ``[...]``: the Gaussian density of a facet slope ``deviation`` ζ ``[..., 2]`` from its mean, for the
    covariance Σ ``[..., 3]`` (σ_xx², σ_xy, σ_yy², positive definite; broadcast against ζ), docs/model.md §4.3."""
    sxx, sxy, syy = covariance.unbind(-1)
    dx, dy = deviation.unbind(-1)
    determinant = sxx * syy - sxy**2
    quadratic = syy * dx**2 - 2.0 * sxy * dx * dy + sxx * dy**2
    return torch.exp(-0.5 * quadratic / determinant) / (2.0 * math.pi * torch.sqrt(determinant))
