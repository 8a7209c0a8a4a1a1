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
    fresnel_transmittance,
    path_gain,
    peak_arrival_gain,
    refract,
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


@pytest.mark.parametrize("widths", [(0.03, 0.01), (0.02, 0.02), (0.0, 0.05), (0.04, 0.0)])
def test_the_field_of_view_averaged_over_a_cell_is_the_share_of_the_cell_within_it(widths):
    """G_A over a cell across which α_A changes by (a, b): against a float64 integral over the cell written here
    (the inner uniform's share in closed form, the outer by the midpoint rule on 20,000 points), at margins
    across the edge; outside the cell's reach it is a ray's G_A."""
    a, b = widths
    alpha = torch.linspace(0.10, 0.24, 57, dtype=torch.float64)
    got = arrival_gain_over_cell(alpha, torch.tensor([a, b], dtype=torch.float64).expand(57, 2), 0.17, 1.2)
    s = (torch.arange(20_000, dtype=torch.float64) + 0.5) / 20_000 - 0.5
    left = 0.17 - alpha.unsqueeze(-1) - a * s  # what q t must stay below, for each s
    inner = (left / b + 0.5).clamp(0.0, 1.0) if b > 0 else (left >= 0).double()
    share = inner.mean(-1)
    expected = peak_arrival_gain(0.17, 1.2) * torch.cos(alpha) * share
    torch.testing.assert_close(got, expected, rtol=0, atol=1e-4 * peak_arrival_gain(0.17, 1.2))
    far = (alpha - 0.17).abs() > (a + b) / 2 + 1e-12
    assert torch.equal(got[far], arrival_gain(alpha, 0.17, 1.2)[far])
    assert torch.equal(
        arrival_gain_over_cell(alpha, torch.zeros(57, 2, dtype=torch.float64), 0.17), arrival_gain(alpha, 0.17)
    )
