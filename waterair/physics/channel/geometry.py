"""Where the link's ends are and what optics they carry (docs/model.md §0, §4 and §5).

Distances in metres, angles in radians (``_deg`` names in degrees).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import torch

from waterair.core.validation import check_choice, check_range
from waterair.physics.optics import N_AIR, N_WATER, WATER_ATTENUATION_PER_M, RefractiveIndices, traced


@dataclass(frozen=True)
class LinkGeometry:
    """Where the transmitter (under water) and the receiver (in the air) are (docs/model.md §0).

    Attributes:
        tx_depth: transmitter depth below mean sea level (m), in (0, 1e4].
        rx_height: receiver height above mean sea level (m), in (0, 1e4].
        offset_ratio: horizontal offset D as a fraction of the vertical distance, in [0, 10]:
            D = offset_ratio · (tx_depth + rx_height).
        offset_azimuth_deg: direction of the offset from +x (degrees), in [-360, 360].
    """

    tx_depth: float = 10.0
    rx_height: float = 10.0
    offset_ratio: float = 0.1
    offset_azimuth_deg: float = 0.0

    def __post_init__(self) -> None:
        check_range("tx_depth", self.tx_depth, 0.0, 1.0e4, low_open=True, unit="m")
        check_range("rx_height", self.rx_height, 0.0, 1.0e4, low_open=True, unit="m")
        check_range("offset_ratio", self.offset_ratio, 0.0, 10.0)
        check_range("offset_azimuth_deg", self.offset_azimuth_deg, -360.0, 360.0, unit="deg")

    @property
    def horizontal_offset(self) -> float:
        """D (m)."""
        return self.offset_ratio * (self.tx_depth + self.rx_height)

    def positions(self, dtype: torch.dtype = torch.float32, device=None) -> tuple[torch.Tensor, torch.Tensor]:
        """Transmitter T = (0, 0, −tx_depth) and receiver R = (D cos φ, D sin φ, rx_height), each ``[3]``."""
        tx, rx = self.positions_for(torch.tensor([self.offset_ratio], dtype=torch.float64))
        return tx[0].to(device, dtype), rx[0].to(device, dtype)

    def positions_for(
        self, offset_ratio: torch.Tensor, azimuth_deg: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """T and R ``[n, 3]`` (m) for per-link offset ratios ``[n]`` and azimuths ``[n]`` (deg), in their dtype.

        Without ``azimuth_deg`` every link has :attr:`offset_azimuth_deg`.
        """
        distance = offset_ratio * (self.tx_depth + self.rx_height)
        if azimuth_deg is None:
            azimuth_deg = torch.full_like(offset_ratio, self.offset_azimuth_deg)
        phi = torch.deg2rad(azimuth_deg.to(offset_ratio))
        tx = torch.zeros(*offset_ratio.shape, 3, dtype=offset_ratio.dtype, device=offset_ratio.device)
        tx[..., 2] = -self.tx_depth
        rx = torch.stack(
            (distance * torch.cos(phi), distance * torch.sin(phi), torch.full_like(distance, self.rx_height)), -1
        )
        return tx, rx


@dataclass(frozen=True)
class Transceiver:
    """Optical parameters of the link (defaults in docs/model.md §5).

    Attributes:
        wavelength: laser wavelength λ (m), in (0, 1e-5].
        divergence: beam divergence ω_D (rad), in (0, π/2); a 0-dim tensor in the copy a compiled step
            takes (:meth:`traced`), one per link ``[B]`` in the copy a step of links with their own takes
            (:meth:`for_links`).
        half_fov: receiver half field of view ω_A (rad), in (0, π/2).
        concentrator_index: n_c (paper n2), in [1, 3].
        water: attenuation preset name, one of :data:`WATER_ATTENUATION_PER_M`.
        attenuation: attenuation coefficient c (1/m); None takes the preset's value.
        n_water, n_air: refractive indices.
        aperture_diameter: receiver aperture diameter D (m), in (0, 1]: the entrance of the receiver optics,
            over which the full channel averages the light (docs/model.md §4.3).
    """

    wavelength: float = 520e-9
    divergence: float = 0.05
    half_fov: float = 0.17
    concentrator_index: float = 1.0
    water: str = "clear_ocean"
    attenuation: float | None = None
    n_water: float = N_WATER
    n_air: float = N_AIR
    aperture_diameter: float = 0.05

    def __post_init__(self) -> None:
        check_range("wavelength", self.wavelength, 0.0, 1e-5, low_open=True, unit="m")
        if not (isinstance(self.divergence, torch.Tensor) and self.divergence.dim() > 0):  # one per link: checked
            check_range("divergence", self.divergence, 0.0, math.pi / 2, low_open=True, high_open=True, unit="rad")
        check_range("half_fov", self.half_fov, 0.0, math.pi / 2, low_open=True, high_open=True, unit="rad")
        check_range("concentrator_index", self.concentrator_index, 1.0, 3.0)
        check_choice("water", self.water, WATER_ATTENUATION_PER_M)
        if self.attenuation is not None:
            check_range("attenuation", self.attenuation, 0.0, 100.0, unit="1/m")
        check_range("n_water", self.n_water, 1.0, 3.0)
        check_range("n_air", self.n_air, 1.0, self.n_water)
        check_range("aperture_diameter", self.aperture_diameter, 0.0, 1.0, low_open=True, unit="m")

    def traced(self, device: torch.device | str | None = None) -> Transceiver:
        """This transceiver with ω_D a 0-dim float64 tensor on ``device``, as a compiled step takes it: a graph
        then reads the beam divergence as an input and serves every divergence (a float would be compiled in
        as a constant, and each new divergence would compile the step again). Same values, same checks. 0-dim,
        as a one-element ω_D would read as one link's (:meth:`rows`)."""
        return replace(self, divergence=traced(self.divergence, device, dims=0))  # type: ignore[arg-type]

    def for_links(self, divergence: torch.Tensor) -> Transceiver:
        """This transceiver with each link's own beam divergence ω_D ``[B]`` (rad, as drawn at its reset): every
        gain of it then reads link b's ω_D for link b (:func:`~waterair.physics.optics.per_link`)."""
        return replace(self, divergence=divergence)  # type: ignore[arg-type]  # ω_D a tensor

    def rows(self, index: slice | torch.Tensor) -> Transceiver:
        """This transceiver for the links ``index`` of a batch: the same, unless ω_D is one per link."""
        divergence = self.divergence
        if isinstance(divergence, torch.Tensor) and divergence.dim() == 1:
            return replace(self, divergence=divergence[index])  # type: ignore[arg-type]
        return self

    @property
    def indices(self) -> RefractiveIndices:
        """The refractive indices either side of the surface."""
        return RefractiveIndices(self.n_water, self.n_air)

    @property
    def attenuation_per_m(self) -> float:
        """The attenuation coefficient c in use (1/m)."""
        return WATER_ATTENUATION_PER_M[self.water] if self.attenuation is None else self.attenuation


def pointing(tilt: torch.Tensor, up: bool) -> torch.Tensor:
    """Unit pointing vector from a tilt vector v = (v_x, v_y), |v| ≤ 1 (docs/model.md §6).

    The transmitter (``up=True``) points (v_x, v_y, +sqrt(1 − |v|²)); the receiver
    (``up=False``) points (v_x, v_y, −sqrt(1 − |v|²)). ``tilt`` is ``[..., 2]``.
    """
    vertical = torch.sqrt(torch.clamp(1.0 - (tilt**2).sum(-1, keepdim=True), min=0.0))
    return torch.cat((tilt, vertical if up else -vertical), dim=-1)
