"""Sea state: which spectrum, how it is cut into harmonics, and the slopes it holds (docs/model.md §1).

Two spectra: the paper's JONSWAP band (``spectrum="jonswap"``, :mod:`.jonswap`) and the
measured-slope sea of Elfouhaily et al. (``spectrum="elfouhaily"``, :mod:`.elfouhaily`), whose
waves shorter than a cutoff are carried as an unresolved slope variance (a two-scale sea).
Frequencies in rad/s, wavenumbers in rad/m, directions in radians relative to the wind, U10 in m/s,
fetch in m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from waterair.core.validation import check_choice, check_int, check_range
from waterair.physics.sea.elfouhaily import (
    elevation_spectrum,
    peak_wavenumber,
    spreading_ratio,
)
from waterair.physics.sea.jonswap import GRAVITY, jonswap, jonswap_alpha, jonswap_omega_p, spreading
from waterair.physics.sea.slopes import MeanSquareSlope, discrete_direction_factors, elfouhaily_slope_variance

BAND_LOW = 0.6
"""Lower band edge of the paper's sea as a multiple of ω_p: below it lies < 1e-4 of m0 (exp(-1.25/0.6⁴) ≈ 7e-5)."""
BAND_HIGH = 6.0
"""Upper band edge of the paper's sea as a multiple of ω_p: the ω⁻⁵ tail above it holds ≈ 0.1 % of m0."""
WAVENUMBER_LOW = 0.4
"""Lower wavenumber edge of the measured-slope sea as a multiple of k_p: below it lies < 3e-4 of m0."""
PEAK_CUTOFF = 12.0
"""The measured-slope sea's cutoff is never below 12 k_p, so that light winds (k_p near the cutoff)
still resolve ≥ 99 % of their height variance (docs/model.md §1.3)."""
SPECTRA = ("jonswap", "elfouhaily")
AMPLITUDE_CONVENTIONS = ("standard", "paper")
QUADRATURE_POINTS = 20_001
"""Points of the float64 trapezoid rules of the resolved slope variance (converged to 1e-7)."""


@dataclass(frozen=True)
class SeaState:
    """A validated sea state and its harmonic discretisation (docs/model.md §1).

    Attributes:
        wind: wind speed U10 (m/s), in (0, 60].
        fetch: fetch F (m), in (0, 1e7].
        gamma: JONSWAP peak enhancement γ, in [1, 10] (``jonswap`` only; Elfouhaily's γ follows Ω_c).
        n_freq: frequency bins of the JONSWAP band, in [1, 4096] (``jonswap`` only).
        n_dir: direction bins over [-π/2, π/2] around the wind, in [1, 1024].
        wind_direction_deg: direction the wind blows toward, degrees from +x, in [-360, 360].
        amplitude: ``"standard"`` (a = sqrt(2 S Δ), Var η = m0) or ``"paper"`` (a = sqrt(S Δ),
            the paper's form, Var η = m0 / 2).
        flat: a calm sea (all amplitudes and unresolved slopes zero) with the same discretisation.
        spectrum: ``"jonswap"`` (the paper's band [0.6 ω_p, 6 ω_p], deep-water waves) or
            ``"elfouhaily"`` (the unified spectrum with capillary-gravity waves up to ``wavenumber_cutoff``
            and the rest carried as unresolved slopes).
        n_wavenumbers: log-spaced wavenumber bins from 0.4 k_p to the cutoff, in [1, 4096]
            (``elfouhaily`` only).
        wavenumber_cutoff: shortest resolved wavenumber k_c (rad/m), in (0, 1e4] (``elfouhaily`` only); the
            band ends at max(wavenumber_cutoff, 12 k_p).
    """

    wind: float = 12.0
    fetch: float = 2.0e4
    gamma: float = 3.3
    n_freq: int = 64
    n_dir: int = 32
    wind_direction_deg: float = 0.0
    amplitude: str = "standard"
    flat: bool = False
    spectrum: str = "jonswap"
    n_wavenumbers: int = 48
    wavenumber_cutoff: float = 10.0

    def __post_init__(self) -> None:
        check_range("wind", self.wind, 0.0, 60.0, low_open=True, unit="m/s")
        check_range("fetch", self.fetch, 0.0, 1.0e7, low_open=True, unit="m")
        check_range("gamma", self.gamma, 1.0, 10.0)
        check_int("n_freq", self.n_freq, 1, 4096)
        check_int("n_dir", self.n_dir, 1, 1024)
        check_range("wind_direction_deg", self.wind_direction_deg, -360.0, 360.0, unit="deg")
        check_choice("amplitude", self.amplitude, AMPLITUDE_CONVENTIONS)
        check_choice("spectrum", self.spectrum, SPECTRA)
        check_int("n_wavenumbers", self.n_wavenumbers, 1, 4096)
        check_range("wavenumber_cutoff", self.wavenumber_cutoff, 0.0, 1.0e4, low_open=True, unit="rad/m")

    # --- the paper's JONSWAP sea (docs/model.md §1.1) ------------------------------------------

    @property
    def two_scale(self) -> bool:
        """Whether the sea carries the waves beyond its cutoff as unresolved slopes (``elfouhaily``): a
        two-scale sea, whose full channel is the two-scale lattice (docs/model.md §4.3)."""
        return self.spectrum == "elfouhaily"

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

    # --- the measured-slope sea of Elfouhaily et al. (docs/model.md §1.2-§1.3) -------------------

    def wavenumber_spectrum(self, k: torch.Tensor, wind: torch.Tensor | float | None = None) -> torch.Tensor:
        """Elfouhaily S(k) (m³/rad) of this fetch at ``wind`` (m/s; default :attr:`wind`); see elevation_spectrum."""
        return elevation_spectrum(k, self.wind if wind is None else wind, self.fetch)

    def resolved_cutoff(self, wind: torch.Tensor | float | None = None) -> torch.Tensor:
        """The shortest resolved wavenumber max(wavenumber_cutoff, 12 k_p) (rad/m) at ``wind`` (m/s)."""
        k_p = peak_wavenumber(self.wind if wind is None else wind, self.fetch)
        return torch.clamp(PEAK_CUTOFF * k_p, min=self.wavenumber_cutoff)

    def wavenumber_bins(
        self, dtype: torch.dtype = torch.float32, device=None, wind: torch.Tensor | None = None
    ) -> torch.Tensor:
        """Edges of the ``n_wavenumbers`` log-spaced bins from 0.4 k_p to :meth:`resolved_cutoff` (rad/m).

        ``[n_wavenumbers + 1]``; with a per-realisation ``wind`` (m/s, ``[B]``) ``[B, n_wavenumbers + 1]``.
        """
        wind_speed = torch.tensor(self.wind, dtype=torch.float64) if wind is None else wind.to(torch.float64)
        low = WAVENUMBER_LOW * peak_wavenumber(wind_speed, self.fetch)
        high = self.resolved_cutoff(wind_speed)
        fraction = torch.linspace(0.0, 1.0, self.n_wavenumbers + 1, dtype=torch.float64, device=low.device)
        edges = torch.exp(torch.log(low).unsqueeze(-1) + fraction * torch.log(high / low).unsqueeze(-1))
        return edges.to(device=device, dtype=dtype)

    def wavenumber_amplitudes(
        self, k: torch.Tensor, d_k: torch.Tensor, wind: torch.Tensor | None = None
    ) -> torch.Tensor:
        """Elfouhaily harmonic amplitudes a_ij (m) for wavenumbers ``k`` ``[..., n]``, shape ``[..., n, n_dir]``.

        ``a_ij = sqrt(c · S(k_i) w_ij Δk_i)`` (c as in :meth:`amplitudes`), with the spreading folded
        onto the downwind half-plane: ``w_ij ∝ 1 + Δ(k_i) cos 2θ_j``, normalised over j. Φ is
        centrosymmetric, and a component's slopes do not depend on the sign of its wavevector, so
        every wave travels downwind and the slope variance is unchanged (docs/model.md §1.3).
        ``wind`` (m/s, ``[B]`` for ``k`` ``[B, n]``) overrides :attr:`wind` per row.
        """
        wind_speed: float | torch.Tensor = self.wind if wind is None else wind.to(k.dtype).unsqueeze(-1)
        weights = self._elfouhaily_weights(k, wind_speed)
        energy = self._amplitude_factor * elevation_spectrum(k, wind_speed, self.fetch) * d_k
        amplitude = torch.sqrt(energy.unsqueeze(-1) * weights)
        return torch.zeros_like(amplitude) if self.flat else amplitude

    # --- shared -------------------------------------------------------------------------------

    def directions(self, dtype: torch.dtype = torch.float32, device=None) -> tuple[torch.Tensor, float]:
        """Direction bin centres relative to the wind (rad, ``[n_dir]``) and the bin width Δθ."""
        d_theta = math.pi / self.n_dir
        centres = -math.pi / 2 + (torch.arange(self.n_dir, dtype=dtype, device=device) + 0.5) * d_theta
        return centres, d_theta

    def m0(self, low: float = 0.0, high: float = math.inf) -> float:
        """Spectral variance m0 (m²) by quadrature over [low, high], rad/s (``jonswap``) or rad/m (``elfouhaily``).

        The default covers the whole spectrum. ``H_s = 4 sqrt(m0)``. For ``jonswap`` the ω⁻⁵ tail
        beyond 60 ω_p is added in closed form.
        """
        if self.spectrum == "elfouhaily":
            k_p = float(peak_wavenumber(self.wind, self.fetch))
            lo, hi = max(low, 1e-3 * k_p), min(high, 1e4 * k_p)
            if hi <= lo:
                return 0.0
            log_k = torch.linspace(math.log(lo), math.log(hi), QUADRATURE_POINTS, dtype=torch.float64)
            k = torch.exp(log_k)
            return torch.trapezoid(self.wavenumber_spectrum(k) * k, log_k).item()
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

    @property
    def significant_wave_height(self) -> float:
        """H_s = 4 sqrt(m0) in metres."""
        return 4.0 * math.sqrt(self.m0())

    def mean_square_slope(self, wind: float | None = None) -> MeanSquareSlope:
        """The mean square slopes this sea holds at ``wind`` (m/s; default :attr:`wind`), docs/model.md §1.4.

        Resolved: the expectation over realisations of the sampled harmonics' slope variance along
        and across the wind (what ``WaveSurface.sample`` draws, jitter and direction bins
        included). Unresolved: the spectrum beyond the cutoff (``elfouhaily``; 0 for ``jonswap``,
        whose band is the paper's sea as it is). A flat sea holds none.
        """
        speed = torch.tensor([self.wind if wind is None else wind], dtype=torch.float64)
        values = [float(v[0]) for v in self.slope_variances(speed)]
        return MeanSquareSlope(*values)

    def slope_variances(self, wind: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """Batched :meth:`mean_square_slope`: resolved up/crosswind, unresolved up/crosswind, each float64 ``[n]``.

        Args: wind U10 (m/s) ``[n]``, one sea per entry (this sea's other parameters).
        """
        wind = wind.to(torch.float64)
        zero = torch.zeros_like(wind)
        if self.flat:
            return zero, zero, zero, zero.clone()
        if self.spectrum == "jonswap":
            omega_p = jonswap_omega_p(wind, self.fetch).unsqueeze(-1)
            fraction = torch.linspace(BAND_LOW, BAND_HIGH, QUADRATURE_POINTS, dtype=torch.float64)
            omega = fraction * omega_p
            density = 0.5 * self._amplitude_factor * jonswap(omega, wind.unsqueeze(-1), self.fetch, self.gamma)
            density = density * (omega**2 / GRAVITY) ** 2  # k² S(ω) with k = ω²/g
            along, across = discrete_direction_factors(
                self._jonswap_weights(omega, omega_p), self.directions(torch.float64)[0]
            )
            return torch.trapezoid(density * along, omega), torch.trapezoid(density * across, omega), zero, zero.clone()
        edges = self.wavenumber_bins(torch.float64, wind=wind)
        low = edges[:, 0]
        high = edges[:, -1]
        fraction = torch.linspace(0.0, 1.0, QUADRATURE_POINTS, dtype=torch.float64)
        log_k = torch.log(low).unsqueeze(-1) + fraction * torch.log(high / low).unsqueeze(-1)
        k = torch.exp(log_k)
        speed = wind.unsqueeze(-1)
        slope_density = 0.5 * self._amplitude_factor * elevation_spectrum(k, speed, self.fetch) * k**3  # k² S d(ln k)
        along, across = discrete_direction_factors(
            self._elfouhaily_weights(k, speed), self.directions(torch.float64)[0]
        )
        resolved_up = torch.trapezoid(slope_density * along, log_k)
        resolved_cross = torch.trapezoid(slope_density * across, log_k)
        return (resolved_up, resolved_cross, *self.unresolved_slope_variances(wind))

    def unresolved_slope_variances(self, wind: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Up- and crosswind slope variance beyond :meth:`resolved_cutoff`, each float64 ``[n]`` (0 for ``jonswap``).

        Args: wind U10 (m/s) ``[n]``. The part of the measured-slope sea that the channel applies as
        an angular spread (docs/model.md §1.3).
        """
        wind = wind.to(torch.float64)
        if self.flat or self.spectrum == "jonswap":
            return torch.zeros_like(wind), torch.zeros_like(wind)
        upwind, crosswind = elfouhaily_slope_variance(self.resolved_cutoff(wind), math.inf, wind, self.fetch)
        scale = 0.5 * self._amplitude_factor
        return scale * upwind, scale * crosswind

    @property
    def _amplitude_factor(self) -> float:
        """c in a = sqrt(c S Δ): 2 for the standard convention, 1 for the paper's."""
        return 2.0 if self.amplitude == "standard" else 1.0

    def _jonswap_weights(self, omega: torch.Tensor, omega_p) -> torch.Tensor:
        """Direction weights ``[..., n_dir]`` of the JONSWAP spreading at ``omega``, summing to 1."""
        theta, d_theta = self.directions(omega.dtype, omega.device)
        weights = spreading(omega.unsqueeze(-1), theta, omega_p) * d_theta
        return weights / weights.sum(-1, keepdim=True)

    def _elfouhaily_weights(self, k: torch.Tensor, wind) -> torch.Tensor:
        """Direction weights ``[..., n_dir]`` of the folded Elfouhaily spreading at ``k``, summing to 1."""
        theta, _ = self.directions(k.dtype, k.device)
        delta = spreading_ratio(k, wind, self.fetch).unsqueeze(-1)
        weights = 1.0 + delta * torch.cos(2.0 * theta)
        return weights / weights.sum(-1, keepdim=True)
