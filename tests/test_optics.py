"""Snell refraction, Fresnel transmittance and the gain terms (docs/model.md §4)."""

import math

import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st

from waterair.physics.channel import Transceiver
from waterair.physics.optics import (
    WATER_ATTENUATION_PER_M,
    angle_between,
    arrival_gain,
    arrival_gain_over_cell,
    beam_divergence,
    critical_angle,
    departure_gain,
    departure_gain_at,
    fresnel_transmittance,
    path_gain,
    peak_arrival_gain,
    refract,
    sin_cos_between,
    sin_cos_of_components,
)


def fresnel_reference(theta_i: float, n1: float = 1.33, n2: float = 1.0) -> float:
    """s and p reflectances from the textbook formulas with θt from Snell, float64 math."""
    sin_t = n1 / n2 * math.sin(theta_i)
    if sin_t >= 1.0:
        return 0.0
    theta_t = math.asin(sin_t)
    ci, ct = math.cos(theta_i), math.cos(theta_t)
    rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct)
    rp = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct)
    return 1.0 - 0.5 * (rs * rs + rp * rp)


def test_critical_angle_is_48_75_degrees():
    assert math.degrees(critical_angle(1.33, 1.0)) == pytest.approx(48.75, abs=0.01)


def test_fresnel_normal_incidence():
    assert fresnel_transmittance(torch.tensor(0.0, dtype=torch.float64)).item() == pytest.approx(0.9799, abs=1e-4)
    assert fresnel_transmittance(torch.tensor(0.0, dtype=torch.float64)).item() == pytest.approx(
        1 - (0.33 / 2.33) ** 2, rel=1e-12
    )


def test_fresnel_is_zero_beyond_the_critical_angle():
    theta = torch.tensor([math.radians(48.76), math.radians(60.0), math.radians(89.0)], dtype=torch.float64)
    assert torch.all(fresnel_transmittance(theta) == 0)
    assert fresnel_transmittance(torch.tensor(math.radians(48.7), dtype=torch.float64)) > 0


def test_fresnel_matches_s_p_reference_at_random_angles():
    generator = torch.Generator().manual_seed(0)
    theta = torch.rand(50, generator=generator, dtype=torch.float64) * math.radians(60.0)
    got = fresnel_transmittance(theta)
    want = torch.tensor([fresnel_reference(v) for v in theta.tolist()], dtype=torch.float64)
    torch.testing.assert_close(got, want, rtol=1e-12, atol=1e-12)


@given(st.floats(0.0, 1.5), st.floats(0.0, 2 * math.pi))
def test_refraction_obeys_snell(theta, azimuth):
    """Air → water and water → air: n1 sin θi = n2 sin θt, transmitted ray on the far side."""
    normal = torch.tensor([0.1, -0.2, 1.0], dtype=torch.float64)
    normal = normal / normal.norm()
    tangent = torch.linalg.cross(normal, torch.tensor([math.cos(azimuth), math.sin(azimuth), 0.0], dtype=torch.float64))
    tangent = tangent / tangent.norm()
    for n1, n2, side in ((1.0, 1.33, -1.0), (1.33, 1.0, 1.0)):
        # incident ray travels along -side·normal tilted by θ; the normal on its side is side·normal
        incident = -side * math.cos(theta) * normal + math.sin(theta) * tangent
        out, ok = refract(incident, side * normal, n1, n2)
        sin_i = math.sin(theta)
        if n1 * sin_i / n2 >= 1.0:
            assert not ok
            continue
        assert ok
        assert out.norm().item() == pytest.approx(1.0, abs=1e-12)
        sin_t = torch.linalg.cross(out, normal).norm().item()
        assert n1 * sin_i == pytest.approx(n2 * sin_t, abs=1e-12)
        assert (out @ normal).item() * side < 0


def test_departure_gain_is_one_on_axis_and_decreases():
    angles = torch.linspace(0, 0.3, 31, dtype=torch.float64)
    g = departure_gain(angles, 0.05, 520e-9)
    assert g[0].item() == 1.0
    assert torch.all(g[1:] < g[:-1])
    # Off axis by one divergence the Gaussian beam has dropped to ≈ e^-2 (λ/πω² ≪ 1 here).
    assert departure_gain(torch.tensor(math.asin(0.05), dtype=torch.float64), 0.05, 520e-9).item() == pytest.approx(
        math.exp(-2.0), rel=1e-6
    )


@pytest.mark.parametrize("divergence", [0.0005, 0.005, 0.05])
def test_the_beam_divergence_as_a_tensor_gives_what_the_float_gives(divergence):
    """A compiled step takes ω_D as a 0-dim tensor (Transceiver.traced): the beam's width and gain are
    the float's, against the closed form ω_D' = ω_D sqrt(1 + (λ/(π ω_D²))²) (λ/(π ω_D²) = 0.66 at 0.5 mrad)."""
    optics = Transceiver(divergence=divergence)
    traced = optics.traced("cpu")
    assert isinstance(traced.divergence, torch.Tensor) and traced.divergence.dim() == 0
    assert traced.divergence.item() == divergence and traced.divergence.dtype == torch.float64
    assert (traced.wavelength, traced.half_fov, traced.water) == (optics.wavelength, optics.half_fov, optics.water)
    closed = divergence * math.sqrt(1.0 + (520e-9 / (math.pi * divergence**2)) ** 2)
    assert beam_divergence(divergence, 520e-9) == pytest.approx(closed, rel=1e-15)
    assert beam_divergence(traced.divergence, 520e-9).item() == pytest.approx(closed, rel=1e-15)
    angles = torch.linspace(0.0, 3 * closed, 13, dtype=torch.float64)
    as_tensor, as_float = departure_gain(angles, traced.divergence, 520e-9), departure_gain(angles, divergence, 520e-9)
    torch.testing.assert_close(as_tensor, as_float, rtol=1e-15, atol=0)
    with pytest.raises(ValueError, match="divergence"):
        Transceiver(divergence=torch.tensor(2.0))  # the checks read a tensor as its value


def test_a_divergence_per_link_gives_each_link_what_its_float_gives():
    """One ω_D per link ``[B]`` (Transceiver.for_links) against each link's as a float, for angles ``[B]`` and
    ``[B, N]``: bit for bit in float64, and in float32 too (what is derived from ω_D is taken in float64, as from a
    float, before it meets the angles)."""
    divergences = torch.tensor([0.0005, 0.005, 0.05, 0.1], dtype=torch.float64)
    per_link = Transceiver().for_links(divergences)
    assert per_link.rows(slice(1, 3)).divergence.tolist() == [0.005, 0.05]
    for dtype in (torch.float64, torch.float32):
        angles = torch.rand(4, 7, generator=torch.Generator().manual_seed(1), dtype=torch.float64).to(dtype) * 0.1
        together = departure_gain(angles, per_link.divergence, 520e-9)
        one_dim = departure_gain(angles[:, 0], per_link.divergence, 520e-9)
        assert together.dtype == dtype == one_dim.dtype
        for row, value in enumerate(divergences.tolist()):
            assert torch.equal(together[row], departure_gain(angles[row], value, 520e-9))
            assert torch.equal(one_dim[row], departure_gain(angles[row, :1], value, 520e-9)[0])


def test_arrival_gain_inside_and_outside_the_fov():
    half_fov = 0.17
    angles = torch.tensor([0.0, 0.1, 0.17], dtype=torch.float64)
    inside = arrival_gain(angles, half_fov, 1.0)
    torch.testing.assert_close(inside, torch.cos(angles) / math.sin(0.17) ** 2)
    outside = arrival_gain(torch.tensor([0.1701, 0.5, 3.0], dtype=torch.float64), half_fov, 1.0)
    assert torch.all(outside == 0)


def test_path_gain_attenuates_with_water_distance():
    d_air = torch.tensor(10.0, dtype=torch.float64)
    for c in WATER_ATTENUATION_PER_M.values():
        g = path_gain(torch.tensor([5.0, 10.0], dtype=torch.float64), d_air, c)
        assert g[1] < g[0]
        assert g[0].item() == pytest.approx(math.exp(-5.0 * c) / 15.0**2, rel=1e-12)


def test_angle_between_is_accurate_for_tiny_angles():
    u = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64)
    v = torch.tensor([math.sin(1e-9), 0.0, math.cos(1e-9)], dtype=torch.float64)
    assert angle_between(u, v).item() == pytest.approx(1e-9, rel=1e-6)


def unit_pairs(angles: torch.Tensor, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    """Random unit vectors u and, for each, a unit v at exactly ``angles`` from it (rad, float64): u rotated by the
    angle about a random axis across it."""
    g = torch.Generator().manual_seed(seed)
    u = torch.nn.functional.normalize(torch.randn(angles.shape[0], 3, generator=g, dtype=torch.float64), dim=-1)
    across = torch.linalg.cross(u, torch.randn(angles.shape[0], 3, generator=g, dtype=torch.float64), dim=-1)
    across = torch.nn.functional.normalize(across, dim=-1)
    return u, torch.cos(angles)[:, None] * u + torch.sin(angles)[:, None] * across


def test_the_sine_and_cosine_between_unit_vectors_are_the_angles():
    """|u×v| and u·v of unit vectors built at known angles, from 1e-9 rad to π − 1e-9, are the angle's sine and
    cosine, of ``[n, 3]`` vectors and of vectors by component; the angle's atan2 of them is angle_between's, bit
    for bit."""
    angles = torch.cat(
        (torch.tensor([1e-9, 1e-6]), torch.linspace(0.01, math.pi - 0.01, 200), torch.tensor([math.pi - 1e-6]))
    )
    u, v = unit_pairs(angles.double())
    sin, cos = sin_cos_between(u, v)
    torch.testing.assert_close(sin, torch.sin(angles.double()), rtol=1e-9, atol=1e-15)
    torch.testing.assert_close(cos, torch.cos(angles.double()), rtol=0, atol=1e-15)
    assert torch.equal(torch.atan2(sin, cos), angle_between(u, v))
    sin, cos = sin_cos_of_components(u.unbind(-1), v.unbind(-1))
    torch.testing.assert_close(sin, torch.sin(angles.double()), rtol=1e-9, atol=1e-15)
    torch.testing.assert_close(cos, torch.cos(angles.double()), rtol=0, atol=1e-15)


@pytest.mark.parametrize("divergence", [0.0005, 0.05])
def test_the_gains_from_sine_and_cosine_are_the_papers_gains_of_the_angle(divergence):
    """G_D and G_A of (sin α, cos α), what the full channel's ascent evaluates, against eqs. (2) and (5) of α written
    here in float64 math, at angles across the beam, the field of view's edge and beyond a right angle."""
    angles = torch.cat((torch.linspace(0.0, 3 * divergence, 60), torch.linspace(0.0, 2.0, 401))).double()
    u, v = unit_pairs(angles, seed=1)
    sin, cos = sin_cos_between(u, v)
    wavelength, half_fov, n_c = 520e-9, math.radians(30), 1.5
    spread = [1 + (wavelength * math.cos(a) / (math.pi * divergence**2)) ** 2 for a in angles.tolist()]
    beam = [math.exp(-2 * math.sin(a) ** 2 / (divergence**2 * s)) for a, s in zip(angles.tolist(), spread, strict=True)]
    field = [n_c**2 / math.sin(half_fov) ** 2 * math.cos(a) if a <= half_fov else 0.0 for a in angles.tolist()]
    torch.testing.assert_close(departure_gain_at(sin, cos, divergence, wavelength), torch.tensor(beam).double())
    alpha = torch.atan2(sin, cos)
    torch.testing.assert_close(arrival_gain(alpha, half_fov, n_c, cos), torch.tensor(field).double())
    steps = (torch.full_like(alpha, 0.01), torch.full_like(alpha, -0.01))
    torch.testing.assert_close(
        arrival_gain_over_cell(alpha, steps, half_fov, n_c, cos), arrival_gain_over_cell(alpha, steps, half_fov, n_c)
    )
    assert sum(value > 0 for value in field) > 100 and sum(value > 1e-3 for value in beam) > 40


@pytest.mark.parametrize("widths", [(0.03, 0.01), (0.02, 0.02), (0.0, 0.05), (0.04, 0.0)])
def test_the_field_of_view_averaged_over_a_cell_is_the_share_of_the_cell_within_it(widths):
    """G_A over a cell across which α_A changes by (a, b): against a float64 integral over the cell written here
    (the inner uniform's share in closed form, the outer by the midpoint rule on 20,000 points), at margins
    across the edge; outside the cell's reach it is a ray's G_A."""
    a, b = widths
    alpha = torch.linspace(0.10, 0.24, 57, dtype=torch.float64)
    got = arrival_gain_over_cell(alpha, (torch.full_like(alpha, a), torch.full_like(alpha, -b)), 0.17, 1.2)
    s = (torch.arange(20_000, dtype=torch.float64) + 0.5) / 20_000 - 0.5
    left = 0.17 - alpha.unsqueeze(-1) - a * s  # what q t must stay below, for each s
    inner = (left / b + 0.5).clamp(0.0, 1.0) if b > 0 else (left >= 0).double()
    share = inner.mean(-1)
    expected = peak_arrival_gain(0.17, 1.2) * torch.cos(alpha) * share
    torch.testing.assert_close(got, expected, rtol=0, atol=1e-4 * peak_arrival_gain(0.17, 1.2))
    far = (alpha - 0.17).abs() > (a + b) / 2 + 1e-12
    assert torch.equal(got[far], arrival_gain(alpha, 0.17, 1.2)[far])
    still = (torch.zeros_like(alpha), torch.zeros_like(alpha))
    assert torch.equal(arrival_gain_over_cell(alpha, still, 0.17), arrival_gain(alpha, 0.17))
