"""The measured-slope sea: the Elfouhaily et al. (1997) unified directional spectrum (docs/model.md §1.2).

Elfouhaily, Chapron, Katsaros and Vandemark, "A unified directional spectrum for long and short
wind-driven waves", J. Geophys. Res. 102(C7), 15781-15796 (1997). Wavenumbers k are in rad/m,
phase speeds in m/s, wind speed U10 in m/s, fetch in m, directions φ in radians relative to the
wind. Every function takes floats or broadcastable tensors and returns tensors in the dtype of
``k`` (or of ``wind`` where there is no ``k``).

The spectrum is written as a curvature spectrum B(k) = B_l + B_h (long and short waves); the
elevation spectrum is S(k) = B(k) / k³ (eq. 1.12), with the variance ∫ S dk and the slope variance
∫ k² S dk = ∫ B d(ln k). Each formula below is one function, numbered as in docs/model.md §1.2.
"""

from __future__ import annotations

import math

import torch

from waterair.physics.sea.jonswap import GRAVITY

K_M = 370.0
"""Wavenumber of the phase-speed minimum k_m (rad/m), eq. (1.5): the gravity-capillary boundary."""
C_M = 0.23
"""Minimum phase speed c_m (m/s) at k_m, eq. (1.5): c(k_m) = sqrt(2 g / k_m) = 0.2303 m/s."""
FETCH_SCALE = 2.2e4
"""X_0, the dimensionless fetch at which the sea approaches full development, eq. (1.6)."""
FULLY_DEVELOPED = 0.84
"""Ω_c of a fully developed sea (infinite fetch), eq. (1.6)."""
VON_KARMAN = 0.4
"""von Kármán constant κ of the logarithmic wind profile, eq. (1.8)."""
CHARNOCK_WAVE_AGE = 3.7e-5
"""Coefficient of the wave-age-dependent roughness length z0 = 3.7e-5 (U²/g) Ω^0.9, eq. (1.8)
(Donelan, Dobson, Smith and Anderson 1993, as used by Elfouhaily et al. 1997)."""
ALPHA_P_EXPONENT = 0.55
"""Exponent of Ω in α_p = 6e-3 Ω^0.55, eq. (1.9) (docs/model.md §1.2 says why not √Ω)."""


def phase_speed(k: torch.Tensor) -> torch.Tensor:
    """Capillary-gravity phase speed c(k) = sqrt((g/k)(1 + (k/k_m)²)) in m/s, eq. (1.4).

    Args: k wavenumber (rad/m), > 0. Its minimum is c_m ≈ 0.23 m/s at k = k_m = 370 rad/m.
    """
    return torch.sqrt(GRAVITY / k * (1.0 + (k / K_M) ** 2))


def angular_frequency(k: torch.Tensor) -> torch.Tensor:
    """Capillary-gravity dispersion ω = sqrt(g k (1 + (k/k_m)²)) in rad/s, eq. (1.3).

    Args: k wavenumber (rad/m), ≥ 0.
    """
    return torch.sqrt(GRAVITY * k * (1.0 + (k / K_M) ** 2))


def inverse_wave_age(wind, fetch):
    """Ω_c = 0.84 tanh[(X / X_0)^0.4]^(-0.75), X = g F / U10², eq. (1.6) (dimensionless).

    Args: wind U10 (m/s), fetch F (m); floats or tensors. 0.84 is a fully developed sea; short
    fetches and strong winds give larger values (a younger sea).
    """
    wind = _tensor(wind)
    dimensionless_fetch = GRAVITY * fetch / wind**2
    return FULLY_DEVELOPED * torch.tanh((dimensionless_fetch / FETCH_SCALE) ** 0.4) ** -0.75


def peak_wavenumber(wind, fetch):
    """Spectral peak k_p = k_0 Ω_c², k_0 = g / U10², in rad/m, eq. (1.7).

    Args: wind U10 (m/s), fetch F (m).
    """
    wind = _tensor(wind)
    return GRAVITY / wind**2 * inverse_wave_age(wind, fetch) ** 2


def peak_inverse_wave_age(wind, fetch):
    """Ω = U10 / c(k_p), the inverse wave age at the peak phase speed, eq. (1.7) (dimensionless)."""
    wind = _tensor(wind)
    return wind / phase_speed(peak_wavenumber(wind, fetch))


def friction_velocity(wind, fetch):
    """Friction velocity u* = κ U10 / ln(10 m / z0) in m/s, with z0 = 3.7e-5 (U10²/g) Ω^0.9, eq. (1.8).

    The drag law: a logarithmic wind profile over the wave-age-dependent roughness of Donelan et
    al. (1993), which Elfouhaily et al. used; it gives u* = 0.52 m/s at 12 m/s and a 2e4 m fetch
    (drag coefficient 1.9e-3).

    Args: wind U10 (m/s), fetch F (m).
    """
    wind = _tensor(wind)
    roughness = CHARNOCK_WAVE_AGE * wind**2 / GRAVITY * peak_inverse_wave_age(wind, fetch) ** 0.9
    return VON_KARMAN * wind / torch.log(10.0 / roughness)


def long_wave_curvature(k: torch.Tensor, wind, fetch) -> torch.Tensor:
    """Long-wave curvature spectrum B_l = ½ α_p (c_p/c) F_p (dimensionless), eqs. (1.9)-(1.10).

    F_p = L_PM J_p exp[−(Ω/√10)(√(k/k_p) − 1)] with the Pierson-Moskowitz shape
    L_PM = exp[−(5/4)(k_p/k)²], the JONSWAP peak enhancement J_p = γ^Γ,
    Γ = exp[−(√(k/k_p) − 1)² / (2σ²)], σ = 0.08 (1 + 4 Ω_c⁻³), γ = 1.7 for Ω_c < 1 and
    1.7 + 6 log10 Ω_c above; α_p = 6e-3 Ω^0.55.

    Args: k wavenumber (rad/m), > 0; wind U10 (m/s), fetch F (m), broadcastable against k.
    """
    wind = torch.as_tensor(wind, dtype=k.dtype, device=k.device)
    k_p = peak_wavenumber(wind, fetch)
    omega = peak_inverse_wave_age(wind, fetch)
    alpha_p = 6e-3 * omega**ALPHA_P_EXPONENT
    c_p = phase_speed(k_p)
    root = torch.sqrt(k / k_p)
    f_p = peak_shape(k, wind, fetch) * torch.exp(-omega / math.sqrt(10.0) * (root - 1.0))
    return 0.5 * alpha_p * c_p / phase_speed(k) * f_p


def short_wave_curvature(k: torch.Tensor, wind, fetch) -> torch.Tensor:
    """Short-wave curvature spectrum B_h = ½ α_m (c_m/c) F_m (dimensionless), eq. (1.11).

    F_m = L_PM J_p exp[−¼ (k/k_m − 1)²]: the factor L_PM J_p (as in the common public
    implementations) keeps the short-wave term out of the long waves, where B_h ∝ √k alone would
    make the elevation spectrum B/k³ non-integrable at k → 0. α_m = 0.01 [1 + ln(u*/c_m)] for
    u* ≤ c_m and 0.01 [1 + 3 ln(u*/c_m)] above, clamped at 0: below u* = c_m/e (U10 ≈ 3 m/s) the
    fit turns negative, and there are no capillary ripples to speak of.

    Args: k wavenumber (rad/m), > 0; wind U10 (m/s), fetch F (m), broadcastable against k.
    """
    wind = torch.as_tensor(wind, dtype=k.dtype, device=k.device)
    log_ratio = torch.log(friction_velocity(wind, fetch) / C_M)
    alpha_m = 0.01 * (1.0 + torch.where(log_ratio <= 0, log_ratio, 3.0 * log_ratio))
    f_m = peak_shape(k, wind, fetch) * torch.exp(-0.25 * (k / K_M - 1.0) ** 2)
    return 0.5 * alpha_m.clamp(min=0.0) * C_M / phase_speed(k) * f_m


def peak_shape(k: torch.Tensor, wind, fetch) -> torch.Tensor:
    """L_PM J_p, the Pierson-Moskowitz shape times the JONSWAP peak enhancement, eq. (1.10)."""
    wind = torch.as_tensor(wind, dtype=k.dtype, device=k.device)
    k_p = peak_wavenumber(wind, fetch)
    omega_c = inverse_wave_age(wind, fetch)
    gamma = torch.where(omega_c < 1.0, torch.full_like(omega_c, 1.7), 1.7 + 6.0 * torch.log10(omega_c))
    sigma = 0.08 * (1.0 + 4.0 * omega_c**-3)
    enhancement = torch.exp(-((torch.sqrt(k / k_p) - 1.0) ** 2) / (2.0 * sigma**2))
    return torch.exp(-1.25 * (k_p / k) ** 2 + enhancement * torch.log(gamma))


def curvature_spectrum(k: torch.Tensor, wind, fetch) -> torch.Tensor:
    """Omnidirectional curvature spectrum B(k) = B_l + B_h (dimensionless), eq. (1.12)."""
    return long_wave_curvature(k, wind, fetch) + short_wave_curvature(k, wind, fetch)


def elevation_spectrum(k: torch.Tensor, wind, fetch) -> torch.Tensor:
    """Omnidirectional elevation spectrum S(k) = B(k) / k³ in m³/rad (m² per rad/m), eq. (1.12).

    Args: k wavenumber (rad/m), > 0; wind U10 (m/s), fetch F (m).
    """
    return curvature_spectrum(k, wind, fetch) / k**3


def spreading_ratio(k: torch.Tensor, wind, fetch) -> torch.Tensor:
    """Up/crosswind ratio Δ(k) = tanh[ln2/4 + 4 (c/c_p)^2.5 + 0.13 (u*/c_m)(c_m/c)^2.5], eq. (1.13).

    Args: k wavenumber (rad/m), > 0; wind U10 (m/s), fetch F (m). Dimensionless, in (0, 1).
    """
    wind = torch.as_tensor(wind, dtype=k.dtype, device=k.device)
    c = phase_speed(k)
    c_p = phase_speed(peak_wavenumber(wind, fetch))
    short = 0.13 * friction_velocity(wind, fetch) / C_M * (C_M / c) ** 2.5
    return torch.tanh(math.log(2.0) / 4.0 + 4.0 * (c / c_p) ** 2.5 + short)


def elfouhaily_spreading(k: torch.Tensor, phi: torch.Tensor, wind, fetch) -> torch.Tensor:
    """Directional spreading Φ(k, φ) = (1/2π)[1 + Δ(k) cos 2φ] in 1/rad, eq. (1.13); ∫ Φ dφ = 1 over 2π.

    Args: k (rad/m) and φ (rad, relative to the wind), broadcastable; wind U10 (m/s), fetch F (m).
    """
    return (1.0 + spreading_ratio(k, wind, fetch) * torch.cos(2.0 * phi)) / (2.0 * math.pi)


def _tensor(value) -> torch.Tensor:
    """A tensor as given, or a Python number as float64 (so that float64 callers lose nothing)."""
    return value if isinstance(value, torch.Tensor) else torch.tensor(float(value), dtype=torch.float64)
