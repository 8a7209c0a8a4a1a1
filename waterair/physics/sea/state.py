"""The sea state: what every sea shares, and what the surface and the channel read of it (docs/model.md §1).

Two seas implement it: the paper's JONSWAP band (:class:`~.jonswap_sea.JonswapSea`, ``spectrum =
"jonswap"``) and the measured-slope sea of Elfouhaily et al. (:class:`~.elfouhaily_sea.ElfouhailySea`,
``"elfouhaily"``), whose waves shorter than a cutoff are carried as an unresolved slope variance (a
two-scale sea); :func:`~.spectra.sea_state` builds one by its name. Each holds only its own keys.
Frequencies in rad/s, wavenumbers in rad/m, directions in radians relative to the wind, U10 in m/s,
fetch in m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import torch

from waterair.core.validation import check_choice, check_int, check_range
from waterair.physics.sea.slopes import MeanSquareSlope

AMPLITUDE_CONVENTIONS = ("standard", "paper")
QUADRATURE_POINTS = 20_001
"""Points of the float64 trapezoid rules of the resolved slope variance (converged to 1e-7)."""


class DirectionBins(NamedTuple):
    """The direction bins of a sea: their centres ``theta`` relative to the wind (rad, ``[n_dir]``) and their
    ``width`` Δθ (rad)."""

    theta: torch.Tensor
    width: float


@dataclass(frozen=True)
class SeaState:
    """What every sea is: validated shared keys, its harmonic discretisation and the slopes it holds.

    Attributes:
        wind: wind speed U10 (m/s), in (0, 60].
        fetch: fetch F (m), in (0, 1e7].
        n_dir: direction bins over [-π/2, π/2] around the wind, in [1, 1024].
        wind_direction_deg: direction the wind blows toward, degrees from +x, in [-360, 360].
        amplitude: ``"standard"`` (a = sqrt(2 S Δ), Var η = m0) or ``"paper"`` (a = sqrt(S Δ),
            the paper's form, Var η = m0 / 2).
        flat: a calm sea (all amplitudes and unresolved slopes zero) with the same discretisation.

    A sea implements :attr:`n_bins`, :meth:`bin_edges` and :meth:`harmonics` (how
    :meth:`waterair.physics.surface.WaveSurface.sample` cuts it into harmonics), :meth:`m0` and
    :meth:`resolved_slope_variances`; :attr:`spectrum` is its name and :attr:`two_scale` whether it carries
    unresolved slopes.
    """

    wind: float = 12.0
    fetch: float = 2.0e4
    n_dir: int = 32
    wind_direction_deg: float = 0.0
    amplitude: str = "standard"
    flat: bool = False

    spectrum: ClassVar[str]
    two_scale: ClassVar[bool] = False
    """Whether the sea carries the waves beyond its cutoff as unresolved slopes: a two-scale sea, whose
    full channel is the two-scale lattice (docs/model.md §4.3)."""

    def __post_init__(self) -> None:
        if type(self) is SeaState:
            raise TypeError("SeaState is what every sea shares: build JonswapSea, ElfouhailySea or sea_state(...)")
        check_range("wind", self.wind, 0.0, 60.0, low_open=True, unit="m/s")
        check_range("fetch", self.fetch, 0.0, 1.0e7, low_open=True, unit="m")
        check_int("n_dir", self.n_dir, 1, 1024)
        check_range("wind_direction_deg", self.wind_direction_deg, -360.0, 360.0, unit="deg")
        check_choice("amplitude", self.amplitude, AMPLITUDE_CONVENTIONS)

    @property
    def n_bins(self) -> int:
        """Frequency or wavenumber bins; the sea has ``n_bins × n_dir`` harmonics."""
        raise NotImplementedError

    def bin_edges(self, dtype: torch.dtype = torch.float32, device=None, wind: torch.Tensor | None = None):
        """Edges of the bins ``[n_bins + 1]`` (``[B, n_bins + 1]`` with a per-realisation ``wind`` ``[B]``, m/s)."""
        raise NotImplementedError

    def harmonics(self, drawn: torch.Tensor, width: torch.Tensor, wind: torch.Tensor | None = None):
        """(ω (rad/s) ``[B, n]``, amplitudes (m) ``[B, n, n_dir]``, |k| (rad/m) ``[B, n]``) of values ``drawn``
        inside bins of ``width`` (each ``[B, n]``, in the bins' unit)."""
        raise NotImplementedError

    def m0(self, low: float = 0.0, high: float = math.inf) -> float:
        """Spectral variance m0 (m²) over [low, high] in the bins' unit; the default covers the whole spectrum."""
        raise NotImplementedError

    def slope_variances(self, wind: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """Batched :meth:`mean_square_slope`: resolved up/crosswind, unresolved up/crosswind, each float64 ``[n]``.

        Args: wind U10 (m/s) ``[n]``, one sea per entry (this sea's other parameters). A flat sea holds none.
        """
        wind = wind.to(torch.float64)
        if self.flat:
            zero = torch.zeros_like(wind)
            return zero, zero, zero, zero.clone()
        return (*self.resolved_slope_variances(wind), *self.unresolved_slope_variances(wind))

    def resolved_slope_variances(self, wind: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Up- and crosswind slope variance of the sampled harmonics (their expectation over realisations), each
        float64 ``[n]``, for a sea that is not flat (wind float64 ``[n]``, m/s)."""
        raise NotImplementedError

    def unresolved_slope_variances(self, wind: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Up- and crosswind slope variance beyond the resolved band, each float64 ``[n]``: none by default."""
        wind = wind.to(torch.float64)
        return torch.zeros_like(wind), torch.zeros_like(wind)

    def directions(self, dtype: torch.dtype = torch.float32, device=None) -> DirectionBins:
        """Direction bin centres relative to the wind (rad, ``[n_dir]``) and the bin width Δθ."""
        d_theta = math.pi / self.n_dir
        centres = -math.pi / 2 + (torch.arange(self.n_dir, dtype=dtype, device=device) + 0.5) * d_theta
        return DirectionBins(centres, d_theta)

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

    @property
    def _amplitude_factor(self) -> float:
        """c in a = sqrt(c S Δ): 2 for the standard convention, 1 for the paper's."""
        return 2.0 if self.amplitude == "standard" else 1.0
