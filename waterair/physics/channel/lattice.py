"""The two-scale channel: light through the resolved surface and the unresolved slopes (docs/model.md §4.3).

On a sea whose waves beyond the cutoff are carried as a slope covariance Σ (§1.3), every surface
point can send light to the receiver: it takes a facet whose extra slope ζ bends the ray from T
exactly toward R, and ζ is Gaussian with covariance Σ. The irradiance at R is the integral over
the resolved surface (horizontal coordinates s)

    E = ∫ ds J(u1) T(θ1) e^{−c r1} (|N·u1| / r1²) · p_Σ(ζ(s)) · (n_a/r2)² |w·u2| / |w_z|³     (4.8)

with u1, u2 the directions T → P(s) → R, w = n_w u1 − n_a u2 (the normal a facet needs, by Snell's
law), ζ(s) = (−w_x/w_z − η_x, −w_y/w_z − η_y) the slope it needs beyond the resolved one, and the
last factor |det ∂ζ/∂R| (how fast ζ changes as the receiver moves). Every refraction point of the
resolved sea lies where ζ = 0, each lit by its lensing, and the caustics between them are smooth:
(4.8) is (4.4) summed over points, blurred by Σ (for Σ → 0 it tends to that sum). The aperture
adds its own blur: a disk of diameter D averages the pattern over (D/4)² per axis.

It is integrated by the trapezoid rule on an n × n lattice shaped by the Gaussian the integrand would be
on a calm sea (the patch the blur spreads the light over, times the beam's footprint): spectrally
accurate for Gaussian-like integrands. Two lattices of that shape: one around the tracked refraction
point, independent of the pointing, for the upper bound; one where the beam meets the patch (the
product of the patch and the footprint around the point the beam is aimed at), for the gain and the
quadrant detector, so that a pointing far off the patch (straight up) still has nodes under its light.
Measured against the local estimate in docs/model.md §4.3. Eagerly, the lattice's surface sums take 1 + 2n
complex exponentials per harmonic rather than one per node (:func:`~waterair.physics.surface.lattice_harmonic_sums`);
a compiled step sums at each node, which inductor runs faster.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple, cast

import torch

from waterair.core.validation import check_int, check_range
from waterair.physics.channel.facets import aperture_slope_variance, facet_normal, interception, slope_density
from waterair.physics.channel.geometry import Transceiver
from waterair.physics.channel.light import LightSamples, Reception, joined, receive, repeated, sliced
from waterair.physics.channel.model import ChannelModel, LinkEnds
from waterair.physics.channel.ray_tube import calm_sea_reference
from waterair.physics.optics import beam_divergence, water_transmittance
from waterair.physics.paths import PathSolution, flat_sea_point, near_calm_point
from waterair.physics.surface import Harmonics, lattice_harmonic_sums, lattice_nodes

LATTICE_NODES = 9
"""Nodes per axis of each lattice (2 n² surface evaluations per link with the beam's own): chosen with
:data:`LATTICE_SPAN` from the accuracy-cost table against the local estimate (docs/model.md §4.3)."""
LATTICE_SPAN = 4.5
"""Half-width of the lattice in standard deviations of its Gaussian: wide enough not to clip the skewed
integrand's tail (4 clipped 0.3-0.5 %), with nodes no further apart than 1.125 of them."""
BEAM_LATTICE_FROM = (0.25, 1.0)
"""Distances (lattice standard deviations) between the two lattices' centres over which the gain moves from the
lattice around the tracked point to the beam's (:func:`beam_share`)."""
LARGEST_PATCH = 0.8
"""Prior width (m) of the patch: a floor on its precision, where the blur would spread it further."""
EIGH_CHUNK = 2**14
"""Links per call of the batched symmetric eigensolver in :func:`lattice_shape`: cuSOLVER's batched solver
(``cusolverDnXsyevBatched``) stops with an internal error somewhere above about 32,000 matrices (seen at 65,536
2 × 2 matrices on an H200, CUDA 13); each matrix is solved on its own, so the pieces give what one call would."""


class LatticeShape(NamedTuple):
    """A two-scale lattice's per-episode shape (:func:`lattice_shape`): its ``basis`` ``[B, 2, 2]``, the
    unresolved slopes' ``blur`` ``[B, 3]`` and the ``pull`` ``[B, 2, 2]`` toward where the beam aims."""

    basis: torch.Tensor
    blur: torch.Tensor
    pull: torch.Tensor


@dataclass(frozen=True)
class TwoScale(ChannelModel):
    """Every point of the resolved surface, blurred by the unresolved slopes and the aperture (eq. 4.8), on
    a ``nodes`` × ``nodes`` lattice of half-width ``span`` standard deviations around the tracked point
    (the calm-sea point where that is lost), and, where :meth:`light` is given the transmitter's pointing,
    a second one where the beam meets the patch: the full channel on a sea with unresolved slopes.

    Attributes: nodes, odd in [3, 31]; span in [1, 8].
    """

    nodes: int = LATTICE_NODES
    span: float = LATTICE_SPAN

    needs_exact_point = False
    Prepared = LatticeShape

    def __post_init__(self) -> None:
        self.check_settings(nodes=self.nodes, span=self.span)

    @staticmethod
    def check_settings(**settings) -> None:
        """Validate the settings given (``nodes``, ``span``), e.g. for a configuration that names another model."""
        if "nodes" in settings:
            nodes = check_int("nodes", settings["nodes"], 3, 31)
            if nodes % 2 == 0:
                raise ValueError(f"nodes = {nodes} is not allowed; it must be odd (a node on the centre)")
        if "span" in settings:
            check_range("span", settings["span"], 1.0, 8.0)

    def reference_gain(self, tx: torch.Tensor, rx: torch.Tensor) -> torch.Tensor:
        return calm_sea_reference(tx, rx, self.optics)

    def prepare(self, tx: torch.Tensor, rx: torch.Tensor, unresolved: torch.Tensor) -> LatticeShape:
        """The lattice's shape (:func:`lattice_shape`, in float64), in ``tx``'s dtype."""
        basis, blur, pull = lattice_shape(tx.double(), rx.double(), unresolved.double(), self.optics)
        return LatticeShape(basis.to(tx.dtype), blur.to(tx.dtype), pull.to(tx.dtype))

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
        followed = near_calm_point(path, ends.calm_point).unsqueeze(-1)
        centre = torch.where(followed, path.point[:, :2], ends.calm_point[:, :2])
        constants = cast(LatticeShape, prepared)  # what prepare gave
        basis, blur = constants.basis, constants.blur

        def lattice(at: torch.Tensor) -> LightSamples:
            grid = Lattice(at, basis, self.nodes, self.span)
            return two_scale_light(sea, ends.tx, ends.rx, time, grid, blur, self.optics)

        if copies == 1:
            everywhere = lattice(centre)
        else:  # the lattice around the tracked point does not depend on the pointing: once per link
            links = centre.shape[0] // copies
            sea_once = Harmonics(*(v[:links] for v in sea))
            tx, rx, now, at, basis_once, spread = (v[:links] for v in (ends.tx, ends.rx, time, centre, basis, blur))
            grid = Lattice(at, basis_once, self.nodes, self.span)
            everywhere = repeated(two_scale_light(sea_once, tx, rx, now, grid, spread, self.optics), copies)
        if ends.pointing is None:
            return everywhere
        shift = (constants.pull @ (beam_aim(ends.tx, ends.pointing) - centre).unsqueeze(-1))[..., 0]
        on_beam = lattice(centre + shift)
        # solve_ex: linalg.solve's error check is an op with effects, which keeps the compiled step out of the
        # inductor cache (a full recompile per process); basis is a lattice's, never singular
        apart = torch.linalg.solve_ex(basis, shift).result
        share = beam_share(torch.linalg.vector_norm(apart, dim=-1)).unsqueeze(-1)
        return joined(everywhere, _scaled(everywhere, 1.0 - share), _scaled(on_beam, share))

    def unpointed_light(self, light: LightSamples) -> LightSamples:
        """The lattice around the tracked point (the bound's), without the blend placed for the pointing."""
        nodes = self.nodes**2
        return light if light.shape[1] == nodes else sliced(light, samples=slice(nodes))

    def receive(self, light: LightSamples, tx_dir: torch.Tensor, rx_dir: torch.Tensor, copies: int = 1) -> Reception:
        """With the pointing given to :meth:`light`: the bound from the lattice around the tracked point
        (independent of the pointing; searched once per link of ``copies``), the gain and the detector's
        reading from its blend with the beam's."""
        nodes = self.nodes**2
        if light.shape[1] == nodes:
            return receive(light, tx_dir, rx_dir, self.optics, copies=copies)
        beam, bound = sliced(light, samples=slice(nodes, None)), self.unpointed_light(light)
        return receive(beam, tx_dir, rx_dir, self.optics, bound_light=bound, copies=copies)


def _scaled(light: LightSamples, factor: torch.Tensor) -> LightSamples:
    return LightSamples(weight=light.weight * factor, departure=light.departure, arrival=light.arrival, cell=light.cell)


def beam_share(apart: torch.Tensor) -> torch.Tensor:
    """The beam's lattice's share of the gain ``[B]`` for lattice centres ``apart`` (in the lattice's standard
    deviations): 0 within :data:`BEAM_LATTICE_FROM`'s first value, where the lattice around the tracked point
    covers the beam's light and the gain is read from the same samples as the bound, 1 beyond its second,
    a smoothstep between (both lattices hold there)."""
    near, far = BEAM_LATTICE_FROM
    x = ((apart - near) / (far - near)).clamp(0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def beam_aim(tx: torch.Tensor, pointing: torch.Tensor) -> torch.Tensor:
    """Where the transmitter's beam axis meets the mean sea surface, (x, y) ``[B, 2]`` (m), for T ``[B, 3]``
    (below it) and a pointing ``[B, 3]`` (unit, up)."""
    return tx[:, :2] - pointing[:, :2] * (tx[:, 2] / pointing[:, 2]).unsqueeze(-1)


def symmetric_eigen(matrices: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """``torch.linalg.eigh`` of ``[B, n, n]`` symmetric matrices, :data:`EIGH_CHUNK` at a time, the vectors laid
    out as one call lays them (each matrix column by column: the products that use them round by their layout)."""
    pieces = [torch.linalg.eigh(piece) for piece in matrices.split(EIGH_CHUNK)]
    return torch.cat([values for values, _ in pieces]), torch.cat([vectors.mT for _, vectors in pieces]).mT


def lattice_shape(tx: torch.Tensor, rx: torch.Tensor, slope_covariance: torch.Tensor, optics: Transceiver):
    """Per-link lattice basis U ``[B, 2, 2]`` (m), the blur covariance ``[B, 3]`` (σ_xx, σ_xy, σ_yy) and the
    pull ``[B, 2, 2]`` that moves the lattice toward where the beam is aimed.

    From the calm-sea geometry of each link (``tx``, ``rx`` ``[B, 3]``, m) and its unresolved slope
    covariance ``[B, 3]``: the blur adds the aperture's spread (D/4 per axis of receiver
    displacement, through |∂ζ/∂R|); the patch is the Gaussian p_Σ(A s) with A = H_flat / w_z the
    calm sea's map from surface steps to needed slopes; the beam footprint is r1 ω'/2 per axis
    (stretched by 1/cos θ1 along the incidence plane). U's columns are the principal axes of
    their product, scaled by its standard deviations. A beam aimed at a surface point a instead of the
    patch's centre c moves the product's mean to c + K (a − c), K = (P + C⁻¹)⁻¹ C⁻¹ the pull (P the
    patch's precision, C the footprint's covariance), and leaves its covariance as it is.
    """
    point = flat_sea_point(tx, rx, optics.n_water, optics.n_air)
    d1, d2 = point - tx, rx - point
    r1, r2 = torch.linalg.vector_norm(d1, dim=-1), torch.linalg.vector_norm(d2, dim=-1)
    u1, u2 = d1 / r1.unsqueeze(-1), d2 / r2.unsqueeze(-1)
    w = facet_normal(u1, u2, optics)
    w_z = w[:, 2]
    eye = torch.eye(2, dtype=tx.dtype, device=tx.device)
    # calm-sea Hessian of L: Σ_i (n_i / r_i)(I − u_i u_iᵀ) over the horizontal axes
    hessian = (optics.n_water / r1)[:, None, None] * (eye - u1[:, :2, None] * u1[:, None, :2]) + (optics.n_air / r2)[
        :, None, None
    ] * (eye - u2[:, :2, None] * u2[:, None, :2])
    slope_map = hessian / w_z[:, None, None]
    aperture = aperture_slope_variance(w, u2, r2, optics)
    blur = slope_covariance + torch.stack((aperture, torch.zeros_like(aperture), aperture), dim=-1)
    precision = slope_map.transpose(-1, -2) @ torch.linalg.inv(_matrix(blur)) @ slope_map + eye / LARGEST_PATCH**2
    horizontal = d1[:, :2] / torch.linalg.vector_norm(d1[:, :2], dim=-1, keepdim=True).clamp(min=1e-12)
    horizontal = torch.where(torch.isfinite(horizontal), horizontal, torch.zeros_like(horizontal))
    cos1 = u1[:, 2]
    footprint = (r1 * beam_divergence(optics.divergence, optics.wavelength) / 2.0) ** 2
    along = horizontal.unsqueeze(-1) * horizontal.unsqueeze(-2)
    covariance = footprint[:, None, None] * (eye + (1.0 / cos1**2 - 1.0)[:, None, None] * along)
    spread = torch.linalg.inv(covariance)
    product = torch.linalg.inv(precision + spread)
    values, vectors = symmetric_eigen(product)
    return vectors * torch.sqrt(values).unsqueeze(-2), blur, product @ spread


class Lattice(NamedTuple):
    """The nodes ``centre + basis · z`` of eq. (4.8)'s trapezoid rule: ``centre`` (x, y) ``[B, 2]`` (m), ``basis``
    ``[B, 2, 2]`` (m, from :func:`lattice_shape`), and z on ``nodes`` × ``nodes`` points of half-width ``span``
    (odd nodes put one on the centre)."""

    centre: torch.Tensor
    basis: torch.Tensor
    nodes: int = LATTICE_NODES
    span: float = LATTICE_SPAN


def two_scale_light(
    sea: Harmonics,
    tx: torch.Tensor,
    rx: torch.Tensor,
    time: torch.Tensor,
    lattice: Lattice,
    blur: torch.Tensor,
    optics: Transceiver,
) -> LightSamples:
    """Eq. (4.8) on the ``lattice`` as weighted rays (:class:`LightSamples`, N = nodes²).

    Args:
        sea: the resolved surfaces, each component ``[B, K]``.
        tx, rx: T and R (m) ``[B, 3]``; time (s) ``[B]``.
        lattice: the nodes, centred on the tracked refraction point.
        blur: from :func:`lattice_shape`.
        optics: the transceiver.

    A pure tensor function (no data-dependent Python), so that it compiles into the step's graph.
    """
    dtype = tx.dtype
    centre, basis, nodes, span = lattice
    grid = torch.linspace(-span, span, nodes, dtype=dtype, device=tx.device)
    xy = lattice_nodes(centre, basis, grid)
    height, slope_x, slope_y = lattice_harmonic_sums(sea, centre, basis, grid, time, 1)
    point = torch.cat((xy, height.unsqueeze(-1)), dim=-1)
    d1, d2 = point - tx.unsqueeze(1), rx.unsqueeze(1) - point
    r1, r2 = torch.linalg.vector_norm(d1, dim=-1), torch.linalg.vector_norm(d2, dim=-1)
    u1, u2 = d1 / r1.unsqueeze(-1), d2 / r2.unsqueeze(-1)
    w = facet_normal(u1, u2, optics)
    w_z = w[..., 2].clamp(min=1e-6)
    needed = torch.stack((-w[..., 0] / w_z - slope_x, -w[..., 1] / w_z - slope_y), dim=-1)
    density = slope_density(needed, blur.unsqueeze(1))
    facet = w / torch.linalg.vector_norm(w, dim=-1, keepdim=True)
    theta1 = torch.acos((u1 * facet).sum(-1).clamp(-1.0, 1.0))
    transmitted = water_transmittance(theta1, r1, optics.n_water, optics.n_air, optics.attenuation_per_m)
    # the facet's interception per unit horizontal area, |u1·(−ζ, 1)| = |u1·w| / w_z for the needed slope ζ
    # (docs/model.md §4.3): a facet tilted toward the ray catches more of it than the mean surface would
    intercepted = interception(u1, needed + torch.stack((slope_x, slope_y), dim=-1)).abs()
    to_receiver = optics.n_air**2 / r2**2 * (w * u2).sum(-1).abs() / w_z**3
    area = (2.0 * span / (nodes - 1)) ** 2 * torch.linalg.det(basis).abs().unsqueeze(-1)
    upward = (w[..., 2] > 1e-6) & (u2[..., 2] > 0)
    weight = area * transmitted * intercepted / r1**2 * density * to_receiver
    weight = torch.where(upward & torch.isfinite(weight), weight, torch.zeros_like(weight))
    cell = across_cells(u2, nodes)
    return LightSamples(weight=weight, departure=u1, arrival=u2, cell=cell)


def across_cells(values: torch.Tensor, nodes: int) -> torch.Tensor:
    """The change of ``values`` ``[B, nodes², 3]`` (a lattice's nodes, row-major) across each node's cell along
    the lattice's two axes, ``[B, nodes², 2, 3]``: central differences between neighbours, one-sided at the
    lattice's edge."""
    grid = values.unflatten(1, (nodes, nodes))

    def along(axis: int) -> torch.Tensor:
        first, second = grid.narrow(axis, 1, 1) - grid.narrow(axis, 0, 1), grid.narrow(axis, 2, nodes - 2)
        inner = (second - grid.narrow(axis, 0, nodes - 2)) / 2
        last = grid.narrow(axis, nodes - 1, 1) - grid.narrow(axis, nodes - 2, 1)
        return torch.cat((first, inner, last), dim=axis)

    return torch.stack((along(1), along(2)), dim=-2).flatten(1, 2)


def _matrix(covariance: torch.Tensor) -> torch.Tensor:
    """(σ_xx, σ_xy, σ_yy) ``[..., 3]`` as a symmetric ``[..., 2, 2]``."""
    xx, xy, yy = covariance.unbind(-1)
    return torch.stack((torch.stack((xx, xy), -1), torch.stack((xy, yy), -1)), -2)
