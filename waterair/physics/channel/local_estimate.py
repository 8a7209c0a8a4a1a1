"""The Monte Carlo reference as a local estimate (next-event estimation), docs/model.md §4.6.

The hit-counting tracer (:mod:`.montecarlo`) draws a facet at every surface hit and counts the rays that
happen to land in the aperture: about 10⁻³ of them for a 5 cm disk at 10 m. The local estimate keeps
every hit: rays leave T from an importance-sampled proposal around the calm-sea departure (density q per
steradian), each meets the resolved surface at P (Newton along the ray), and each hit sends its light to
``points`` points R′ drawn uniformly on the aperture disk. Toward each R′ (direction u₂, distance r₂) the
weight is the density, per steradian of u₂, with which a facet of the unresolved slope distribution
refracts the ray toward R′ (:func:`facet_density`), times the Fresnel transmission of that facet and the
absorption e^{−c r₁}, over q r₂²: the irradiance across the ray at R′ per unit on-axis radiant intensity.
Its mean over the rays and the points is the aperture's mean irradiance, the quantity the counting tracer
estimates, without the counting.

The facet normal that refracts u₁ into u₂ is h ∥ n_w u₁ − n_a u₂ (Snell's law in vector form); the density
of u₂ is that of the facet slope ζ = −(h_x, h_y)/h_z, a Gaussian N(ζ̄, Σ) around the resolved slope ζ̄ at P,
times |∂ζ/∂Ω₂| = (1/h_z³) · n_a² (u₂·h) / |n_w u₁ − n_a u₂|² (slope to normal, then normal to arrival
direction; Walter et al. 2007, eq. 16-17). Integrated over every arrival direction it is the probability
that the facet transmits at all (1 below the critical angle; tested). Units: m, rad, 1/sr, 1/m².
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from waterair.core.validation import check_int
from waterair.physics.channel.facets import interception, slope_density
from waterair.physics.channel.geometry import Transceiver
from waterair.physics.channel.light import LightSamples
from waterair.physics.channel.model import LinkEnds
from waterair.physics.channel.montecarlo import (
    MonteCarloLight,
    RayChunk,
    RayEstimate,
    RayRequest,
    UnresolvedSlopes,
    ray_offsets,
)
from waterair.physics.channel.rays import FEWEST_ITERATIONS, departures, surface_hits
from waterair.physics.optics import transverse_frame, water_transmittance
from waterair.physics.surface import Harmonics


def arrival_jacobian(
    incoming: torch.Tensor, outgoing: torch.Tensor, n_water: float, n_air: float
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """|∂ζ/∂Ω₂| (per steradian), the facet normal h ``[..., 3]`` and whether a facet refracts u₁ into u₂.

    The facet that refracts ``incoming`` u₁ (water, up) into ``outgoing`` u₂ (air) has the normal
    h ∥ n_w u₁ − n_a u₂ and the slope ζ = −(h_x, h_y)/h_z; the Jacobian of ζ against the arrival direction
    is (1/h_z³) · n_a² (u₂·h) / |n_w u₁ − n_a u₂|² (docs/model.md §4.6). No facet does where h would face
    down or u₁, u₂ lie on the wrong sides of it (the ray would need to pass the critical angle).
    """
    bend = n_water * incoming - n_air * outgoing
    length = torch.linalg.vector_norm(bend, dim=-1)
    normal = bend / length.unsqueeze(-1)
    cos_in, cos_out, cos_up = (incoming * normal).sum(-1), (outgoing * normal).sum(-1), normal[..., 2]
    valid = (cos_up > 0) & (cos_in > 0) & (cos_out > 0)
    jacobian = n_air**2 * cos_out / length**2 / cos_up.clamp(min=1e-30) ** 3
    return torch.where(valid, jacobian, torch.zeros_like(jacobian)), normal, valid


def facet_density(
    incoming: torch.Tensor,
    outgoing: torch.Tensor,
    mean_slope: torch.Tensor,
    covariance: torch.Tensor,
    n_water: float,
    n_air: float,
) -> tuple[torch.Tensor, torch.Tensor]:
    """p(u₂ | u₁) per steradian of u₂, and the facet's unit normal h ``[..., 3]`` (docs/model.md §4.6).

    Args:
        incoming: u₁ ``[..., 3]``, the unit ray in the water (up); outgoing: u₂ ``[..., 3]``, a unit direction
            in the air.
        mean_slope: ζ̄ ``[..., 2]``, the resolved surface slope where the ray meets it.
        covariance: Σ ``[..., 3]`` (σ_xx², σ_xy, σ_yy²), the unresolved slope covariance (positive definite).
        n_water, n_air: refractive indices.

    Zero where no facet refracts u₁ into u₂ (:func:`arrival_jacobian`). Fresnel transmission and
    absorption are not included.
    """
    jacobian, normal, valid = arrival_jacobian(incoming, outgoing, n_water, n_air)
    slope = -normal[..., :2] / normal[..., 2:].clamp(min=1e-30)
    gaussian = slope_density(slope - mean_slope, covariance)
    return torch.where(valid, gaussian * jacobian, torch.zeros_like(jacobian)), normal


def facet_share(incoming: torch.Tensor, normal: torch.Tensor, mean_slope: torch.Tensor) -> torch.Tensor:
    """u₁·(−ζ, 1) / u₁·(−ζ̄, 1) ``[...]``: the facet of unit ``normal`` h intercepts this share of the ray
    ``incoming`` u₁ against the mean surface of slope ``mean_slope`` ζ̄ (:func:`.facets.interception`)."""
    facing = (incoming * normal).sum(-1) / normal[..., 2].clamp(min=1e-30)  # u₁·h / h_z = u₁·(−ζ, 1)
    return facing / interception(incoming, mean_slope.expand_as(normal[..., :2]))


@dataclass(frozen=True)
class LocalEstimate(RayEstimate):
    """The local estimate as a channel model (``env/channel=montecarlo`` on a two-scale sea; slow, for
    evaluation): ``rays`` surface rays per link and step from a proposal ``proposal_beams`` beam divergences
    wide around the calm-sea departure, each sending its light to ``points`` points of the aperture. Eager
    (it draws from the caller's generator). It needs unresolved slopes (Σ > 0); on a sea without them the
    counting tracer is the reference.

    Attributes: rays in [1, 1e9]; points in [1, 1e4]; proposal_beams in (0, 100].
    """

    rays: int = 20_000
    points: int = 1
    proposal_beams: float = 0.5

    def __post_init__(self) -> None:
        self.check_settings(rays=self.rays, points=self.points, proposal_beams=self.proposal_beams)

    @staticmethod
    def check_settings(**settings) -> None:
        """Validate the settings given (``rays``, ``points``, ``proposal_beams``)."""
        RayEstimate.check_settings(**settings)
        if "points" in settings:
            check_int("points", settings["points"], 1, 10**4)

    def prepare(self, tx: torch.Tensor, rx: torch.Tensor, unresolved: torch.Tensor) -> UnresolvedSlopes:
        """The unresolved slope covariance ``[B, 3]`` the facet density uses; refused where it is not positive."""
        xx, xy, yy = unresolved.to(torch.float64).unbind(-1)
        if not bool(((xx > 0) & (xx * yy - xy**2 > 0)).all()):
            raise ValueError("the local estimate needs unresolved slopes (a two-scale sea with wind); a link has none")
        return super().prepare(tx, rx, unresolved)

    def estimate(
        self,
        sea: Harmonics,
        unresolved: torch.Tensor,
        ends: LinkEnds,
        time: float | torch.Tensor,
        generator: torch.Generator | None,
    ) -> MonteCarloLight:
        """The samples with the rays they came from (for :func:`.montecarlo.standard_error`); as :meth:`light`."""
        request = self.request(ends, generator, self.rays, self.points)
        return local_estimate(sea, unresolved, ends.tx, ends.rx, time, self.optics, request)


def local_estimate(
    sea: Harmonics,
    unresolved: torch.Tensor,
    tx: torch.Tensor,
    rx: torch.Tensor,
    t: float | torch.Tensor,
    optics: Transceiver,
    request: RayRequest,
) -> MonteCarloLight:
    """``request.rays`` rays per link from ``tx``, each sent to ``request.per_ray`` aperture points:
    ``[B, rays · points]`` samples.

    Args:
        sea: the resolved surfaces of B seas; unresolved: their slope covariance Σ ``[B, 3]`` (positive).
        tx, rx: T and R (m) ``[B, 3]``; t: time (s), a float or ``[B]``.
        optics: transceiver (attenuation, indices, aperture diameter).
        request: the proposal, the rays and points, and the aperture disk's normal at R (:class:`RayRequest`).
    """
    batch, dtype, device = tx.shape[0], tx.dtype, tx.device
    rays, points, generator = request.rays, request.per_ray, request.generator
    frame = transverse_frame(request.axis)
    a1, a2 = transverse_frame(request.reference)
    radius = optics.aperture_diameter / 2.0
    pieces = []
    for start, tangent in ray_offsets(request, sea, tx):
        shape = (batch, tangent.shape[1], points, 2)
        disk = torch.rand(shape, generator=generator, dtype=torch.float64, device=generator.device)
        disk = disk.to(device=device, dtype=dtype)
        rho, phi = radius * torch.sqrt(disk[..., 0]), 2.0 * math.pi * disk[..., 1]
        offset = (rho * torch.cos(phi)).unsqueeze(-1) * a1[:, None, None, :] + (rho * torch.sin(phi)).unsqueeze(
            -1
        ) * a2[:, None, None, :]
        target = rx[:, None, None, :] + offset
        pieces.append(_estimate_chunk(sea, tx, t, optics, request, RayChunk(start, tangent, frame, target), unresolved))
    weight, departure, arrival, ray = (torch.cat(part, dim=1) for part in zip(*pieces, strict=True))
    light = LightSamples(weight=weight / (rays * points), departure=departure, arrival=arrival)
    counts = torch.full((batch,), rays, dtype=torch.int64, device=device)
    return MonteCarloLight(light=light, ray=ray, rays=counts)


def _estimate_chunk(sea, tx, t, optics: Transceiver, request: RayRequest, chunk: RayChunk, unresolved):
    """One chunk of rays: (weight, departure, arrival, ray index), each ``[B, count · points, ·]``."""
    start, target = chunk.start, chunk.draws
    batch, count, points = target.shape[:3]
    direction, proposal = departures(request.axis, *chunk.frame, chunk.tangent, request.width)
    point, resolved, distance = surface_hits(sea, tx, direction, t, FEWEST_ITERATIONS)
    toward = target - point.unsqueeze(2)
    reach = torch.linalg.vector_norm(toward, dim=-1)
    outgoing = toward / reach.unsqueeze(-1)
    incoming = direction.unsqueeze(2).expand_as(outgoing)
    density, normal = facet_density(
        incoming,
        outgoing,
        resolved.unsqueeze(2),
        unresolved[:, None, None, :].to(tx.dtype),
        optics.n_water,
        optics.n_air,
    )
    theta1 = torch.acos((incoming * normal).sum(-1).clamp(-1.0, 1.0))
    transmitted = water_transmittance(
        theta1, distance.unsqueeze(-1), optics.n_water, optics.n_air, optics.attenuation_per_m
    )
    # the ray meets facets in proportion to their interception, u₁·(−ζ, 1) = u₁·h / h_z, against the mean
    # surface's u₁·(−ζ̄, 1) (docs/model.md §4.3): p(ζ) per unit horizontal area becomes per intercepted ray
    share = facet_share(incoming, normal, resolved.unsqueeze(2))
    # irradiance across the ray at R′ per unit on-axis intensity: (power per sr toward u₂) / r₂², over q
    weight = transmitted * density * share / reach**2 / proposal.unsqueeze(-1)
    good = (outgoing[..., 2] > 0) & torch.isfinite(weight)
    weight = torch.where(good, weight, torch.zeros_like(weight))
    ray = (start + torch.arange(count, device=tx.device)).view(1, count, 1).expand(batch, count, points)
    return (
        weight.reshape(batch, -1),
        incoming.reshape(batch, -1, 3),
        outgoing.reshape(batch, -1, 3),
        ray.reshape(batch, -1),
    )
