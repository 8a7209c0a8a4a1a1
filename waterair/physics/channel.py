"""Link geometry and the channel gain of a refracted path (docs/model.md §0 and §4, paper eq. (1)).

    G = G_D(α_D) · G_p(d_water, d_air) · G_ref(θ1) · G_A(α_A)

Distances in metres, angles in radians (``_deg`` names in degrees).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from tensordict import TensorClass

from waterair.core.validation import check_choice, check_range
from waterair.physics.optics import (
    N_AIR,
    N_WATER,
    WATER_ATTENUATION_PER_M,
    angle_between,
    arrival_gain,
    departure_gain,
    fresnel_transmittance,
    path_gain,
)
from waterair.physics.paths import PathSolution, flat_sea_point


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
        divergence: beam divergence ω_D (rad), in (0, π/2).
        half_fov: receiver half field of view ω_A (rad), in (0, π/2).
        concentrator_index: n_c (paper n2), in [1, 3].
        water: attenuation preset name, one of :data:`WATER_ATTENUATION_PER_M`.
        attenuation: attenuation coefficient c (1/m); None takes the preset's value.
        n_water, n_air: refractive indices.
    """

    wavelength: float = 520e-9
    divergence: float = 0.05
    half_fov: float = 0.17
    concentrator_index: float = 1.0
    water: str = "clear_ocean"
    attenuation: float | None = None
    n_water: float = N_WATER
    n_air: float = N_AIR

    def __post_init__(self) -> None:
        check_range("wavelength", self.wavelength, 0.0, 1e-5, low_open=True, unit="m")
        check_range("divergence", self.divergence, 0.0, math.pi / 2, low_open=True, high_open=True, unit="rad")
        check_range("half_fov", self.half_fov, 0.0, math.pi / 2, low_open=True, high_open=True, unit="rad")
        check_range("concentrator_index", self.concentrator_index, 1.0, 3.0)
        check_choice("water", self.water, WATER_ATTENUATION_PER_M)
        if self.attenuation is not None:
            check_range("attenuation", self.attenuation, 0.0, 100.0, unit="1/m")
        check_range("n_water", self.n_water, 1.0, 3.0)
        check_range("n_air", self.n_air, 1.0, self.n_water)

    @property
    def attenuation_per_m(self) -> float:
        """The attenuation coefficient c in use (1/m)."""
        return WATER_ATTENUATION_PER_M[self.water] if self.attenuation is None else self.attenuation


class ChannelGain(TensorClass):
    """G and its four factors for each batch element (all ``[B]``), plus the pointing errors.

    ``gain`` G (1/m²); ``departure`` G_D, ``path`` G_p (1/m²), ``refraction`` G_ref, ``arrival``
    G_A; ``alpha_d`` α_D and ``alpha_a`` α_A (rad). Invalid paths have every gain 0.
    """

    gain: torch.Tensor
    departure: torch.Tensor
    path: torch.Tensor
    refraction: torch.Tensor
    arrival: torch.Tensor
    alpha_d: torch.Tensor
    alpha_a: torch.Tensor


def channel_gain(path: PathSolution, tx_dir: torch.Tensor, rx_dir: torch.Tensor, optics: Transceiver) -> ChannelGain:
    """Channel gain of ``path`` for the given pointings (docs/model.md §4, paper eq. (1)).

    Args:
        path: the refracted path.
        tx_dir: unit transmitter pointing (upward), ``[B, 3]``.
        rx_dir: unit receiver boresight (downward), ``[B, 3]``.
        optics: transceiver parameters.

    α_D is the angle between ``tx_dir`` and u_d; α_A the angle between ``rx_dir`` and −u_a.
    """
    alpha_d = angle_between(tx_dir, path.departure)
    alpha_a = angle_between(rx_dir, -path.arrival)
    g_d = departure_gain(alpha_d, optics.divergence, optics.wavelength)
    g_a = arrival_gain(alpha_a, optics.half_fov, optics.concentrator_index)
    g_p, g_ref = _path_terms(path, optics)
    gain = g_d * g_p * g_ref * g_a
    return ChannelGain(
        gain=gain,
        departure=g_d,
        path=g_p,
        refraction=g_ref,
        arrival=g_a,
        alpha_d=alpha_d,
        alpha_a=alpha_a,
        batch_size=gain.shape[:1],
    )


def gain_upper_bound(path: PathSolution, optics: Transceiver) -> torch.Tensor:
    """G_UB = G_p G_ref n_c² / sin² ω_A: both ends pointed along the path (docs/model.md §4), ``[B]`` (1/m²)."""
    g_p, g_ref = _path_terms(path, optics)
    return g_p * g_ref * _peak_arrival_gain(optics)


def calm_sea_gain(link: LinkGeometry, optics: Transceiver, dtype: torch.dtype = torch.float64) -> float:
    """G_0: the aligned gain on a flat sea for this geometry (1/m²), the intensity reference (docs/model.md §4)."""
    tx, rx = link.positions(dtype)
    return float(calm_sea_gains(tx.unsqueeze(0), rx.unsqueeze(0), optics)[0])


def calm_sea_gains(tx: torch.Tensor, rx: torch.Tensor, optics: Transceiver) -> torch.Tensor:
    """G_0 for a batch of geometries, ``tx``/``rx`` ``[B, 3]`` (m) → ``[B]`` (1/m²)."""
    point = flat_sea_point(tx, rx, optics.n_water, optics.n_air)
    d_water = torch.linalg.vector_norm(point - tx, dim=-1)
    d_air = torch.linalg.vector_norm(rx - point, dim=-1)
    theta1 = torch.acos(((point - tx)[:, 2] / d_water).clamp(-1.0, 1.0))
    g_p = path_gain(d_water, d_air, optics.attenuation_per_m)
    g_ref = fresnel_transmittance(theta1, optics.n_water, optics.n_air)
    return g_p * g_ref * _peak_arrival_gain(optics)


def pointing(tilt: torch.Tensor, up: bool) -> torch.Tensor:
    """Unit pointing vector from a tilt vector v = (v_x, v_y), |v| ≤ 1 (docs/model.md §6).

    The transmitter (``up=True``) points (v_x, v_y, +sqrt(1 − |v|²)); the receiver
    (``up=False``) points (v_x, v_y, −sqrt(1 − |v|²)). ``tilt`` is ``[..., 2]``.
    """
    vertical = torch.sqrt(torch.clamp(1.0 - (tilt**2).sum(-1, keepdim=True), min=0.0))
    return torch.cat((tilt, vertical if up else -vertical), dim=-1)


def _peak_arrival_gain(optics: Transceiver) -> float:
    """G_A at α_A = 0: n_c² / sin² ω_A (docs/model.md §4)."""
    return optics.concentrator_index**2 / math.sin(optics.half_fov) ** 2


def _path_terms(path: PathSolution, optics: Transceiver) -> tuple[torch.Tensor, torch.Tensor]:
    """G_p and G_ref of a path, zero where the path is invalid."""
    g_p = path_gain(path.d_water, path.d_air, optics.attenuation_per_m)
    g_ref = fresnel_transmittance(path.theta1, optics.n_water, optics.n_air)
    zero = torch.zeros_like(g_p)
    return torch.where(path.valid, g_p, zero), torch.where(path.valid, g_ref, zero)
