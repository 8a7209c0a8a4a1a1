"""What the link's sensors report, and when (docs/environment.md, "Sensing").

The receiver measures the received intensity (a photodiode) and where the light arrives on a
quadrant detector (the ``spot``: the incoming direction in the receiver frame over tan ω_A); the
gimbals report their pointing. These readings form one *packet* per step, which reaches the
controller, at the transmitter, ``latency_steps`` steps late (the drone's readings travel back over an
acoustic or optical return link); the beacon reading, taken at the transmitter, reaches it at once
(:func:`waterair.envs.packets.deliver`). Readings are noisy (relative and additive intensity noise, angular spot
noise), the photodiode saturates, and below an intensity threshold the detector sees no spot.

The ideal sensor (every setting 0 or None) reports the true values at once; no random numbers are
drawn for it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from copy import copy as shallow_copy
from dataclasses import dataclass
from typing import Any, NamedTuple

import torch

from waterair.envs.noise import draw_nonce, normals
from waterair.physics.channel import Beacon
from waterair.physics.optics import Scalar, per_link, traced, transverse_frame, unit_vector

PACKET_PARTS = ("tx_pointing", "rx_pointing", "intensity", "spot", "spot_valid", "beacon", "beacon_valid", "history")
"""Observation parts that travel in the measurement packet: each arrives ``latency_steps`` late but the beacon's,
read where the controller runs."""
TRACED_SETTINGS = (
    "intensity_noise",
    "intensity_noise_floor",
    "spot_noise",
    "spot_threshold",
    "beacon_noise",
    "beacon_threshold",
)
"""The :class:`Sensor` settings a compiled step reads as tensors (:meth:`Sensor.traced`)."""
INTENSITY_EPS = 1e-6
"""Offset inside the observed intensity feature log10(I + ε), so that I = 0 maps to a finite value."""


def intensity_feature(intensity: torch.Tensor) -> torch.Tensor:
    """Observed intensity feature (log10(I + 1e-6) + 6) / 6: 0 for no light, ≈ 1 at calm-sea level.

    Monotone in I; logarithmic because I spans many decades between aligned and lost
    (docs/model.md §6).
    """
    return (torch.log10(intensity + INTENSITY_EPS) + 6.0) / 6.0


def intensity_from_feature(feature: torch.Tensor) -> torch.Tensor:
    """The inverse of :func:`intensity_feature`: the intensity I ≥ 0 a feature stands for."""
    return (10.0 ** (6.0 * feature - 6.0) - INTENSITY_EPS).clamp(min=0.0)


def spot_position(arrival: torch.Tensor, boresight: torch.Tensor, half_fov: float) -> torch.Tensor:
    """Incoming direction −u_a in the receiver frame over tan ω_A, ``[n, 2]`` (docs/model.md §6).

    The frame: e1 is +x projected across the boresight, e2 = boresight × e1. Within ±1 inside the
    field of view.
    """
    incoming = -arrival
    along = (incoming * boresight).sum(-1, keepdim=True)
    across = incoming - along * boresight
    e1, e2 = transverse_frame(boresight)
    return torch.stack(((across * e1).sum(-1), (across * e2).sum(-1)), -1) / (
        along.clamp(min=1e-6) * math.tan(half_fov)
    )


def read_parked(steps: torch.Tensor, latency_steps: int | torch.Tensor) -> torch.Tensor:
    """Whether the packet delivered for the decision after ``steps`` ``[n]`` steps since a reset was read with
    the gimbals parked as the reset leaves them (straight up and down): the reset's own packet, which the
    first ``latency_steps`` (one, or each row's ``[n]``) + 1 decisions receive. A tracker learns nothing about its
    own pointing from it."""
    return steps <= latency_steps


def back_projection(
    boresight: torch.Tensor,
    spot: torch.Tensor,
    seen: torch.Tensor,
    tx: torch.Tensor,
    rx: torch.Tensor,
    fallback: tuple[torch.Tensor, torch.Tensor],
    half_fov: float,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Quadrant-detector back-projection: unit transmitter (up) and receiver (down) pointing ``[n, 3]``.

    The receiver looks along the measured incoming direction (the ``spot`` ``[n, 2]`` read with
    ``boresight`` ``[n, 3]``); the transmitter points at where that ray, back-projected from R, meets
    the mean sea level z = 0. Rows not ``seen`` ``[n]`` (no reading) take ``fallback`` (tx, rx).
    """
    toward_surface = spot_direction(boresight, spot, half_fov)
    down = toward_surface[:, 2] < -1e-6
    reach = -rx[:, 2] / torch.where(down, toward_surface[:, 2], -torch.ones_like(rx[:, 2]))
    sea_point = rx + reach.unsqueeze(-1) * toward_surface
    use = (seen & down).unsqueeze(-1)
    return torch.where(use, unit_vector(sea_point - tx), fallback[0]), torch.where(use, toward_surface, fallback[1])


def spot_direction(boresight: torch.Tensor, spot: torch.Tensor, half_fov: float) -> torch.Tensor:
    """The unit incoming direction ``[n, 3]`` a reading ``spot`` ``[n, 2]``, read with ``boresight`` ``[n, 3]``
    over tan ``half_fov``, stands for: the inverse of :func:`spot_position`."""
    e1, e2 = transverse_frame(boresight)
    return unit_vector(boresight + math.tan(half_fov) * (spot[:, :1] * e1 + spot[:, 1:] * e2))


def beacon_pointing(
    readings: tuple[torch.Tensor, torch.Tensor, torch.Tensor],
    spots: tuple[torch.Tensor, torch.Tensor, torch.Tensor],
    fallback: tuple[torch.Tensor, torch.Tensor],
    beacon_half_fov: float,
    half_fov: float,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Each end from its own latest reading: unit transmitter (up) and receiver (down) pointing ``[n, 3]``.

    The transmitter points where the beacon's light comes from (``readings``: the transmitter's boresight, the
    beacon reading and whether it is seen), reciprocity's answer one reading late; the receiver along the
    measured uplink arrival (``spots``: the receiver's boresight, the spot and whether it is seen), as the
    quadrant tracker's. An end without a reading takes its ``fallback`` (tx, rx).
    """
    tx_boresight, beacon, beacon_seen = readings
    rx_boresight, spot, spot_seen = spots
    tx = torch.where(beacon_seen.unsqueeze(-1), spot_direction(tx_boresight, beacon, beacon_half_fov), fallback[0])
    rx = torch.where(spot_seen.unsqueeze(-1), spot_direction(rx_boresight, spot, half_fov), fallback[1])
    return tx, rx


def packet_sizes(history_length: int) -> tuple[int, ...]:
    """The widths of the parts of :data:`PACKET_PARTS` in one packet."""
    return (3, 3, 1, 2, 1, 2, 1, history_length)


@dataclass(frozen=True)
class SensorSettings:
    """The sensing keys of an environment (``EnvConfig.sensing``, validated there); the defaults are the ideal
    sensor.

    Attributes:
        latency_steps: steps a packet takes to reach the controller (0: the present model).
        intensity_noise: relative standard deviation of the measured intensity.
        intensity_noise_floor: additive standard deviation (units of I: the detector floor).
        intensity_saturation: the largest measurable I, or None.
        spot_noise_rad: standard deviation of each spot component, as an angle (rad).
        spot_threshold: measured I below which the spot reads nothing (``spot_valid`` 0, spot 0).
        beacon_noise_rad: standard deviation of each component of the transmitter's beacon reading (rad).
        beacon_threshold: beacon intensity (G_B over its calm-sea value) below which it reads nothing.
    """

    latency_steps: int = 0
    intensity_noise: float = 0.0
    intensity_noise_floor: float = 0.0
    intensity_saturation: float | None = None
    spot_noise_rad: float = 0.0
    spot_threshold: float = 0.0
    beacon_noise_rad: float = 0.0
    beacon_threshold: float = 0.0


class SensorNoise(NamedTuple):
    """One reading's standard normal draws (:meth:`Sensor.draw`), by the noise they feed; a source that is off
    reads zeros."""

    intensity_relative: torch.Tensor
    """``[n]``: the intensity's relative noise, σ_rel."""
    intensity_floor: torch.Tensor
    """``[n]``: its additive floor, σ_floor."""
    spot: torch.Tensor
    """``[n, 2]``: the spot reading's two components."""
    beacon: torch.Tensor
    """``[n, 2]``: the beacon reading's two components."""
    motion: torch.Tensor | None = None
    """``[n, MOTION_WIDTH]``: the step's draws of the ends' motion, where they move (``env.motion``; the inertial
    sensors' errors among them), drawn beside the readings' (:mod:`waterair.envs.platforms`)."""


class Sensor:
    """The sensor settings of one environment and the readings they turn true values into.

    Readings are pure functions of the true values and a noise draw (:meth:`draw`, made outside
    the compiled step from the sensor's own generator), so the step stays one graph.

    Args:
        settings: the sensing keys (:class:`SensorSettings`), or one per replica where the replicas sense
            differently (``env.replica_sensing``: an evaluation's controllers with each sensor side by side).
        half_fov: receiver half field of view ω_A (rad), the spot's scale.
        generator: the CPU generator of the readings' nonces (its own, so that noise never shifts the seas).
        beacon_half_fov: the beacon detector's half field of view (rad), the beacon reading's scale.

    Replicas that sense differently hold each setting as a tensor ``[replicas]`` (float64; the latency int64, no
    saturation +inf), which :meth:`at` turns into one value per row; a noise source is drawn where any replica
    has it, and a replica without it reads it at level 0, its true value unchanged.
    """

    def __init__(
        self,
        settings: SensorSettings | Sequence[SensorSettings],
        half_fov: float,
        generator: torch.Generator,
        beacon_half_fov: float = Beacon.half_fov,
    ):
        each = [settings] if isinstance(settings, SensorSettings) else list(settings)
        self.replicas = len(each) if len(set(each)) > 1 else None
        """The replicas that sense differently, or None where every row senses alike (plain settings)."""

        def setting(values: list) -> Any:  # one value, or a tensor of each replica's (float64, or int64)
            kind = torch.int64 if isinstance(values[0], int) else torch.float64
            return values[0] if self.replicas is None else torch.tensor(values, dtype=kind)

        self.latency_steps: int | torch.Tensor = setting([s.latency_steps for s in each])
        self.intensity_noise: Scalar = setting([float(s.intensity_noise) for s in each])
        self.intensity_noise_floor: Scalar = setting([float(s.intensity_noise_floor) for s in each])
        saturation = [math.inf if s.intensity_saturation is None else float(s.intensity_saturation) for s in each]
        self.intensity_saturation: Scalar | None = (
            setting(saturation) if self.replicas else each[0].intensity_saturation
        )
        self.spot_noise: Scalar = setting([s.spot_noise_rad / math.tan(half_fov) for s in each])
        self.spot_threshold: Scalar = setting([float(s.spot_threshold) for s in each])
        self.beacon_noise: Scalar = setting([s.beacon_noise_rad / math.tan(beacon_half_fov) for s in each])
        self.beacon_threshold: Scalar = setting([float(s.beacon_threshold) for s in each])
        self.generator = generator
        self.longest_latency = max(s.latency_steps for s in each)
        """The packets in flight are this many + 1, whatever each row's latency."""
        # which noise sources are on, for any replica: decided here, on the floats, so that a traced copy branches
        # the same way
        self.noisy_intensity = any(s.intensity_noise or s.intensity_noise_floor for s in each)
        self.noisy_spot = any(s.spot_noise_rad for s in each)
        self.noisy_beacon = any(s.beacon_noise_rad for s in each)
        self._noise_on = torch.tensor([self.noisy_intensity] * 2 + [self.noisy_spot] * 2 + [self.noisy_beacon] * 2)

    def traced(self, device: torch.device, dtype: torch.dtype) -> Sensor:
        """This sensor as a compiled step takes it: its noise levels and thresholds one-element tensors in
        ``dtype`` on ``device`` (:func:`~waterair.physics.optics.traced`), so that one graph serves every setting of
        them (as floats they would be compiled in, and a group of policies with another sensor would compile the
        step again); per replica settings on ``device``, in ``dtype`` but the latency. Same readings, same draws."""
        copy = shallow_copy(self)
        if self.replicas is None:
            for name in TRACED_SETTINGS:
                setattr(copy, name, traced(getattr(self, name), device, dtype))
            return copy
        for name in (*TRACED_SETTINGS, "intensity_saturation", "latency_steps"):
            value = getattr(self, name)
            setattr(copy, name, value.to(device) if name == "latency_steps" else value.to(device, dtype))
        return copy

    def at(self, replica: torch.Tensor) -> Sensor:
        """This sensor for rows of the replicas ``replica`` ``[n]`` (int64): each setting one value per row
        ``[n]``; a sensor whose rows sense alike is returned as it is."""
        if self.replicas is None:
            return self
        copy = shallow_copy(self)
        for name in (*TRACED_SETTINGS, "intensity_saturation", "latency_steps"):
            value = getattr(self, name)
            setattr(copy, name, value.to(replica.device)[replica])
        copy.replicas = None  # one value per row: read as they are
        return copy

    def draw(self, keys: torch.Tensor, dtype: torch.dtype, device: torch.device) -> SensorNoise | None:
        """Standard normal draws for one reading of the links of stream ``keys`` ``[n]`` (CPU int64,
        :func:`waterair.envs.noise.stream_keys`), or None if noiseless.

        Six a link, one stream (the intensity's two, the spot's two, the beacon's two, in this order, whichever
        are on); a source that is off reads zeros. One nonce is drawn from the generator per reading, so a link's
        noise depends on its key and the reading's count alone; a noiseless sensor draws its nonce too, so that the
        draws after it (the ends' motion's) are the same whatever the sensing (a replica's included).
        """
        if not (self.noisy_intensity or self.noisy_spot or self.noisy_beacon):
            draw_nonce(self.generator)
            return None
        draws = torch.where(self._noise_on, normals(keys, draw_nonce(self.generator), 6), 0.0)
        relative, floor, spot, beacon = draws.to(device=device, dtype=dtype).split((1, 1, 2, 2), dim=-1)
        return SensorNoise(relative.squeeze(-1), floor.squeeze(-1), spot, beacon)

    def intensity(self, true: torch.Tensor, noise: SensorNoise | None) -> torch.Tensor:
        """Measured intensity ``[n]``: I (1 + σ_rel n1) + σ_floor n2, clipped to [0, saturation]."""
        measured = true
        if self.noisy_intensity and noise is not None:
            relative, floor = per_link(self.intensity_noise, true), per_link(self.intensity_noise_floor, true)
            measured = true * (1.0 + relative * noise.intensity_relative) + floor * noise.intensity_floor
            measured = measured.clamp(min=0.0)
        if isinstance(self.intensity_saturation, torch.Tensor):  # per row (no saturation: +inf)
            measured = torch.minimum(measured, per_link(self.intensity_saturation, measured))
        elif self.intensity_saturation is not None:
            measured = measured.clamp(max=self.intensity_saturation)
        return measured

    def spot(self, true: torch.Tensor, lit: torch.Tensor, measured_intensity: torch.Tensor, noise: SensorNoise | None):
        """Spot reading ``[n, 2]`` and its validity ``[n]`` (float 0/1): noisy where light is seen, else 0."""
        return _gated(
            true,
            lit & (measured_intensity >= per_link(self.spot_threshold, measured_intensity)),
            self.noisy_spot,
            self.spot_noise,
            None if noise is None else noise.spot,
        )

    def beacon(self, true: torch.Tensor, lit: torch.Tensor, intensity: torch.Tensor, noise: SensorNoise | None):
        """Beacon reading ``[n, 2]`` and its validity ``[n]`` (float 0/1) at the transmitter: the true reading
        ``[n, 2]`` plus noise where the beacon's light is seen (``lit``) at ``intensity`` (G_B over its calm-sea
        value) at or above the threshold, else 0."""
        seen = lit & (intensity >= per_link(self.beacon_threshold, intensity))  # compared in the readings' dtype
        return _gated(true, seen, self.noisy_beacon, self.beacon_noise, None if noise is None else noise.beacon)


def _gated(true: torch.Tensor, valid: torch.Tensor, noisy: bool, scale: Scalar, noise: torch.Tensor | None):
    """A detector's reading ``[n, 2]`` and its validity ``[n]`` (float 0/1): ``true`` plus ``scale`` times its
    ``noise`` ``[n, 2]`` where the detector is ``noisy`` and a draw is given, 0 where not ``valid``."""
    reading = true
    if noisy and noise is not None:
        reading = true + per_link(scale, true) * noise
    reading = torch.where(valid.unsqueeze(-1), reading, torch.zeros_like(reading))
    return reading, valid.to(true.dtype)
