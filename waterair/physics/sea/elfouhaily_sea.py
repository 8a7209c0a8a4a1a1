"""The measured-slope sea as a sea state: Elfouhaily et al. (1997) up to a cutoff, the rest carried as
unresolved slopes (docs/model.md §1.2-§1.3)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from waterair.core.validation import check_int, check_range
from waterair.physics.sea.elfouhaily import angular_frequency, elevation_spectrum, peak_wavenumber, spreading_ratio
from waterair.physics.sea.slopes import discrete_direction_factors, elfouhaily_slope_variance
from waterair.physics.sea.state import QUADRATURE_POINTS, SeaState

WAVENUMBER_LOW = 0.4
"""Lower wavenumber edge of the measured-slope sea as a multiple of k_p: below it lies < 3e-4 of m0."""
PEAK_CUTOFF = 12.0
"""The measured-slope sea's cutoff is never below 12 k_p, so that light winds (k_p near the cutoff)
still resolve ≥ 99 % of their height variance (docs/model.md §1.3)."""


@dataclass(frozen=True)
class ElfouhailySea(SeaState):
    """The measured-slope sea (``spectrum = "elfouhaily"``): its shared keys (:class:`SeaState`) and

    Attributes:
        n_dir: direction bins, as every sea's, 16 by default here (docs/model.md §1.3).
        n_wavenumbers: log-spaced wavenumber bins from 0.4 k_p to the cutoff, in [1, 4096].
        wavenumber_cutoff: shortest resolved wavenumber k_c (rad/m), in (0, 1e4]; the band ends at
            max(wavenumber_cutoff, 12 k_p).
    """

    n_dir: int = 16
    n_wavenumbers: int = 48
    wavenumber_cutoff: float = 10.0

    spectrum = "elfouhaily"
    two_scale = True

    def __post_init__(self) -> None:
        super().__post_init__()
        self.check_own_keys(n_wavenumbers=self.n_wavenumbers, wavenumber_cutoff=self.wavenumber_cutoff)

    @staticmethod
    def check_own_keys(n_wavenumbers: int, wavenumber_cutoff: float) -> None:
        """Validate the keys only this sea has (a configuration that names another sea still checks them)."""
        check_int("n_wavenumbers", n_wavenumbers, 1, 4096)
        check_range("wavenumber_cutoff", wavenumber_cutoff, 0.0, 1.0e4, low_open=True, unit="rad/m")

    @property
    def n_bins(self) -> int:
        return self.n_wavenumbers

    def bin_edges(self, dtype: torch.dtype = torch.float32, device=None, wind: torch.Tensor | None = None):
        return self.wavenumber_bins(dtype, device, wind)

    def harmonics(self, drawn: torch.Tensor, width: torch.Tensor, wind: torch.Tensor | None = None):
        return angular_frequency(drawn), self.wavenumber_amplitudes(drawn, width, wind), drawn

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

    def m0(self, low: float = 0.0, high: float = math.inf) -> float:
        """Spectral variance m0 (m²) by quadrature over wavenumbers [low, high] (rad/m); the default covers
        the whole spectrum. ``H_s = 4 sqrt(m0)``."""
        k_p = float(peak_wavenumber(self.wind, self.fetch))
        lo, hi = max(low, 1e-3 * k_p), min(high, 1e4 * k_p)
        if hi <= lo:
            return 0.0
        log_k = torch.linspace(math.log(lo), math.log(hi), QUADRATURE_POINTS, dtype=torch.float64)
        k = torch.exp(log_k)
        return torch.trapezoid(self.wavenumber_spectrum(k) * k, log_k).item()

    def resolved_slope_variances(self, wind: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Up- and crosswind slope variance of the harmonics: the trapezoid rule of k² S(k) over the band's
        log-spaced wavenumbers, shared out by the discrete directions (docs/model.md §1.4)."""
        edges = self.wavenumber_bins(torch.float64, wind=wind)
        low = edges[:, 0]
        high = edges[:, -1]
        fraction = torch.linspace(0.0, 1.0, QUADRATURE_POINTS, dtype=torch.float64)
        log_k = torch.log(low).unsqueeze(-1) + fraction * torch.log(high / low).unsqueeze(-1)
        k = torch.exp(log_k)
        speed = wind.unsqueeze(-1)
        slope_density = 0.5 * self._amplitude_factor * elevation_spectrum(k, speed, self.fetch) * k**3  # k² S d(ln k)
        along, across = discrete_direction_factors(
            self._elfouhaily_weights(k, speed), self.directions(torch.float64).theta
        )
        return torch.trapezoid(slope_density * along, log_k), torch.trapezoid(slope_density * across, log_k)

    def unresolved_slope_variances(self, wind: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Up- and crosswind slope variance beyond :meth:`resolved_cutoff`, each float64 ``[n]``.

        Args: wind U10 (m/s) ``[n]``. The part of the measured-slope sea that the channel applies as
        an angular spread (docs/model.md §1.3).
        """
        wind = wind.to(torch.float64)
        if self.flat:
            return torch.zeros_like(wind), torch.zeros_like(wind)
        # once per distinct wind (a batch of seas has a few); the integrals are row by row: the same values, to
        # a float64 ulp (invisible in the float32 seas)
        speeds, each = torch.unique(wind, return_inverse=True)
        upwind, crosswind = elfouhaily_slope_variance(self.resolved_cutoff(speeds), math.inf, speeds, self.fetch)
        scale = 0.5 * self._amplitude_factor
        return scale * upwind[each], scale * crosswind[each]

    def _elfouhaily_weights(self, k: torch.Tensor, wind) -> torch.Tensor:
        """Direction weights ``[..., n_dir]`` of the folded Elfouhaily spreading at ``k``, summing to 1."""
        theta, _ = self.directions(k.dtype, k.device)
        delta = spreading_ratio(k, wind, self.fetch).unsqueeze(-1)
        weights = 1.0 + delta * torch.cos(2.0 * theta)
        return weights / weights.sum(-1, keepdim=True)
