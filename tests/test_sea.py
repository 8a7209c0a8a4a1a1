"""JONSWAP spectrum, spreading and the sea-state discretisation (docs/model.md §1, §2)."""

import math

import pytest
import torch

from waterair.physics.sea import jonswap, sea_state, spreading

G = 9.81


def jonswap_reference(omega: float, wind: float, fetch: float, gamma: float = 3.3) -> float:
    """S(ω) written out independently with math, float64."""
    alpha = 0.076 * (wind**2 / (G * fetch)) ** 0.22
    omega_p = 22.0 * (G**2 / (wind * fetch)) ** (1 / 3)
    sigma = 0.07 if omega <= omega_p else 0.09
    r = math.exp(-((omega - omega_p) ** 2) / (2 * sigma**2 * omega_p**2))
    return alpha * G**2 / omega**5 * math.exp(-1.25 * (omega_p / omega) ** 4) * gamma**r


def test_check_values_from_spec():
    sea = sea_state("jonswap", wind=12.0, fetch=2.0e4)
    assert sea.alpha == pytest.approx(0.0155, rel=0.02)
    assert sea.omega_p == pytest.approx(1.62, rel=0.02)
    assert 2 * math.pi / sea.omega_p == pytest.approx(3.9, rel=0.02)
    assert sea.m0() == pytest.approx(0.066, rel=0.02)
    assert sea.significant_wave_height == pytest.approx(1.03, rel=0.02)


@pytest.mark.parametrize("wind,fetch", [(4.0, 1e3), (12.0, 2e4), (25.0, 1e6)])
def test_jonswap_matches_independent_formula(wind, fetch):
    omega = torch.linspace(0.2, 12.0, 97, dtype=torch.float64)
    got = jonswap(omega, wind, fetch)
    want = torch.tensor([jonswap_reference(w, wind, fetch) for w in omega.tolist()], dtype=torch.float64)
    torch.testing.assert_close(got, want, rtol=1e-12, atol=0.0)


def test_jonswap_is_zero_for_non_positive_frequencies():
    assert torch.all(jonswap(torch.tensor([-1.0, 0.0]), 12.0, 2e4) == 0)


@pytest.mark.parametrize("ratio", [0.3, 0.8, 1.0, 1.5, 3.0, 6.0])
def test_spreading_integrates_to_one(ratio):
    omega_p = 1.62
    theta = torch.linspace(-math.pi / 2, math.pi / 2, 20_001, dtype=torch.float64)
    g = spreading(torch.tensor(ratio * omega_p, dtype=torch.float64), theta, omega_p)
    assert torch.trapezoid(g, theta).item() == pytest.approx(1.0, abs=1e-8)


def test_spreading_is_zero_behind_the_wind():
    theta = torch.tensor([-2.0, 1.6, 3.0], dtype=torch.float64)
    assert torch.all(spreading(torch.tensor(1.0, dtype=torch.float64), theta, 1.0) == 0)


@pytest.mark.parametrize("wind", [0.5, 4.0, 12.0, 40.0])
def test_band_holds_99_percent_of_m0(wind):
    sea = sea_state("jonswap", wind=wind)
    assert sea.m0(*sea.omega_band) / sea.m0() >= 0.99


@pytest.mark.parametrize("n_dir", [1, 2, 3, 32])
@pytest.mark.parametrize("amplitude,factor", [("standard", 1.0), ("paper", 0.5)])
def test_amplitudes_carry_the_bin_energy(n_dir, amplitude, factor):
    """Σ_j a_ij² / 2 = factor · S(ω_i) Δω_i for any direction count."""
    sea = sea_state("jonswap", n_freq=16, n_dir=n_dir, amplitude=amplitude)
    edges = sea.frequency_bins(torch.float64)
    omega, d_omega = 0.5 * (edges[1:] + edges[:-1]), edges[1:] - edges[:-1]
    a = sea.amplitudes(omega, d_omega)
    torch.testing.assert_close(0.5 * (a**2).sum(-1), factor * sea.frequency_spectrum(omega) * d_omega)


def test_flat_sea_has_zero_amplitudes():
    sea = sea_state("jonswap", flat=True)
    edges = sea.frequency_bins(torch.float64)
    assert torch.all(sea.amplitudes(edges[:-1], edges[1:] - edges[:-1]) == 0)


@pytest.mark.parametrize(
    "kwargs,key",
    [
        ({"wind": 0.0}, "wind"),
        ({"wind": -3.0}, "wind"),
        ({"fetch": 0.0}, "fetch"),
        ({"n_freq": 0}, "n_freq"),
        ({"n_dir": 2.5}, "n_dir"),
        ({"gamma": 0.5}, "gamma"),
        ({"amplitude": "double"}, "amplitude"),
        ({"wind": float("nan")}, "wind"),
    ],
)
def test_bad_sea_parameters_name_key_value_and_range(kwargs, key):
    with pytest.raises(ValueError) as info:
        sea_state("jonswap", **kwargs)
    message = str(info.value)
    assert message.startswith(f"{key} = ")
    assert repr(next(iter(kwargs.values()))) in message
    assert "allowed" in message or "choose one of" in message


def test_paper_sea_is_sampled_bit_for_bit_as_the_first_release():
    """The JONSWAP sea (env/spectrum=paper) keeps the first release's draws and arithmetic exactly:
    equal-width bins over [0.6, 6] ω_p, one uniform jitter per bin, then uniform phases, each
    amplitude sqrt(2 S(ω) w Δω) with the spreading weights normalised per frequency."""
    from waterair.physics.surface import WaveSurface

    sea = sea_state("jonswap", wind=9.0, fetch=3e4, n_freq=12, n_dir=5)
    got = WaveSurface.sample(sea, 3, seed=11, dtype=torch.float64)

    generator = torch.Generator().manual_seed(11)
    omega_p = 22.0 * (G**2 / (9.0 * 3e4)) ** (1.0 / 3.0)
    edges = (torch.linspace(0.6, 6.0, 13, dtype=torch.float64) * omega_p).expand(3, 13)
    width = edges[:, 1:] - edges[:, :-1]
    omega = edges[:, :-1] + torch.rand(3, 12, generator=generator, dtype=torch.float64) * width
    theta = -math.pi / 2 + (torch.arange(5, dtype=torch.float64) + 0.5) * (math.pi / 5)
    weights = spreading(omega.unsqueeze(-1), theta, omega_p) * (math.pi / 5)
    weights = weights / weights.sum(-1, keepdim=True)
    amplitude = torch.sqrt((2.0 * jonswap(omega, 9.0, 3e4) * width).unsqueeze(-1) * weights)
    phase = 2.0 * math.pi * torch.rand(3, 60, generator=generator, dtype=torch.float64)
    wavenumber = (omega**2 / G).unsqueeze(-1)
    assert torch.equal(got.omega, omega.unsqueeze(-1).expand(3, 12, 5).reshape(3, -1))
    assert torch.equal(got.amplitude, amplitude.reshape(3, -1))
    assert torch.equal(got.kx, (wavenumber * torch.cos(theta)).reshape(3, -1))
    assert torch.equal(got.phase, phase)
