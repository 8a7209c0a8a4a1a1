"""The paper's sea: the JONSWAP frequency spectrum and its directional spreading (docs/model.md §1.1).

Paper Sec. III, eqs. (6)-(7). Angular frequencies ω are in rad/s, directions θ in radians relative
to the wind, wind speed U10 in m/s, fetch in m. These formulas are kept exactly as the first release
had them, so that ``env/spectrum=jonswap`` reproduces the paper bit for bit.
"""

from __future__ import annotations

import math

import torch

GRAVITY = 9.81
"""Gravitational acceleration g (m/s²), docs/model.md §1."""

JONSWAP_SIGMA_LOW = 0.07
"""Peak width σ for ω ≤ ω_p (docs/model.md §1.1)."""
JONSWAP_SIGMA_HIGH = 0.09
"""Peak width σ for ω > ω_p (docs/model.md §1.1)."""


def jonswap_alpha(wind, fetch):
    """Phillips constant α = 0.076 (U² / (g F))^0.22 (docs/model.md §1.1).

    Args: wind U10 (m/s), fetch F (m); floats or broadcastable tensors.
    """
    return 0.076 * (wind**2 / (GRAVITY * fetch)) ** 0.22


def jonswap_omega_p(wind, fetch):
    """Peak angular frequency ω_p = 22 (g² / (U F))^(1/3) in rad/s (docs/model.md §1.1).

    Args: wind U10 (m/s), fetch F (m); floats or broadcastable tensors.
    """
    return 22.0 * (GRAVITY**2 / (wind * fetch)) ** (1.0 / 3.0)


def jonswap(omega: torch.Tensor, wind, fetch: float, gamma: float = 3.3) -> torch.Tensor:
    """JONSWAP frequency spectrum S(ω) in m²·s/rad (docs/model.md §1.1, paper eq. (6)).

    Args:
        omega: angular frequency (rad/s), any shape; S is 0 where ω ≤ 0.
        wind: wind speed U10 (m/s), a float or a tensor broadcastable against ``omega``.
        fetch: fetch F (m).
        gamma: peak enhancement factor γ (dimensionless).
    """
    alpha = jonswap_alpha(wind, fetch)
    omega_p = jonswap_omega_p(wind, fetch)
    positive = omega > 0
    w = torch.where(positive, omega, torch.ones_like(omega))
    sigma = torch.where(w <= omega_p, torch.full_like(w, JONSWAP_SIGMA_LOW), torch.full_like(w, JONSWAP_SIGMA_HIGH))
    peak = torch.exp(-((w - omega_p) ** 2) / (2.0 * sigma**2 * omega_p**2))
    # exp(r ln γ) rather than γ**r: a Python-float base is rounded to float32 by torch.pow.
    spectrum = alpha * GRAVITY**2 / w**5 * torch.exp(-1.25 * (omega_p / w) ** 4 + peak * math.log(gamma))
    return torch.where(positive, spectrum, torch.zeros_like(spectrum))


def spreading(omega: torch.Tensor, theta: torch.Tensor, omega_p) -> torch.Tensor:
    """Directional spreading G(ω, θ) = (1/π)[1 + p cos 2θ + q cos 4θ] in 1/rad (docs/model.md §1.1, paper eq. (7)).

    Args:
        omega: angular frequency (rad/s), broadcastable against ``theta``.
        theta: direction relative to the wind (rad); G is 0 for |θ| > π/2.
        omega_p: peak angular frequency (rad/s), a float or a broadcastable tensor.

    ``∫ G dθ = 1`` over [-π/2, π/2] for every ω.
    """
    decay = torch.exp(-0.5 * (omega / omega_p) ** 4)
    p = 0.5 + 0.82 * decay
    q = 0.32 * decay
    g = (1.0 + p * torch.cos(2.0 * theta) + q * torch.cos(4.0 * theta)) / math.pi
    return torch.where(theta.abs() <= math.pi / 2, g, torch.zeros_like(g))
