"""The local estimate (docs/model.md §4.6): its facet density against normalisation and finite differences,
the closed form of a calm sea as the facets vanish, and the counting tracer where counting is precise."""

import math

import pytest
import torch
from conftest import F64, calm, ends

from waterair.physics.channel import LinkEnds, MonteCarlo, Transceiver, flat_sea_irradiance, standard_error
from waterair.physics.channel.local_estimate import (
    LocalEstimate,
    arrival_jacobian,
    facet_density,
    facet_share,
    local_estimate,
)
from waterair.physics.channel.montecarlo import RayRequest
from waterair.physics.channel.rays import FEWEST_ITERATIONS, departures, surface_hits
from waterair.physics.optics import N_AIR, N_WATER, refract, transverse_frame, unit_vector
from waterair.physics.paths import flat_sea_point
from waterair.physics.sea import sea_state
from waterair.physics.surface import WaveSurface, harmonic_sums

INCOMING = unit_vector(torch.tensor([0.08, -0.05, 1.0], dtype=F64))
MEAN_SLOPE = torch.tensor([0.05, -0.02], dtype=F64)
COVARIANCE = torch.tensor([0.010, 0.002, 0.006], dtype=F64)  # σ ≈ 0.1 and 0.08, correlated


def refracted(slope: torch.Tensor) -> torch.Tensor:
    """u₂ of INCOMING through facets of ``slope`` ``[..., 2]``, by vector Snell (independent of the density)."""
    normal = unit_vector(torch.cat((-slope, torch.ones_like(slope[..., :1])), -1))
    out, transmitted = refract(INCOMING.expand_as(normal), -normal, N_WATER, N_AIR)
    assert transmitted.all()
    return out


def test_the_facet_density_integrated_over_every_arrival_direction_is_one():
    # u₂ on a tangent-plane grid (exponential map) around the specular direction, ±0.5 rad: ≥ 10 σ of the
    # arrival spread; the trapezoid in float64 over 1201² points
    centre = refracted(MEAN_SLOPE)
    e1, e2 = transverse_frame(centre[None])
    axis = torch.linspace(-0.5, 0.5, 1201, dtype=F64)
    a, b = torch.meshgrid(axis, axis, indexing="ij")
    angle = torch.sqrt(a**2 + b**2).clamp(min=1e-300)
    direction = torch.cos(angle)[..., None] * centre + torch.sin(angle)[..., None] * (
        (a / angle)[..., None] * e1[0] + (b / angle)[..., None] * e2[0]
    )
    density, normal = facet_density(INCOMING, direction, MEAN_SLOPE, COVARIANCE, N_WATER, N_AIR)
    solid_angle = torch.sin(angle) / angle  # dΩ = sin|t|/|t| dt²
    step = float(axis[1] - axis[0])
    total = torch.trapezoid(torch.trapezoid(density * solid_angle, dx=step), dx=step)
    assert abs(float(total) - 1.0) < 1e-3
    # weighted by each facet's share of the ray (its interception against the mean surface's): still 1, as
    # the share is linear in the slope and the slopes are centred on ζ̄; and not 1 without that centring
    share = facet_share(INCOMING, normal, MEAN_SLOPE)
    intercepted = torch.trapezoid(torch.trapezoid(density * share * solid_angle, dx=step), dx=step)
    assert abs(float(intercepted) - 1.0) < 1e-3
    assert share.min() < 0.95 and share.max() > 1.05  # the facets the ray meets differ from the slopes' statistics
    off_centre = facet_share(INCOMING, normal, torch.zeros(2, dtype=F64))
    wrong = torch.trapezoid(torch.trapezoid(density * off_centre * solid_angle, dx=step), dx=step)
    assert abs(float(wrong) - 1.0) > 2e-3


@pytest.mark.parametrize("slope", [(0.0, 0.0), (0.12, -0.07), (-0.3, 0.25)])
def test_the_jacobian_is_the_finite_difference_of_the_refraction_map(slope):
    # |∂ζ/∂Ω₂| = 1 / |det ∂Ω₂/∂ζ|: the solid angle swept by u₂ as the slope moves, by central differences
    zeta = torch.tensor(slope, dtype=F64)
    out = refracted(zeta)
    e1, e2 = transverse_frame(out[None])
    step = 1e-6
    columns = []
    for k in range(2):
        shift = torch.zeros(2, dtype=F64)
        shift[k] = step
        change = (refracted(zeta + shift) - refracted(zeta - shift)) / (2 * step)
        columns.append(torch.stack(((change * e1[0]).sum(), (change * e2[0]).sum())))
    swept = abs(float(torch.linalg.det(torch.stack(columns, -1))))
    jacobian, normal, valid = arrival_jacobian(INCOMING, out, N_WATER, N_AIR)
    assert bool(valid)
    assert float(jacobian) * swept == pytest.approx(1.0, rel=1e-7)
    assert torch.allclose(-normal[:2] / normal[2], zeta, atol=1e-12)  # the facet found is the facet used


def test_no_facet_sends_the_ray_back_down_or_past_the_critical_angle():
    down = unit_vector(torch.tensor([0.0, 0.3, -1.0], dtype=F64))
    grazing = unit_vector(torch.tensor([1.0, 0.0, 0.02], dtype=F64))  # needs a facet beyond the critical angle
    straight_up = torch.tensor([0.0, 0.0, 1.0], dtype=F64)
    for outgoing in (down, grazing):
        density, _ = facet_density(straight_up, outgoing, torch.zeros(2, dtype=F64), COVARIANCE, N_WATER, N_AIR)
        assert float(density) == 0.0


@pytest.mark.parametrize(("depth", "height"), [(10.0, 10.0), (20.0, 5.0)])
def test_on_a_calm_sea_with_vanishing_facets_it_is_the_closed_form(depth, height):
    """A flat surface with facets of σ = 0.01, normal incidence: the isotropic source's irradiance at R is
    eq. (4.5) within 0.1 %. A 5 mm aperture: across a 5 cm one the departures that reach each point move by
    about the facets' own spread, and the estimate's variance with them."""
    optics = Transceiver(aperture_diameter=0.005)
    surface = calm(WaveSurface.sample(sea_state("elfouhaily", wind=8.0, n_wavenumbers=2, n_dir=1), 1, seed=0))
    tx, rx = ends(0.0, 1, depth=depth, height=height)
    point = flat_sea_point(tx, rx, optics.n_water, optics.n_air)
    sigma = 0.01
    # the departures that a facet within σ sends to R: σ (n_w − n_a) / (n_a d_w / d_a + n_w), the least variance
    spread = sigma * (N_WATER - N_AIR) / (N_AIR * depth / height + N_WATER)
    result = local_estimate(
        surface.to(F64).harmonics,
        torch.tensor([[sigma**2, 0.0, sigma**2]], dtype=F64),
        tx,
        rx,
        0.0,
        optics,
        RayRequest(
            axis=unit_vector(point - tx),
            reference=unit_vector(rx - point),
            width=spread,
            rays=500_000,
            per_ray=1,
            generator=torch.Generator().manual_seed(1),
        ),
    )
    irradiance = result.light.weight.sum(1)
    per_ray = result.light.weight * result.rays[:, None]
    error = per_ray.std(1) / math.sqrt(int(result.rays[0]))
    closed = flat_sea_irradiance(tx, rx, optics)
    assert (error / closed).max() < 3e-4
    assert ((irradiance / closed - 1).abs() < 1e-3).all(), irradiance / closed


def test_the_counting_tracer_agrees_on_a_large_aperture():
    """Both estimators on 12 m/s ocean seas with a 0.5 m aperture, where counting is precise: within 2 SE."""
    optics = Transceiver(aperture_diameter=0.5)
    sea = sea_state("elfouhaily", wind=12.0, n_wavenumbers=8, n_dir=4)
    surface = WaveSurface.sample(sea, 2, seed=5, dtype=F64)
    tx, rx = ends(0.2, 2)
    point = flat_sea_point(tx, rx, optics.n_water, optics.n_air)
    link = LinkEnds(tx, rx, point)
    pointing = unit_vector(point - tx), -unit_vector(rx - point)
    counting = MonteCarlo(optics, rays=40_000, facets=64, proposal_beams=0.5)
    local = LocalEstimate(optics, rays=40_000, points=1)
    generator = torch.Generator().manual_seed(2)
    counted, counted_error = standard_error(
        counting.estimate(surface.harmonics, surface.unresolved, link, 0.0, generator), *pointing, optics
    )
    estimated, estimated_error = standard_error(
        local.estimate(surface.harmonics, surface.unresolved, link, 0.0, generator), *pointing, optics
    )
    combined = torch.sqrt(counted_error**2 + estimated_error**2)
    assert (combined / estimated).max() < 0.01
    assert ((counted - estimated).abs() < 2 * combined).all(), (counted / estimated, combined / estimated)
    assert (estimated_error < counted_error).all()  # and it is the more precise of the two at the same rays


def test_four_newton_steps_put_every_ray_on_a_rough_surface():
    """The local estimate's intersection (FEWEST_ITERATIONS) on a 20 m/s ocean sea, rays ±0.1 rad off the calm
    departure at a 50 % offset: the ray's height is the surface's to 1e-10 m."""
    sea = sea_state("elfouhaily", wind=20.0, n_wavenumbers=24, n_dir=8)
    surface = WaveSurface.sample(sea, 4, seed=3, dtype=F64)
    tx, rx = ends(0.5, 4)
    axis = unit_vector(flat_sea_point(tx, rx, N_WATER, N_AIR) - tx)
    e1, e2 = transverse_frame(axis)
    tangent = 0.1 * torch.randn(4, 2000, 2, dtype=F64, generator=torch.Generator().manual_seed(0))
    direction, _ = departures(axis, e1, e2, tangent, 0.1)
    point, _, distance = surface_hits(surface.harmonics, tx, direction, 10.0, FEWEST_ITERATIONS)
    time = torch.full((4,), 10.0, dtype=F64)
    height = harmonic_sums(surface.harmonics, point[..., 0], point[..., 1], time, 0)[0]
    assert (point[..., 2] - height).abs().max() < 1e-10
    assert torch.allclose(point, tx[:, None] + distance[..., None] * direction, atol=1e-12)
