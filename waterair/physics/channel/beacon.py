"""The drone's beacon as the transmitter reads it: the channel's light, reversed (docs/model.md §4.9).

The drone carries a beacon aimed down; the transmitter a quadrant detector for it on its own gimbal, looking
along the laser. By Helmholtz reciprocity the beacon's light crosses the sea along the uplink's rays reversed:
each sample of the uplink's :class:`~waterair.physics.channel.light.LightSamples` (weight W, leaving T along u1,
reaching R along u2) is a sample of the beacon's light leaving R along −u2 and reaching T along −u1. Along a
ray tube the étendue n² dA dΩ is conserved, so the irradiance at T per unit intensity of a source at R is
(n_water / n_air)² times the irradiance at R per unit intensity of a source at T: the beacon's weight is
(n_w / n_a)² W (the Fresnel transmittance is the same both ways). The detector reads the beacon's centroid: the
mean incoming direction u1 of the samples, weighted by their share of the beacon's gain

    G_B = Σ (n_w / n_a)² W · G_D,B(angle from the beacon's axis to −u2) · G_A,T(angle from the detector's axis to u1),

with the beacon's Gaussian pattern G_D,B (its divergence and wavelength) and the detector's acceptance G_A,T
(its field of view and concentrator), the same formulas as the uplink's (paper eqs. (2) and (5)). Its reading,
reversed, is where the transmitter should point, one reading late.

Where it stops: the beacon's water attenuation is the uplink's (the channel's weights carry the uplink's
exp(−c d)); a beacon at a wavelength the water absorbs differently scales its gain, not its centroid, by
exp(−Δc d) along the path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import torch

from waterair.core.validation import check_choice, check_range
from waterair.physics.channel.geometry import Transceiver
from waterair.physics.channel.light import LightSamples, weighted_direction
from waterair.physics.optics import arrival_gain, departure_gain_at, peak_arrival_gain, sin_cos_between

BEACON_POINTINGS = ("receiver", "nadir")
"""Where the beacon aims: along the drone's receiver boresight (one gimbal for both), or straight down."""


@dataclass(frozen=True)
class Beacon:
    """The drone's beacon and the transmitter's detector for it (defaults in docs/model.md §4.9).

    Attributes:
        divergence: the beacon's beam divergence ω_B (rad), in (0, π/2): wide, so that it reaches the
            transmitter however the sea bends it.
        wavelength: the beacon's wavelength (m), in (0, 1e-5].
        pointing: one of :data:`BEACON_POINTINGS`.
        half_fov: the detector's half field of view (rad), in (0, π/2), about the transmitter's pointing.
        concentrator_index: the detector's concentrator index, in [1, 3].
    """

    divergence: float = 0.1
    wavelength: float = 470e-9
    pointing: str = "receiver"
    half_fov: float = 0.17
    concentrator_index: float = 1.0

    def __post_init__(self) -> None:
        check_range("divergence", self.divergence, 0.0, math.pi / 2, low_open=True, high_open=True, unit="rad")
        check_range("wavelength", self.wavelength, 0.0, 1e-5, low_open=True, unit="m")
        check_choice("pointing", self.pointing, BEACON_POINTINGS)
        check_range("half_fov", self.half_fov, 0.0, math.pi / 2, low_open=True, high_open=True, unit="rad")
        check_range("concentrator_index", self.concentrator_index, 1.0, 3.0)

    def axis(self, rx_dir: torch.Tensor) -> torch.Tensor:
        """The beacon's axis ``[B, 3]`` (unit, down) for the receiver boresights ``rx_dir`` ``[B, 3]``."""
        if self.pointing == "receiver":
            return rx_dir
        down = torch.zeros_like(rx_dir)
        down[:, 2] = -1.0
        return down

    def reference_gain(self, reference: torch.Tensor, optics: Transceiver) -> torch.Tensor:
        """G_B,0 ``[B]`` (1/m²): the beacon's gain on a calm sea with both ends aligned, from the uplink's G_0
        ``reference`` ``[B]``: (n_w / n_a)² G_0 with the detector's peak acceptance for the receiver's."""
        scale = (optics.n_water / optics.n_air) ** 2 * peak_arrival_gain(self.half_fov, self.concentrator_index)
        return reference * (scale / peak_arrival_gain(optics.half_fov, optics.concentrator_index))


class BeaconReading(NamedTuple):
    """What the transmitter's detector receives of the beacon, each with leading shape ``[B]``: the gain G_B
    (1/m²), the centroid's ``incoming`` direction (unit, from T up toward where the light comes from,
    ``[B, 3]``; the transmitter's pointing where none is seen) and whether any light is seen (``lit``)."""

    gain: torch.Tensor
    incoming: torch.Tensor
    lit: torch.Tensor


def read_beacon(
    light: LightSamples, tx_dir: torch.Tensor, rx_dir: torch.Tensor, beacon: Beacon, optics: Transceiver
) -> BeaconReading:
    """The beacon's light at the transmitter for the uplink's ``light`` ``[B, N]`` (the samples placed whatever
    the laser points at: :meth:`~.model.ChannelModel.unpointed_light`), the transmitter pointing ``tx_dir`` (up,
    the detector's axis) and the receiver boresight ``rx_dir`` (down) ``[B, 3]``."""
    axis = beacon.axis(rx_dir)
    sin_b, cos_b = sin_cos_between(axis.unsqueeze(1), -light.arrival)
    emitted = departure_gain_at(sin_b, cos_b, beacon.divergence, beacon.wavelength)
    sin_t, cos_t = sin_cos_between(tx_dir.unsqueeze(1), light.departure)
    accepted = arrival_gain(torch.atan2(sin_t, cos_t), beacon.half_fov, beacon.concentrator_index, cos_t)
    shares = ((optics.n_water / optics.n_air) ** 2) * light.weight * emitted * accepted
    gain = shares.sum(-1)
    return BeaconReading(gain, weighted_direction(shares, light.departure, tx_dir), gain > 0)
