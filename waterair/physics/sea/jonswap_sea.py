"""The paper's sea as a sea state: JONSWAP over [0.6, 6] ω_p, deep-water waves (docs/model.md §1.1)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from waterair.core.validation import check_int, check_range
from waterair.physics.sea.jonswap import GRAVITY, jonswap, jonswap_alpha, jonswap_omega_p, spreading
from waterair.physics.sea.slopes import discrete_direction_factors
from waterair.physics.sea.state import QUADRATURE_POINTS, SeaState

BAND_LOW = 0.6
"""Lower band edge of the paper's sea as a multiple of ω_p: below it lies < 1e-4 of m0 (exp(-1.25/0.6⁴) ≈ 7e-5)."""
BAND_HIGH = 6.0
"""Upper band edge of the paper's sea as a multiple of ω_p: the ω⁻⁵ tail above it holds ≈ 0.1 % of m0."""


@dataclass(frozen=True)
class JonswapSea(SeaState):
    """The paper's sea (``spectrum = "jonswap"``): its shared keys (:class:`SeaState`) and

    Attributes:
        gamma: JONSWAP peak enhancement γ, in [1, 10].
        n_freq: frequency bins of the band, in [1, 4096].
    """

    gamma: float = 3.3
    n_freq: int = 64

    spectrum = "jonswap"

    def __post_init__(self) -> None:
        super().__post_init__()
        self.check_own_keys(gamma=self.gamma, n_freq=self.n_freq)

    @staticmethod
    def check_own_keys(gamma: float, n_freq: int) -> None:
        """Validate the keys only this sea has (a configuration that names another sea still checks them)."""
        check_range("gamma", gamma, 1.0, 10.0)
        check_int("n_freq", n_freq, 1, 4096)

    @property
    def n_bins(self) -> int:
        return self.n_freq

    def bin_edges(self, dtype: torch.dtype = torch.float32, device=None, wind: torch.Tensor | None = None):
        return self.frequency_bins(dtype, device, wind)

    def harmonics(self, drawn: torch.Tensor, width: torch.Tensor, wind: torch.Tensor | None = None):
        return drawn, self.amplitudes(drawn, width, wind), drawn**2 / GRAVITY

    @property
    def alpha(self) -> float:
        """JONSWAP Phillips constant α (dimensionless)."""
        return jonswap_alpha(self.wind, self.fetch)

    @property
    def omega_p(self) -> float:
        """JONSWAP peak angular frequency ω_p (rad/s)."""
        return jonswap_omega_p(self.wind, self.fetch)

    @property
    def omega_band(self) -> tuple[float, float]:
        """The paper's frequency band [0.6 ω_p, 6 ω_p] (rad/s), holding ≥ 99 % of m0."""
        return BAND_LOW * self.omega_p, BAND_HIGH * self.omega_p

    def frequency_spectrum(self, omega: torch.Tensor) -> torch.Tensor:
        """JONSWAP S(ω) of this wind and fetch (m²·s/rad); see :func:`jonswap`."""
        return jonswap(omega, self.wind, self.fetch, self.gamma)

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

    def amplitudes(self, omega: torch.Tensor, d_omega: torch.Tensor, wind: torch.Tensor | None = None) -> torch.Tensor:
        """JONSWAP amplitudes a_ij (m) for frequencies ``omega`` ``[..., n_freq]``, shape ``[..., n_freq, n_dir]``.

        ``a_ij = sqrt(c · S(ω_i) w_ij Δω_i)`` with c = 2 (standard) or 1 (paper), where
        ``w_ij = G(ω_i, θ_j) Δθ`` normalised so that ``Σ_j w_ij = 1`` exactly: for n_dir ≥ 3 the
        midpoint rule already gives 1; the normalisation keeps Var η = m0 for coarser grids too.
        Correction (docs/model.md §1.1): the paper's form has c = 1, which gives half the variance.
        ``wind`` (m/s, ``[B]`` for ``omega`` ``[B, n_freq]``) overrides :attr:`wind` per row.
        """
        wind_speed: float | torch.Tensor
        omega_p: float | torch.Tensor
        if wind is None:
            wind_speed, omega_p = self.wind, self.omega_p
        else:
            wind_speed = wind.to(omega.dtype).unsqueeze(-1)
            omega_p = jonswap_omega_p(wind_speed, self.fetch).unsqueeze(-1)
        weights = self._jonswap_weights(omega, omega_p)
        energy = self._amplitude_factor * jonswap(omega, wind_speed, self.fetch, self.gamma) * d_omega
        amplitude = torch.sqrt(energy.unsqueeze(-1) * weights)
        return torch.zeros_like(amplitude) if self.flat else amplitude

    def m0(self, low: float = 0.0, high: float = math.inf) -> float:
        """Spectral variance m0 (m²) by quadrature over frequencies [low, high] (rad/s); the default covers
        the whole spectrum, the ω⁻⁵ tail beyond 60 ω_p added in closed form. ``H_s = 4 sqrt(m0)``."""
        omega_p = self.omega_p
        top = 60.0 * omega_p
        lo, hi = max(low, 0.05 * omega_p), min(high, top)
        total = 0.0
        if hi > lo:
            omega = torch.linspace(lo, hi, 200_001, dtype=torch.float64)
            total = torch.trapezoid(self.frequency_spectrum(omega), omega).item()
        if high > top:
            total += self.alpha * GRAVITY**2 / (4.0 * max(low, top) ** 4)
        return total

    def resolved_slope_variances(self, wind: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Up- and crosswind slope variance of the harmonics: the trapezoid rule of k² S(ω) over the band
        [0.6, 6] ω_p, shared out by the discrete directions (docs/model.md §1.4)."""
        omega_p = jonswap_omega_p(wind, self.fetch).unsqueeze(-1)
        fraction = torch.linspace(BAND_LOW, BAND_HIGH, QUADRATURE_POINTS, dtype=torch.float64)
        omega = fraction * omega_p
        density = 0.5 * self._amplitude_factor * jonswap(omega, wind.unsqueeze(-1), self.fetch, self.gamma)
        density = density * (omega**2 / GRAVITY) ** 2  # k² S(ω) with k = ω²/g
        along, across = discrete_direction_factors(
            self._jonswap_weights(omega, omega_p), self.directions(torch.float64).theta
        )
        return torch.trapezoid(density * along, omega), torch.trapezoid(density * across, omega)

    def _jonswap_weights(self, omega: torch.Tensor, omega_p) -> torch.Tensor:
        """Direction weights ``[..., n_dir]`` of the JONSWAP spreading at ``omega``, summing to 1."""
        theta, d_theta = self.directions(omega.dtype, omega.device)
        weights = spreading(omega.unsqueeze(-1), theta, omega_p) * d_theta
        return weights / weights.sum(-1, keepdim=True)
