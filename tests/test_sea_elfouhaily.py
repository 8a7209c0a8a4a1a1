"""The measured-slope sea: Elfouhaily spectrum, capillary waves, slopes against Cox-Munk (docs/model.md §1.2-§1.4)."""

import math

import pytest
import torch

from waterair.physics.sea import angular_frequency, cox_munk, elevation_spectrum, phase_speed, sea_state
from waterair.physics.sea.elfouhaily import spreading_ratio
from waterair.physics.surface import WaveSurface

G = 9.81


def elfouhaily_reference(k: float, wind: float, fetch: float) -> tuple[float, float]:
    """S(k) (m³/rad) and Δ(k) written out independently with math, float64 (Elfouhaily et al. 1997)."""
    k_m, c_m = 370.0, 0.23
    omega_c = 0.84 * math.tanh((G * fetch / wind**2 / 2.2e4) ** 0.4) ** -0.75
    k_p = G / wind**2 * omega_c**2

    def c(kk):
        return math.sqrt(G / kk * (1 + (kk / k_m) ** 2))

    c_p = c(k_p)
    big_omega = wind / c_p
    u_star = 0.4 * wind / math.log(10.0 / (3.7e-5 * wind**2 / G * big_omega**0.9))
    gamma = 1.7 if omega_c < 1 else 1.7 + 6 * math.log10(omega_c)
    sigma = 0.08 * (1 + 4 / omega_c**3)
    l_pm = math.exp(-5 / 4 * (k_p / k) ** 2)
    j_p = gamma ** math.exp(-((math.sqrt(k / k_p) - 1) ** 2) / (2 * sigma**2))
    f_p = l_pm * j_p * math.exp(-big_omega / math.sqrt(10) * (math.sqrt(k / k_p) - 1))
    b_l = 0.5 * 6e-3 * big_omega**0.55 * c_p / c(k) * f_p
    if u_star <= c_m:
        alpha_m = 0.01 * (1 + math.log(u_star / c_m))
    else:
        alpha_m = 0.01 * (1 + 3 * math.log(u_star / c_m))
    f_m = l_pm * j_p * math.exp(-0.25 * (k / k_m - 1) ** 2)
    b_h = 0.5 * max(alpha_m, 0.0) * c_m / c(k) * f_m
    delta = math.tanh(math.log(2) / 4 + 4 * (c(k) / c_p) ** 2.5 + 0.13 * u_star / c_m * (c_m / c(k)) ** 2.5)
    return (b_l + b_h) / k**3, delta


@pytest.mark.parametrize("wind,fetch", [(4.0, 2e4), (12.0, 2e4), (20.0, 1e5), (8.0, 1e6)])
def test_spectrum_and_spreading_match_an_independent_implementation(wind, fetch):
    """From below the peak through the gravity-capillary range to the capillaries (0.05-3000 rad/m)."""
    k = torch.logspace(math.log10(0.05), math.log10(3000.0), 41, dtype=torch.float64)
    reference = [elfouhaily_reference(v, wind, fetch) for v in k.tolist()]
    want_s = torch.tensor([r[0] for r in reference], dtype=torch.float64)
    want_delta = torch.tensor([r[1] for r in reference], dtype=torch.float64)
    torch.testing.assert_close(elevation_spectrum(k, wind, fetch), want_s, rtol=1e-12, atol=0.0)
    torch.testing.assert_close(spreading_ratio(k, wind, fetch), want_delta, rtol=1e-12, atol=0.0)


def test_phase_speed_minimum_is_c_m_at_k_m():
    k = torch.logspace(1.0, 4.0, 30_001, dtype=torch.float64)
    c = phase_speed(k)
    assert k[c.argmin()].item() == pytest.approx(370.0, rel=1e-3)
    assert c.min().item() == pytest.approx(math.sqrt(2 * G / 370.0), rel=1e-9)
    assert c.min().item() == pytest.approx(0.23, abs=5e-4)


def test_dispersion_is_deep_water_for_long_waves_and_capillary_for_short():
    long, short = torch.tensor([0.1], dtype=torch.float64), torch.tensor([5000.0], dtype=torch.float64)
    assert angular_frequency(long).item() == pytest.approx(math.sqrt(G * 0.1), rel=1e-6)
    # ω² → g k³ / k_m² = (σ/ρ) k³ with σ/ρ = g / k_m²: capillary waves
    assert angular_frequency(short).item() == pytest.approx(math.sqrt(G * 5000.0**3 / 370.0**2), rel=0.01)


@pytest.mark.parametrize("wind", [4.0, 12.0, 20.0])
def test_sampled_ocean_sea_against_cox_munk(wind):
    """Totals within 10 % of Cox & Munk's clean-surface fit, components within 20 %, and the slopes of
    1024 sampled seas equal the reported resolved part within 5 %."""
    sea = sea_state(wind=wind, spectrum="elfouhaily", n_wavenumbers=48, n_dir=16)
    mss = sea.mean_square_slope()
    measured = cox_munk(wind)
    assert mss.total == pytest.approx(measured.total, rel=0.10)
    assert mss.upwind == pytest.approx(measured.upwind, rel=0.20)
    assert mss.crosswind == pytest.approx(measured.crosswind, rel=0.20)
    assert 0 < mss.resolved < mss.total and mss.unresolved > 0

    surface = WaveSurface.sample(sea, 1024, seed=7, dtype=torch.float64)
    points = torch.rand(1024, 4, generator=torch.Generator().manual_seed(1), dtype=torch.float64) * 50.0
    sample = surface.evaluate(points[:, :2], points[:, 2:], 3.0, order=1)
    assert sample.dx.pow(2).mean().item() == pytest.approx(mss.resolved_upwind, rel=0.05)
    assert sample.dy.pow(2).mean().item() == pytest.approx(mss.resolved_crosswind, rel=0.05)


@pytest.mark.parametrize("wind", [4.0, 12.0, 20.0])
def test_ocean_sea_holds_99_percent_of_its_height_variance(wind):
    sea = sea_state(wind=wind, spectrum="elfouhaily")
    edges = sea.wavenumber_bins(torch.float64)
    assert sea.m0(edges[0].item(), edges[-1].item()) / sea.m0() >= 0.99
    # and the sampled harmonics carry the band's variance in expectation (10 % noise over 512 seas)
    variance = WaveSurface.sample(sea, 512, seed=3, dtype=torch.float64).variance().mean().item()
    assert variance == pytest.approx(sea.m0(edges[0].item(), edges[-1].item()), rel=0.02)


def test_unresolved_slopes_are_rotated_into_the_wind_frame():
    sea = sea_state(spectrum="elfouhaily", wind_direction_deg=90.0)
    surface = WaveSurface.sample(sea, 2, seed=0, dtype=torch.float64)
    mss = sea.mean_square_slope()
    xx, xy, yy = surface.unresolved[0].tolist()
    assert yy == pytest.approx(mss.unresolved_upwind, rel=1e-9)  # the wind blows toward +y
    assert xx == pytest.approx(mss.unresolved_crosswind, rel=1e-9)
    assert abs(xy) < 1e-12


def test_unresolved_slopes_of_a_mixed_batch_are_each_winds_own():
    """Computed once per distinct wind and handed back in the batch's order: each row as if alone."""
    sea = sea_state(spectrum="elfouhaily")
    winds = torch.tensor([12.0, 4.0, 20.0, 12.0, 7.5, 4.0, 20.0, 12.0], dtype=torch.float64)
    upwind, crosswind = sea.unresolved_slope_variances(winds)
    for i, wind in enumerate(winds):
        up, cross = sea.unresolved_slope_variances(wind.reshape(1))
        assert upwind[i].item() == pytest.approx(up.item(), rel=1e-14)
        assert crosswind[i].item() == pytest.approx(cross.item(), rel=1e-14)
    assert upwind[1] < upwind[0] < upwind[2]  # rows not mixed up: slopes grow with the wind


def test_capillary_waves_travel_at_their_own_speed():
    sea = sea_state(spectrum="elfouhaily", wavenumber_cutoff=800.0)
    surface = WaveSurface.sample(sea, 1, seed=0, dtype=torch.float64)
    k = torch.hypot(surface.kx, surface.ky)
    torch.testing.assert_close(surface.omega, torch.sqrt(G * k * (1 + (k / 370.0) ** 2)))
    assert k.max().item() > 370.0


def test_paper_sea_carries_no_unresolved_slopes_and_a_flat_sea_none_at_all():
    paper = sea_state("jonswap")
    assert paper.mean_square_slope().unresolved == 0.0
    assert torch.all(WaveSurface.sample(paper, 4, seed=0).unresolved == 0)
    calm = sea_state(spectrum="elfouhaily", flat=True)
    assert calm.mean_square_slope().total == 0.0
    assert torch.all(WaveSurface.sample(calm, 4, seed=0).unresolved == 0)


def test_paper_sea_resolved_slopes_are_its_band_integral():
    """The paper's band holds 41 % of Cox-Munk at 12 m/s (the issue's table): ∫ S ω⁴/g² dω over [0.6, 6] ω_p."""
    sea = sea_state("jonswap", wind=12.0)
    low, high = sea.omega_band
    omega = torch.linspace(low, high, 100_001, dtype=torch.float64)
    want = torch.trapezoid(sea.frequency_spectrum(omega) * omega**4 / G**2, omega).item()
    assert sea.mean_square_slope().total == pytest.approx(want, rel=1e-6)
    assert sea.mean_square_slope().total / cox_munk(12.0).total == pytest.approx(0.41, abs=0.01)


@pytest.mark.parametrize(
    "kwargs,key",
    [
        ({"spectrum": "pierson"}, "spectrum"),
        ({"spectrum": "elfouhaily", "wavenumber_cutoff": 0.0}, "wavenumber_cutoff"),
        ({"spectrum": "elfouhaily", "n_wavenumbers": 0}, "n_wavenumbers"),
    ],
)
def test_bad_ocean_parameters_name_key_value_and_range(kwargs, key):
    with pytest.raises(ValueError) as info:
        sea_state(**kwargs)
    assert str(info.value).startswith(f"{key} = {kwargs[key]!r}")


@pytest.mark.parametrize(("spectrum", "key"), [("jonswap", "wavenumber_cutoff"), ("elfouhaily", "gamma")])
def test_each_sea_holds_only_its_own_keys(spectrum, key):
    with pytest.raises(ValueError, match=rf"^{key} is not a key of the {spectrum} sea; its keys: "):
        sea_state(spectrum, **{key: 5.0})
    assert sea_state(spectrum).spectrum == spectrum and not hasattr(sea_state(spectrum), key)
