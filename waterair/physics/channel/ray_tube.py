"""The power one refraction point delivers: the ray-tube (stationary-phase) irradiance (docs/model.md §4.2).

For a point source of radiant intensity J(u) under the surface and a receiver at R, the irradiance
through one refraction point P (on a plane across the arriving ray) is

    E = J(u1) · T(θ1) · e^{−c r1} · n_a² |N·u1| |N·u2| / ((r1 r2)² |det H|)           (4.4)

with u1 = (P − T)/r1, u2 = (R − P)/r2, N = (−η_x, −η_y, 1) the surface normal (unnormalised) and
H the Hessian of the optical path length L(x, y) (§3), which the Newton solver builds. The factor
|N·u1|/r1² is the solid angle per unit surface area seen from T, and (n_a/r2)² |N·u2| / |det H| the
surface area per unit receiver area (the implicit-function theorem on ∇L(x, y; R) = 0). On a flat
sea at normal incidence E = J T e^{−c d_w} n_a² / (n_a d_w + n_w d_a)²: the paper's 1/(d_w + d_a)²
omits how refraction spreads the beam in air and overstates the calm-sea power by 1.34× at the
default geometry.

A curved surface focuses and spreads the beam (lensing): |det H_flat| / |det H| is the factor by
which one point's power differs from the calm sea's. At a caustic det H → 0; a finite aperture
bounds the power there (:func:`ray_tube_factor`). Gains here are per unit on-axis radiant intensity
(G_D(0) = 1, as in the paper's gain, docs/model.md §4.1): multiply by G_D and G_A for a pointing.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from waterair.physics.channel.facets import aperture_slope_variance, facet_normal
from waterair.physics.channel.geometry import Transceiver
from waterair.physics.channel.light import LightSamples
from waterair.physics.channel.model import ChannelModel, LinkEnds
from waterair.physics.optics import peak_arrival_gain, water_transmittance
from waterair.physics.paths import PathSolution, flat_sea_point
from waterair.physics.paths.newton import fermat_terms
from waterair.physics.surface import Harmonics, directional_third_derivatives

FOLD_CONSTANT = 2.705
"""κ / (σ b) of the aperture-bounded fold (docs/model.md §4.2): a pair of points merging at a fold
caustic, each with |ζ'| replaced by sqrt(ζ'² + κ), sums to the exact Gaussian-blurred peak
2 Γ(5/4) 8^{1/4} / sqrt(2π σ b) = 1.216 / sqrt(σ b)."""


@dataclass(frozen=True)
class RayTube(ChannelModel):
    """The exact power through the tracked refraction point, with its lensing (eq. 4.4), bounded at
    caustics by the aperture through the surface's third derivatives along the Hessian's axes: the full
    channel on a sea without unresolved slopes (``env/channel=full`` on the paper's sea)."""

    def reference_gain(self, tx: torch.Tensor, rx: torch.Tensor) -> torch.Tensor:
        return calm_sea_reference(tx, rx, self.optics)

    def light(
        self,
        sea: Harmonics,
        path: PathSolution,
        ends: LinkEnds,
        time: torch.Tensor,
        prepared: tuple,
        generator: torch.Generator | None = None,
        copies: int = 1,
    ) -> LightSamples:
        optics, xy = self.optics, path.point[:, :2]
        hessian = fermat_terms(sea, xy, time, ends.tx, ends.rx, optics.n_water, optics.n_air).hess
        third = directional_third_derivatives(sea, xy, time, hessian_eigenvectors(hessian))
        return ray_tube_light(path, hessian, ends.tx, ends.rx, optics, third)


def ray_tube_factor(
    point: torch.Tensor,
    slope: torch.Tensor,
    hessian: torch.Tensor,
    tx: torch.Tensor,
    rx: torch.Tensor,
    optics: Transceiver,
    third: torch.Tensor | None = None,
) -> torch.Tensor:
    """E / J(u1) of eq. (4.4) (1/m², Fresnel and absorption included) for refraction points ``[..., 3]``.

    Args:
        point: P (m) ``[..., 3]``; slope: (η_x, η_y) at P ``[..., 2]``; hessian: (L_xx, L_xy, L_yy)
            of the optical path length at P (1/m) ``[..., 3]``; tx, rx: T and R (m) broadcastable.
        optics: the transceiver (attenuation, indices, aperture D).
        third: the surface's third derivative along each eigenvector of H, ``[..., 2]`` (1/m²), or
            None. With it, each eigenvalue λ of A = H / w_z is bounded as sqrt(λ² + κ σ |η_vvv|),
            σ = the spread of the needed slope over the aperture (D/4 across it): the power stays
            finite at a caustic. Without it (a flat sea, a test of the bare formula), eq. (4.4) as is.
    """
    d1, d2 = point - tx, rx - point
    r1, r2 = torch.linalg.vector_norm(d1, dim=-1), torch.linalg.vector_norm(d2, dim=-1)
    u1, u2 = d1 / r1.unsqueeze(-1), d2 / r2.unsqueeze(-1)
    normal = torch.cat((-slope, torch.ones_like(slope[..., :1])), dim=-1)
    cos1 = (normal * u1).sum(-1).abs() / torch.linalg.vector_norm(normal, dim=-1)
    theta1 = torch.acos(cos1.clamp(max=1.0))
    transmitted = water_transmittance(theta1, r1, optics.n_water, optics.n_air, optics.attenuation_per_m)
    geometry = optics.n_air**2 * (normal * u1).sum(-1).abs() * (normal * u2).sum(-1).abs() / (r1 * r2) ** 2
    return transmitted * geometry / bounded_determinant(hessian, u1, u2, r2, optics, third)


def bounded_determinant(hessian, u1, u2, r2, optics: Transceiver, third=None) -> torch.Tensor:
    """|det H|, or with ``third`` its aperture-bounded value (see :func:`ray_tube_factor`), ``[...]`` (1/m²)."""
    hxx, hxy, hyy = hessian.unbind(-1)
    if third is None:
        return (hxx * hyy - hxy**2).abs()
    w = facet_normal(u1, u2, optics)
    w_z = w[..., 2]
    # A = H / w_z maps a step on the surface to the facet slope it needs; the aperture spreads that
    # slope by (D/4)·|∂ζ/∂R| (docs/model.md §4.3).
    spread = torch.sqrt(aperture_slope_variance(w, u2, r2, optics))
    half_trace, half_gap = 0.5 * (hxx + hyy), torch.sqrt((0.5 * (hxx - hyy)) ** 2 + hxy**2)
    eigen = torch.stack((half_trace - half_gap, half_trace + half_gap), dim=-1) / w_z.unsqueeze(-1)
    bounded = torch.sqrt(eigen**2 + FOLD_CONSTANT * spread.unsqueeze(-1) * third.abs())
    return bounded.prod(-1) * w_z**2


def hessian_eigenvectors(hessian: torch.Tensor) -> torch.Tensor:
    """Unit eigenvectors of the 2×2 (L_xx, L_xy, L_yy) ``[..., 3]``, the smaller eigenvalue's first: ``[..., 2, 2]``."""
    hxx, hxy, hyy = hessian.unbind(-1)
    angle = 0.5 * torch.atan2(2.0 * hxy, hxx - hyy)  # the larger eigenvalue's axis
    major = torch.stack((torch.cos(angle), torch.sin(angle)), dim=-1)
    minor = torch.stack((-torch.sin(angle), torch.cos(angle)), dim=-1)
    return torch.stack((minor, major), dim=-2)


def flat_sea_irradiance(tx: torch.Tensor, rx: torch.Tensor, optics: Transceiver) -> torch.Tensor:
    """Eq. (4.4) on a calm sea, per unit on-axis radiant intensity (1/m²), ``[B]`` for ``tx``/``rx`` ``[B, 3]``.

    In closed form: with θ1, θ2 the angles at the calm-sea point and r1, r2 the distances,
    E = T e^{−c r1} n_a² cos θ1 cos θ2 / ((r1 r2)² (n_w cos²θ1 / r1 + n_a cos²θ2 / r2)(n_w/r1 + n_a/r2)),
    which at normal incidence is T e^{−c d_w} n_a² / (n_a d_w + n_w d_a)² (eq. 4.5).
    """
    point = flat_sea_point(tx, rx, optics.n_water, optics.n_air)
    d1, d2 = point - tx, rx - point
    r1, r2 = torch.linalg.vector_norm(d1, dim=-1), torch.linalg.vector_norm(d2, dim=-1)
    cos1, cos2 = d1[:, 2] / r1, d2[:, 2] / r2
    c1, c2 = optics.n_water / r1, optics.n_air / r2
    determinant = (c1 * cos1**2 + c2 * cos2**2) * (c1 + c2)
    theta1 = torch.acos(cos1.clamp(max=1.0))
    transmitted = water_transmittance(theta1, r1, optics.n_water, optics.n_air, optics.attenuation_per_m)
    return transmitted * optics.n_air**2 * cos1 * cos2 / ((r1 * r2) ** 2 * determinant)


def calm_sea_reference(tx: torch.Tensor, rx: torch.Tensor, optics: Transceiver) -> torch.Tensor:
    """G_0 of the full channel: the aligned gain on a calm sea, ``[B]`` (1/m²), eq. (4.6).

    The exact calm-sea irradiance (:func:`flat_sea_irradiance`) times the peak arrival gain
    n_c² / sin² ω_A; the intensity I = G / G_0 is 1 for an aligned link on a calm sea.
    """
    return flat_sea_irradiance(tx, rx, optics) * peak_arrival_gain(optics.half_fov, optics.concentrator_index)


def ray_tube_light(
    path: PathSolution,
    hessian: torch.Tensor,
    tx: torch.Tensor,
    rx: torch.Tensor,
    optics: Transceiver,
    third: torch.Tensor | None = None,
) -> LightSamples:
    """One refraction point per link, the ``path``'s, as :class:`LightSamples` (N = 1): weight
    :func:`ray_tube_factor` (0 where the path is not valid), departure u1 and arrival u2. The other arguments
    as for :func:`ray_tube_factor`, each ``[B, ·]``; for a sea without unresolved slopes (docs/model.md §4.2)."""
    point, valid = path.point, path.valid
    slope = -path.normal[:, :2] / path.normal[:, 2:]
    factor = ray_tube_factor(point, slope, hessian, tx, rx, optics, third)
    factor = torch.where(valid & torch.isfinite(factor), factor, torch.zeros_like(factor))
    d1, d2 = point - tx, rx - point
    u1 = d1 / torch.linalg.vector_norm(d1, dim=-1, keepdim=True)
    u2 = d2 / torch.linalg.vector_norm(d2, dim=-1, keepdim=True)
    return LightSamples(
        weight=factor.unsqueeze(1),
        departure=u1.unsqueeze(1),
        arrival=u2.unsqueeze(1),
    )
