"""Sea state: the JONSWAP spectrum, its directional spreading and their discretisation.

docs/model.md §1 (paper Sec. III, eqs. for S(ω), G(ω, θ) and T(x, y, t)). Angular frequencies ω are in
rad/s, directions θ in radians relative to the wind, wind speed U10 in m/s, fetch in m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from waterair.core.validation import check_choice, check_int, check_range

GRAVITY = 9.81
"""Gravitational acceleration g (m/s²), docs/model.md §1."""

JONSWAP_SIGMA_LOW = 0.07
"""Peak width σ for ω ≤ ω_p (docs/model.md §1)."""
JONSWAP_SIGMA_HIGH = 0.09
"""Peak width σ for ω > ω_p (docs/model.md §1)."""

BAND_LOW = 0.6
"""Lower band edge as a multiple of ω_p: below it lies < 1e-4 of m0 (exp(-1.25/0.6⁴) ≈ 7e-5)."""
BAND_HIGH = 6.0
"""Upper band edge as a multiple of ω_p: the ω⁻⁵ tail above it holds ≈ 0.1 % of m0 (docs/model.md §1)."""

AMPLITUDE_CONVENTIONS = ("standard", "paper")


def jonswap_alpha(wind, fetch):
    """Phillips constant α = 0.076 (U² / (g F))^0.22 (docs/model.md §1).

    Args: wind U10 (m/s), fetch F (m); floats or broadcastable tensors.
    """
    return 0.076 * (wind**2 / (GRAVITY * fetch)) ** 0.22


def jonswap_omega_p(wind, fetch):
    """Peak angular frequency ω_p = 22 (g² / (U F))^(1/3) in rad/s (docs/model.md §1).

    Args: wind U10 (m/s), fetch F (m); floats or broadcastable tensors.
    """
    return 22.0 * (GRAVITY**2 / (wind * fetch)) ** (1.0 / 3.0)


def jonswap(omega: torch.Tensor, wind, fetch: float, gamma: float = 3.3) -> torch.Tensor:
    """JONSWAP frequency spectrum S(ω) in m²·s/rad (docs/model.md §1, paper eq. (6)).

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
    """Directional spreading G(ω, θ) = (1/π)[1 + p cos 2θ + q cos 4θ] in 1/rad (docs/model.md §1, paper eq. (7)).

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


@dataclass(frozen=True)
class SeaState:
    """A validated sea state and its harmonic discretisation (docs/model.md §1).

    Attributes:
        wind: wind speed U10 (m/s), in (0, 60].
        fetch: fetch F (m), in (0, 1e7].
        gamma: JONSWAP peak enhancement γ, in [1, 10].
        n_freq: number of frequency bins, in [1, 4096].
        n_dir: number of direction bins over [-π/2, π/2] around the wind, in [1, 1024].
        wind_direction_deg: direction the wind blows toward, degrees from +x, in [-360, 360].
        amplitude: ``"standard"`` (a = sqrt(2 S G Δω Δθ), Var η = m0) or ``"paper"``
            (a = sqrt(S G Δω Δθ), the paper's form, Var η = m0 / 2).
        flat: a calm sea (all amplitudes zero) with the same discretisation.
    """

    wind: float = 12.0
    fetch: float = 2.0e4
    gamma: float = 3.3
    n_freq: int = 64
    n_dir: int = 32
    wind_direction_deg: float = 0.0
    amplitude: str = "standard"
    flat: bool = False

    def __post_init__(self) -> None:
        check_range("wind", self.wind, 0.0, 60.0, low_open=True, unit="m/s")
        check_range("fetch", self.fetch, 0.0, 1.0e7, low_open=True, unit="m")
        check_range("gamma", self.gamma, 1.0, 10.0)
        check_int("n_freq", self.n_freq, 1, 4096)
        check_int("n_dir", self.n_dir, 1, 1024)
        check_range("wind_direction_deg", self.wind_direction_deg, -360.0, 360.0, unit="deg")
        check_choice("amplitude", self.amplitude, AMPLITUDE_CONVENTIONS)

    @property
    def alpha(self) -> float:
        """Phillips constant α (dimensionless)."""
        return jonswap_alpha(self.wind, self.fetch)

    @property
    def omega_p(self) -> float:
        """Peak angular frequency ω_p (rad/s)."""
        return jonswap_omega_p(self.wind, self.fetch)

    @property
    def omega_band(self) -> tuple[float, float]:
        """Simulated frequency band [0.6 ω_p, 6 ω_p] (rad/s), holding ≥ 99 % of m0."""
        return BAND_LOW * self.omega_p, BAND_HIGH * self.omega_p

    def spectrum(self, omega: torch.Tensor) -> torch.Tensor:
        """S(ω) of this sea (m²·s/rad); see :func:`jonswap`."""
        return jonswap(omega, self.wind, self.fetch, self.gamma)

    def m0(self, low: float = 0.0, high: float = math.inf) -> float:
        """Spectral variance m0 = ∫ S dω (m²) over [low, high] rad/s, by float64 quadrature.

        The default covers the whole spectrum (the ω⁻⁵ tail beyond 60 ω_p is added in closed
        form). ``H_s = 4 sqrt(m0)``.
        """
        omega_p = self.omega_p
        top = 60.0 * omega_p
        lo, hi = max(low, 0.05 * omega_p), min(high, top)
        total = 0.0
        if hi > lo:
            omega = torch.linspace(lo, hi, 200_001, dtype=torch.float64)
            total = torch.trapezoid(self.spectrum(omega), omega).item()
        if high > top:
            total += self.alpha * GRAVITY**2 / (4.0 * max(low, top) ** 4)
        return total

    @property
    def significant_wave_height(self) -> float:
        """H_s = 4 sqrt(m0) in metres."""
        return 4.0 * math.sqrt(self.m0())

    def frequency_bins(
        self, dtype: torch.dtype = torch.float32, device=None, wind: torch.Tensor | None = None
    ) -> torch.Tensor:
        """Edges of the ``n_freq`` equal-width frequency bins over :attr:`omega_band` (rad/s).

        ``[n_freq + 1]``; with a per-realisation ``wind`` (m/s, ``[B]``, overriding :attr:`wind`)
        each row gets its own band, ``[B, n_freq + 1]``.
        """
        fraction = torch.linspace(BAND_LOW, BAND_HIGH, self.n_freq + 1, dtype=dtype, device=device)
        if wind is None:
            return fraction * self.omega_p
        return fraction * jonswap_omega_p(wind.to(dtype), self.fetch).unsqueeze(-1)

    def directions(self, dtype: torch.dtype = torch.float32, device=None) -> tuple[torch.Tensor, float]:
        """Direction bin centres relative to the wind (rad, ``[n_dir]``) and the bin width Δθ."""
        d_theta = math.pi / self.n_dir
        centres = -math.pi / 2 + (torch.arange(self.n_dir, dtype=dtype, device=device) + 0.5) * d_theta
        return centres, d_theta

    def amplitudes(self, omega: torch.Tensor, d_omega: torch.Tensor, wind: torch.Tensor | None = None) -> torch.Tensor:
        """Harmonic amplitudes a_ij (m) for frequencies ``omega`` ``[..., n_freq]``, shape ``[..., n_freq, n_dir]``.

        ``a_ij = sqrt(c · S(ω_i) w_ij Δω_i)`` with c = 2 (standard) or 1 (paper), where
        ``w_ij = G(ω_i, θ_j) Δθ`` normalised so that ``Σ_j w_ij = 1`` exactly: for n_dir ≥ 3 the
        midpoint rule already gives 1; the normalisation keeps Var η = m0 for coarser grids too.
        Correction (docs/model.md §1): the paper's form has c = 1, which gives half the variance.
        ``wind`` (m/s, ``[B]`` for ``omega`` ``[B, n_freq]``) overrides :attr:`wind` per row.
        """
        wind_speed: float | torch.Tensor
        omega_p: float | torch.Tensor
        if wind is None:
            wind_speed, omega_p = self.wind, self.omega_p
        else:
            wind_speed = wind.to(omega.dtype).unsqueeze(-1)
            omega_p = jonswap_omega_p(wind_speed, self.fetch).unsqueeze(-1)
        theta, d_theta = self.directions(omega.dtype, omega.device)
        weights = spreading(omega.unsqueeze(-1), theta, omega_p) * d_theta
        weights = weights / weights.sum(-1, keepdim=True)
        factor = 2.0 if self.amplitude == "standard" else 1.0
        energy = factor * jonswap(omega, wind_speed, self.fetch, self.gamma) * d_omega
        amplitude = torch.sqrt(energy.unsqueeze(-1) * weights)
        return torch.zeros_like(amplitude) if self.flat else amplitude
