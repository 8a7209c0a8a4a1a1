"""An independent Monte Carlo ray tracer of the channel: the reference of the fast model (docs/model.md §4.6).

Rays leave the transmitter with directions drawn around an axis (a proposal density q over solid
angle, importance-weighted to the beam's profile), each is intersected with the harmonic surface
(Newton on z(s) − η(x(s), y(s), t) along the ray), refracted by vector Snell about the surface
normal tilted by an unresolved facet slope drawn from the sea's covariance (``facets`` draws per
surface hit, which costs nothing like a surface evaluation), weighted by Fresnel transmission and
absorption, carried to the plane through the receiver across ``reference`` and counted inside the
aperture disk. It shares nothing with the fast model but the surface and the optics' formulas.

The hits are returned as :class:`~waterair.physics.channel.light.LightSamples` (each hit's weight is
its irradiance across its own direction, before the angular gains), so the gain of any pointing,
the upper bound and the light's centroid follow as for the fast model, from one set of rays. Units:
m, rad, 1/m² per unit on-axis radiant intensity.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import NamedTuple, cast

import torch

from waterair.core.validation import check_int, check_range
from waterair.physics.channel.facets import interception
from waterair.physics.channel.geometry import Transceiver
from waterair.physics.channel.light import LightSamples, pointed_gains
from waterair.physics.channel.model import ChannelModel, LinkEnds
from waterair.physics.channel.ray_tube import calm_sea_reference
from waterair.physics.channel.rays import departures, surface_hits
from waterair.physics.optics import (
    beam_divergence,
    per_link,
    refract,
    transverse_frame,
    unit_vector,
    water_transmittance,
)
from waterair.physics.paths import PathSolution
from waterair.physics.surface import Harmonics


class UnresolvedSlopes(NamedTuple):
    """A Monte Carlo model's per-episode constant: the sea's unresolved slope ``covariance`` ``[B, 3]``."""

    covariance: torch.Tensor


class MonteCarloLight(NamedTuple):
    """The hits of one trace: ``light`` (:class:`LightSamples`, ``[B, H]``, padded with zero weights),
    ``ray`` ``[B, H]`` (int64, which surface ray each hit came from, for the standard error) and
    ``rays`` ``[B]`` (int64, the surface rays traced per link)."""

    light: LightSamples
    ray: torch.Tensor
    rays: torch.Tensor


@dataclass(frozen=True)
class RayRequest:
    """What a Monte Carlo estimate is asked for: ``rays`` surface rays per link from a Gaussian proposal of
    standard deviation ``width`` (rad) per axis around the unit ``axis`` ``[B, 3]`` (up), ``per_ray`` draws for
    each (the counting tracer's facets, the local estimate's aperture points), the light read across the unit
    ``reference`` ``[B, 3]`` at R (the counting plane's normal, the aperture disk's), random numbers from
    ``generator`` (its device is where they are drawn), rays traced in chunks under ``memory`` elements of one
    ``[B, rays, K]`` surface evaluation. The proposal must cover every pointing the hits are weighted for."""

    axis: torch.Tensor
    reference: torch.Tensor
    width: float | torch.Tensor
    rays: int
    per_ray: int
    generator: torch.Generator
    memory: int = 2**23


class RayChunk(NamedTuple):
    """One chunk of a request's rays: the index of its first ray, their offsets ``tangent`` ``[B, n, 2]`` (rad)
    around the axis in its ``frame`` (e1, e2), and the ``draws`` ``[B, n, per_ray, ·]`` of each ray (facet
    slopes, or aperture points (m))."""

    start: int
    tangent: torch.Tensor
    frame: tuple[torch.Tensor, torch.Tensor]
    draws: torch.Tensor


@dataclass(frozen=True)
class RayEstimate(ChannelModel):
    """What the Monte Carlo models share (:class:`MonteCarlo` here, :class:`~.local_estimate.LocalEstimate`):
    eager estimates from a generator, the unresolved slope covariance as their episode constant, G_0 the exact
    calm-sea gain, and a Gaussian proposal ``proposal_beams`` beam divergences wide around the calm-sea
    departure. A model implements :meth:`estimate`; its ``light`` is the estimate's."""

    proposal_beams: float = 1.0

    needs_exact_point = False
    compiles = False
    Prepared = UnresolvedSlopes

    @staticmethod
    def check_settings(**settings) -> None:
        """Validate the settings given that every estimate has (``rays``, ``proposal_beams``)."""
        if "rays" in settings:
            check_int("rays", settings["rays"], 1, 10**9)
        if "proposal_beams" in settings:
            check_range("proposal_beams", settings["proposal_beams"], 0.0, 100.0, low_open=True)

    def reference_gain(self, tx: torch.Tensor, rx: torch.Tensor) -> torch.Tensor:
        return calm_sea_reference(tx, rx, self.optics)

    def prepare(self, tx: torch.Tensor, rx: torch.Tensor, unresolved: torch.Tensor) -> UnresolvedSlopes:
        """The unresolved slope covariance ``[B, 3]``."""
        return UnresolvedSlopes(unresolved.to(tx.dtype))

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
        return self.estimate(sea, cast(UnresolvedSlopes, prepared).covariance, ends, time, generator).light

    def estimate(
        self,
        sea: Harmonics,
        unresolved: torch.Tensor,
        ends: LinkEnds,
        time: float | torch.Tensor,
        generator: torch.Generator | None,
    ) -> MonteCarloLight:
        """The samples with the rays they came from (for :func:`standard_error`); arguments as :meth:`light`."""
        raise NotImplementedError

    def request(self, ends: LinkEnds, generator: torch.Generator | None, rays: int, per_ray: int) -> RayRequest:
        """What every estimate takes from the ends: the proposal's ``axis`` (the calm-sea departure) and ``width``
        (rad), the aperture's ``reference`` normal (the calm-sea arrival), with ``rays``, ``per_ray`` and the
        ``generator``."""
        if generator is None:
            raise ValueError(f"the {type(self).__name__} channel draws its rays from a generator; pass one")
        tx, rx, calm = ends.tx, ends.rx, ends.calm_point
        return RayRequest(
            axis=unit_vector(calm - tx),
            reference=unit_vector(rx - calm),
            width=self.proposal_beams * beam_divergence(self.optics.divergence, self.optics.wavelength),
            rays=rays,
            per_ray=per_ray,
            generator=generator,
        )


@dataclass(frozen=True)
class MonteCarlo(RayEstimate):
    """The hit-counting tracer as a channel model (``env/channel=counting``, and ``montecarlo`` on a sea without
    unresolved slopes; slow, for evaluation): ``rays``
    surface rays per link and step, ``facets`` unresolved-slope draws each, from a proposal
    ``proposal_beams`` beam divergences wide around the calm-sea departure, counted across the
    calm-sea arrival. Eager (it draws random numbers from the caller's generator).

    Attributes: rays in [1, 1e9]; facets in [1, 1e5]; proposal_beams in (0, 100].
    """

    rays: int = 20_000
    facets: int = 64
    proposal_beams: float = 1.0

    def __post_init__(self) -> None:
        self.check_settings(rays=self.rays, facets=self.facets, proposal_beams=self.proposal_beams)

    @staticmethod
    def check_settings(**settings) -> None:
        """Validate the settings given (``rays``, ``facets``, ``proposal_beams``)."""
        RayEstimate.check_settings(**settings)
        if "facets" in settings:
            check_int("facets", settings["facets"], 1, 10**5)

    def estimate(
        self,
        sea: Harmonics,
        unresolved: torch.Tensor,
        ends: LinkEnds,
        time: float | torch.Tensor,
        generator: torch.Generator | None,
    ) -> MonteCarloLight:
        """The hits with the rays they came from (for :func:`standard_error`); arguments as :meth:`light`."""
        request = self.request(ends, generator, self.rays, self.facets)
        return trace(sea, unresolved, ends.tx, ends.rx, time, self.optics, request)


def trace(
    sea: Harmonics,
    unresolved: torch.Tensor,
    tx: torch.Tensor,
    rx: torch.Tensor,
    t: float | torch.Tensor,
    optics: Transceiver,
    request: RayRequest,
) -> MonteCarloLight:
    """Trace ``request.rays`` rays per link from ``tx`` toward the surface, ``request.per_ray`` facet draws each.

    Args:
        sea: the resolved surfaces of B seas; unresolved: their slope covariance ``[B, 3]``, which tilts
            the facets (zero: the resolved surface only).
        tx, rx: T and R (m) ``[B, 3]``; t: time (s), a float or ``[B]``.
        optics: transceiver (attenuation, indices, aperture diameter).
        request: the proposal (a few beam widths), the rays and facets, and the counting plane through R
            (:class:`RayRequest`).
    """
    batch, dtype, device = tx.shape[0], tx.dtype, tx.device
    rays, facets, generator = request.rays, request.per_ray, request.generator
    frame = transverse_frame(request.axis)
    covariance = unresolved.to(torch.float64)
    xx, xy, yy = covariance.unbind(-1)
    jitter = 1e-30
    l11 = torch.sqrt(xx + jitter)
    l21 = xy / l11
    l22 = torch.sqrt((yy - l21**2).clamp(min=0.0) + jitter)
    cholesky = torch.stack((torch.stack((l11, torch.zeros_like(l11)), -1), torch.stack((l21, l22), -1)), -2)
    cholesky = torch.where((covariance.abs().sum(-1) > 0)[:, None, None], cholesky, torch.zeros_like(cholesky))
    pieces = []
    for start, tangent in ray_offsets(request, sea, tx):
        shape = (batch, tangent.shape[1], facets, 2)
        tilt = torch.randn(shape, generator=generator, dtype=torch.float64, device=generator.device).to(device)
        facet_slopes = torch.einsum("bij,bnmj->bnmi", cholesky.to(device), tilt).to(dtype)
        pieces.append(_trace_chunk(sea, tx, rx, t, optics, request, RayChunk(start, tangent, frame, facet_slopes)))
    weight, departure, arrival, ray = (torch.cat(part, dim=1) for part in zip(*pieces, strict=True))
    weight = weight / (rays * facets)
    keep = weight > 0
    order = torch.argsort((~keep).to(torch.int8), dim=1, stable=True)
    hits = max(1, int(keep.sum(1).max().item()))
    take = order[:, :hits]

    def gather(values: torch.Tensor) -> torch.Tensor:
        index = take.reshape(batch, hits, *([1] * (values.dim() - 2))).expand(batch, hits, *values.shape[2:])
        return torch.gather(values, 1, index)

    light = LightSamples(
        weight=gather(torch.where(keep, weight, torch.zeros_like(weight))),
        departure=gather(departure),
        arrival=gather(arrival),
    )
    counts = torch.full((batch,), rays, dtype=torch.int64, device=device)
    return MonteCarloLight(light=light, ray=gather(ray), rays=counts)


def ray_offsets(request: RayRequest, sea: Harmonics, tx: torch.Tensor) -> Iterator[tuple[int, torch.Tensor]]:
    """The ``request``'s rays in chunks of under ``request.memory`` elements of one surface evaluation of ``sea``:
    each chunk's first ray and the rays' offsets ``tangent`` ``[B, n, 2]`` (rad) around the axis, drawn from the
    proposal in float64 and handed over in ``tx``'s dtype and device. A caller draws its per-ray values from
    ``request.generator`` before it asks for the next chunk, so that a seed gives the same rays."""
    batch, generator = tx.shape[0], request.generator
    chunk = max(16, request.memory // (batch * sea.omega.shape[-1]))
    for start in range(0, request.rays, chunk):
        count = min(chunk, request.rays - start)
        draws = torch.randn(batch, count, 2, generator=generator, dtype=torch.float64, device=generator.device)
        yield start, (per_link(request.width, draws) * draws).to(device=tx.device, dtype=tx.dtype)


def standard_error(result: MonteCarloLight, tx_dir: torch.Tensor, rx_dir: torch.Tensor, optics: Transceiver):
    """(G, its standard error) ``[B]`` each (1/m²) for pointings ``[B, 3]``: the mean over surface rays
    and the standard deviation of the per-ray sums over sqrt(rays)."""
    shares = pointed_gains(result.light, tx_dir, rx_dir, optics)
    rays = int(result.rays.max().item())
    per_ray = torch.zeros(shares.shape[0], rays, dtype=shares.dtype, device=shares.device)
    per_ray.scatter_add_(1, result.ray, shares)
    per_ray = per_ray * rays  # each ray's own estimate of G (the weights carry 1/rays)
    gain = per_ray.mean(1)
    return gain, per_ray.std(1) / math.sqrt(rays)


def _trace_chunk(sea, tx, rx, t, optics: Transceiver, request: RayRequest, chunk: RayChunk):
    """One chunk of rays: (weight, departure, arrival, ray index), each ``[B, count · facets, ·]``."""
    start, facet_slopes, reference = chunk.start, chunk.draws, request.reference
    batch, count, facets = facet_slopes.shape[:3]
    area = math.pi * optics.aperture_diameter**2 / 4.0
    direction, proposal = departures(request.axis, *chunk.frame, chunk.tangent, request.width)
    point, resolved, distance = surface_hits(sea, tx, direction, t)
    # facets: the resolved slope plus each draw of the unresolved one
    slope = resolved.unsqueeze(2) + facet_slopes
    normal = torch.cat((-slope, torch.ones_like(slope[..., :1])), dim=-1)
    normal = normal / torch.linalg.vector_norm(normal, dim=-1, keepdim=True)
    incoming = direction.unsqueeze(2).expand_as(normal)
    out, transmitted = refract(incoming, -normal, optics.n_water, optics.n_air)
    theta1 = torch.acos((incoming * normal).sum(-1).clamp(-1.0, 1.0))
    # carried to the counting plane through R across `reference`
    to_plane = ((rx.unsqueeze(1) - point) * reference.unsqueeze(1)).sum(-1).unsqueeze(-1)
    slant = (out * reference[:, None, None, :]).sum(-1)
    reach = to_plane / slant.clamp(min=1e-12)
    landing = point.unsqueeze(2) + reach.unsqueeze(-1) * out
    inside = torch.linalg.vector_norm(landing - rx[:, None, None, :], dim=-1) <= optics.aperture_diameter / 2.0
    good = transmitted & (out[..., 2] > 0) & (slant > 1e-6) & inside & (reach > 0)
    transmitted_power = water_transmittance(
        theta1, distance.unsqueeze(-1), optics.n_water, optics.n_air, optics.attenuation_per_m
    )
    # the ray meets facets in proportion to their interception u₁·(−ζ, 1) against the mean surface's
    # u₁·(−ζ̄, 1) (docs/model.md §4.3): the draws, per unit horizontal area, weighted per intercepted ray
    facing = interception(incoming, slope)
    share = facing / interception(incoming, resolved.unsqueeze(2).expand_as(slope))
    # plane irradiance → irradiance across the ray (÷ cos), per unit on-axis intensity (÷ q)
    weight = transmitted_power * share / proposal.unsqueeze(-1) / area / slant.clamp(min=1e-12)
    weight = torch.where(good & (facing > 0) & torch.isfinite(weight), weight, torch.zeros_like(weight))
    ray = (start + torch.arange(count, device=tx.device)).view(1, count, 1).expand(batch, count, facets)
    departure = direction.unsqueeze(2).expand(batch, count, facets, 3)
    return (
        weight.reshape(batch, -1),
        departure.reshape(batch, -1, 3),
        out.reshape(batch, -1, 3),
        ray.reshape(batch, -1),
    )
