"""Optics of the water-air link: Snell refraction, Fresnel transmittance and the four gain terms.

docs/model.md §4 (paper Sec. II, eqs. (2)-(5)). Angles in radians, distances in metres.
"""

from __future__ import annotations

import math
from typing import NamedTuple, overload

import torch

N_WATER = 1.33
"""Refractive index of sea water n_w (paper n1), docs/model.md §0."""
N_AIR = 1.0
"""Refractive index of air n_a (paper n2), docs/model.md §0."""


class RefractiveIndices(NamedTuple):
    """The refractive indices either side of the sea surface: ``n_water`` below (paper n1), ``n_air`` above."""

    n_water: float = N_WATER
    n_air: float = N_AIR


WATER_AIR = RefractiveIndices()
"""Sea water below the surface, air above (:data:`N_WATER`, :data:`N_AIR`)."""

WATER_ATTENUATION_PER_M = {
    "pure_sea": 0.056,
    "clear_ocean": 0.151,
    "coastal": 0.398,
    "harbor": 2.17,
}
"""Attenuation coefficient c (1/m) at 532 nm for the usual water types (docs/model.md §4)."""
Scalar = float | torch.Tensor
"""A number of the configuration as a float, or as the 0-dim tensor a compiled step takes it as (:func:`traced`),
or, for a number each link has its own of (the beam divergence), a ``[B]`` tensor."""


def per_link(value: Scalar, like: torch.Tensor) -> Scalar:
    """``value`` as it broadcasts against ``like`` ``[B, ...]``, in ``like``'s dtype: a ``[B]`` tensor (one value per
    link) gets a unit dimension for each of ``like``'s after the first, a tensor shaped as ``like`` stays so; a float
    or a 0-dim tensor is returned as it is."""
    if isinstance(value, torch.Tensor) and value.dim() >= 1:  # in like's dtype, as a 0-dim tensor would act
        value = value.to(like.dtype)
        return value.reshape(value.shape[0], *(1,) * (like.dim() - 1)) if value.dim() == 1 else value
    return value


def traced(
    value: float, device: torch.device | str | None = None, dtype: torch.dtype = torch.float64, dims: int = 1
) -> torch.Tensor:
    """``value`` as a compiled step takes a number that differs between environments: a tensor on ``device``, an
    input of the graph (a float would be compiled in as a constant, one graph per value).

    One element in one dimension by default, in the ``dtype`` the step computes in (it takes part in type
    promotion as a tensor, not as a number), so that it acts as the number would against a link's values. A
    0-dim float64 tensor on the CPU (``dims=0``), which promotes as a number, is also read by torch.compile as
    one, which inductor then turns back into a tensor by restarting the compile: each first compile traced its
    graph twice."""
    return torch.tensor(float(value), dtype=dtype, device=device).reshape((1,) * dims)


def critical_angle(n1: float = N_WATER, n2: float = N_AIR) -> float:
    """Critical angle asin(n2 / n1) (rad) for light going from index n1 into n2 < n1."""
    return math.asin(n2 / n1) if n2 < n1 else math.pi / 2


def refract(direction: torch.Tensor, normal: torch.Tensor, n1: float, n2: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Snell's law in vector form.

    Args:
        direction: unit propagation direction of the incident ray, ``[..., 3]``.
        normal: unit surface normal on the incident side (``normal · direction < 0``), ``[..., 3]``.
        n1, n2: refractive indices of the incident and transmitted media.

    Returns:
        The unit transmitted direction ``[..., 3]`` and a bool mask, False where the ray is
        totally internally reflected (the direction there is the reflected one, never NaN).
    """
    ratio = n1 / n2
    cos_i = -(normal * direction).sum(-1, keepdim=True)
    sin2_t = ratio**2 * (1.0 - cos_i**2)
    transmitted = sin2_t <= 1.0
    cos_t = torch.sqrt(torch.clamp(1.0 - sin2_t, min=0.0))
    refracted = ratio * direction + (ratio * cos_i - cos_t) * normal
    reflected = direction + 2.0 * cos_i * normal
    return torch.where(transmitted, refracted, reflected), transmitted.squeeze(-1)


def fresnel_transmittance(theta1: torch.Tensor, n1: float = N_WATER, n2: float = N_AIR) -> torch.Tensor:
    """Unpolarised Fresnel power transmittance G_ref = 1 − ½(r_s² + r_p²) (docs/model.md §4, paper eq. (4)).

    Args:
        theta1: incidence angle in the first medium (rad), any shape.
        n1, n2: refractive indices of the incident and transmitted media.

    0 beyond the critical angle (total internal reflection). Normal incidence 1.33 → 1 gives
    1 − ((1.33 − 1)/(1.33 + 1))² ≈ 0.9799.
    """
    cos1 = torch.cos(theta1)
    sin2 = (n1 / n2) * torch.sin(theta1)
    total_reflection = sin2.abs() >= 1.0
    cos2 = torch.sqrt(torch.clamp(1.0 - sin2**2, min=0.0))
    r_s = (n1 * cos1 - n2 * cos2) / (n1 * cos1 + n2 * cos2)
    r_p = (n2 * cos1 - n1 * cos2) / (n2 * cos1 + n1 * cos2)
    transmittance = 1.0 - 0.5 * (r_s**2 + r_p**2)
    return torch.where(total_reflection, torch.zeros_like(transmittance), transmittance)


def water_transmittance(
    theta1: torch.Tensor, d_water: torch.Tensor, n1: float, n2: float, attenuation: float
) -> torch.Tensor:
    """T(θ1) e^{−c d_water}: the share of a ray's power that crosses the water and the surface (docs/model.md §4.2).

    Args:
        theta1: incidence angle on the surface (rad); d_water: the ray's length in water (m).
        n1, n2: refractive indices of water and air; attenuation: c (1/m).
    """
    return fresnel_transmittance(theta1, n1, n2) * torch.exp(-attenuation * d_water)


@overload
def beam_divergence(divergence: float, wavelength: float) -> float: ...
@overload
def beam_divergence(divergence: torch.Tensor, wavelength: float) -> torch.Tensor: ...
def beam_divergence(divergence: Scalar, wavelength: float) -> Scalar:
    """ω_D' = ω_D sqrt(1 + (λ/(π ω_D²))²) (rad): G_D ≈ exp(−2 α²/ω_D'²) for small α (docs/model.md §4.1, eq. 9.1).

    Args:
        divergence: beam divergence ω_D (rad): a float, or a tensor (0-dim as a compiled step gets it,
            :meth:`~waterair.physics.channel.Transceiver.traced`; ``[B]``, one per link), which gives a tensor.
        wavelength: wavelength λ (m).
    """
    spread = 1.0 + (wavelength / (math.pi * divergence**2)) ** 2
    return divergence * (torch.sqrt(spread) if isinstance(spread, torch.Tensor) else math.sqrt(spread))


def departure_gain(alpha_d: torch.Tensor, divergence: Scalar, wavelength: float) -> torch.Tensor:
    """Gaussian-beam departure gain G_D(α_D) (docs/model.md §4, paper eq. (2)), dimensionless, G_D(0) = 1.

    Args:
        alpha_d: angle between the transmitter's pointing and the departing ray (rad), ``[B, ...]``.
        divergence: beam divergence ω_D (rad), a float, a 0-dim tensor or one per link ``[B]`` (:func:`per_link`).
        wavelength: wavelength λ (m).
    """
    return departure_gain_at(torch.sin(alpha_d), torch.cos(alpha_d), divergence, wavelength)


def departure_gain_at(sin_d: torch.Tensor, cos_d: torch.Tensor, divergence: Scalar, wavelength: float) -> torch.Tensor:
    """:func:`departure_gain` from the sine and cosine of α_D (:func:`sin_cos_between`), without the angle."""
    squared = divergence**2  # in float64 from a per-link tensor, as from a float, then in the angle's dtype
    spread = 1.0 + (wavelength * cos_d / per_link(math.pi * squared, cos_d)) ** 2
    return torch.exp(-2.0 * sin_d**2 / (per_link(squared, cos_d) * spread))


def path_gain(d_water: torch.Tensor, d_air: torch.Tensor, attenuation: float) -> torch.Tensor:
    """Path gain G_p = exp(−c d_water) / (d_water + d_air)² (1/m²), docs/model.md §4, paper eq. (3).

    Args:
        d_water, d_air: ray lengths in water and air (m).
        attenuation: attenuation coefficient c > 0 (1/m).

    Correction: the paper writes exp(α d_water); attenuation must reduce the gain.
    """
    return torch.exp(-attenuation * d_water) / (d_water + d_air) ** 2


def arrival_gain(
    alpha_a: torch.Tensor, half_fov: float, concentrator_index: float = 1.0, cos_a: torch.Tensor | None = None
) -> torch.Tensor:
    """Receiver gain G_A = (n_c² / sin² ω_A) cos α_A inside the FOV, 0 outside (docs/model.md §4, paper eq. (5)).

    Args:
        alpha_a: angle between the receiver boresight and the reversed arriving ray (rad).
        half_fov: receiver half field of view ω_A (rad).
        concentrator_index: concentrator refractive index n_c (paper n2).
        cos_a: cos α_A where the caller has it (:func:`sin_cos_between`); else taken of ``alpha_a``.
    """
    inside = alpha_a <= half_fov
    gain = peak_arrival_gain(half_fov, concentrator_index) * (torch.cos(alpha_a) if cos_a is None else cos_a)
    return torch.where(inside, gain, torch.zeros_like(gain))


def arrival_gain_over_cell(
    alpha_a: torch.Tensor,
    steps: tuple[torch.Tensor, torch.Tensor],
    half_fov: float,
    concentrator_index: float = 1.0,
    cos_a: torch.Tensor | None = None,
) -> torch.Tensor:
    """G_A averaged over a lattice node's cell (docs/model.md §4.3, "The field of view's edge"): (n_c² / sin² ω_A)
    cos α_A times the share of the cell seen within the field of view, where α_A changes linearly across the
    cell by ``steps`` (a, b) (rad, each shaped as ``alpha_a``) along its two axes: P(α_A + a s + b t ≤ ω_A) for
    s, t uniform on [-1/2, 1/2]. With no change across the cell (steps 0) it is :func:`arrival_gain`, bit for
    bit. ``cos_a``: as :func:`arrival_gain`'s."""
    inside = _cell_share(half_fov - alpha_a, steps[0].abs(), steps[1].abs())
    gain = peak_arrival_gain(half_fov, concentrator_index) * (torch.cos(alpha_a) if cos_a is None else cos_a)
    return torch.where(inside > 0, gain * inside, torch.zeros_like(gain))


def _cell_share(margin: torch.Tensor, p: torch.Tensor, q: torch.Tensor) -> torch.Tensor:
    """P(p s + q t ≤ margin) for s, t uniform on [-1/2, 1/2], p, q ≥ 0: the distribution function of the sum of
    two uniforms of widths p and q (a trapezoid's), 1 or 0 by the sign of ``margin`` where both vanish."""
    wide, narrow = torch.maximum(p, q), torch.minimum(p, q)
    y = margin + (wide + narrow) / 2  # from the sum's lowest value
    tiny = torch.finfo(margin.dtype).tiny
    ramp = (y - narrow / 2) / wide.clamp(min=tiny)
    corner = 2 * wide * narrow
    rising = y**2 / corner.clamp(min=tiny)
    falling = 1 - (wide + narrow - y) ** 2 / corner.clamp(min=tiny)
    share = torch.where(y < narrow, rising, torch.where(y <= wide, ramp, falling))
    share = torch.where(y <= 0, torch.zeros_like(share), torch.where(y >= wide + narrow, torch.ones_like(share), share))
    return torch.where(wide > 0, share, (margin >= 0).to(margin.dtype))


def peak_arrival_gain(half_fov: float, concentrator_index: float = 1.0) -> float:
    """G_A at α_A = 0: n_c² / sin² ω_A (docs/model.md §4, paper eq. (5)); ω_A in rad."""
    return concentrator_index**2 / math.sin(half_fov) ** 2


def angle_between(u: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Angle (rad) between unit vectors ``[..., 3]``, accurate near 0 and π (atan2 of |u×v|, u·v)."""
    return torch.atan2(*sin_cos_between(u, v))


def sin_cos_between(u: torch.Tensor, v: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The sine and cosine of the angle between unit vectors ``[..., 3]``: |u×v| and u·v, what
    :func:`angle_between` takes the atan2 of. Where a gain needs only them, no atan2, sine or cosine is taken
    (:func:`sin_cos_of_components` where the vectors are held by component)."""
    return torch.linalg.vector_norm(torch.linalg.cross(u, v, dim=-1), dim=-1), (u * v).sum(-1)


def sin_cos_of_components(
    u: tuple[torch.Tensor, torch.Tensor, torch.Tensor], v: tuple[torch.Tensor, torch.Tensor, torch.Tensor]
) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`sin_cos_between` of unit vectors given by their components (x, y, z), each a tensor, all broadcasting
    together: the layout in which the full channel's gains loop over its nodes (components as contiguous
    ``[B, N]`` planes; ``[B, N, 3]`` vectors compile to loops several times slower, docs/benchmarks.md
    "Channels")."""
    cross = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
    return torch.sqrt(cross[0] ** 2 + cross[1] ** 2 + cross[2] ** 2), dot_of_components(u, v)


def dot_of_components(
    u: tuple[torch.Tensor, torch.Tensor, torch.Tensor], v: tuple[torch.Tensor, torch.Tensor, torch.Tensor]
) -> torch.Tensor:
    """u · v of vectors given by their components (:func:`sin_cos_of_components`)."""
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def unit_vector(v: torch.Tensor) -> torch.Tensor:
    """``v / |v|`` along the last dimension (``[..., 3]``)."""
    return v / torch.linalg.vector_norm(v, dim=-1, keepdim=True)


def transverse_frame(axis: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Two unit vectors (e1, e2) ``[n, 3]`` across the unit ``axis`` ``[n, 3]``: e1 the projection of +x,
    e2 = axis × e1 (the quadrant detector's axes, the Monte Carlo tracer's tangent plane)."""
    east = torch.zeros_like(axis)
    east[:, 0] = 1.0
    e1 = east - (east * axis).sum(-1, keepdim=True) * axis
    e1 = e1 / torch.linalg.vector_norm(e1, dim=-1, keepdim=True)
    return e1, torch.linalg.cross(axis, e1, dim=-1)
