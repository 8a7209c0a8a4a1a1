"""Classical controllers: what an engineer builds on the link's sensors instead of RL.

Each is a TensorDict policy like the baselines (:mod:`waterair.envs.baselines`) and reads only
what the chosen sensor model delivers in the observation (docs/environment.md, "Sensing") plus
the nominal geometry (``tx_position``, ``rx_position``) and the datasheet optics. Their
assumptions are in their docstrings; ``required_extras`` names the observation parts they need.
"""

from __future__ import annotations

import math

import torch

from waterair.envs import tracks
from waterair.envs.baselines import FlatSeaSnell, PointingPolicy
from waterair.envs.sensors import back_projection, beacon_pointing, intensity_from_feature, read_parked
from waterair.physics.channel import pointing
from waterair.physics.optics import per_link, unit_vector


class BeaconTracker(PointingPolicy):
    """Each end along its own reading: the terminals sense each other (docs/model.md §4.9).

    Assumes a beacon on the drone and a quadrant detector for it on the transmitter's gimbal, read with the
    transmitter's present pointing where the controller runs, so at once, and the drone's quadrant detector for
    the uplink (as :class:`AoATracker`), its reading over the return link in the packet; the detectors' fields of
    view from their datasheets.

    * Transmitter: where the beacon's light comes from, the measured beacon arrival reversed: by reciprocity
      the direction in which the uplink leaves toward the drone, one reading late.
    * Receiver: along the measured incoming direction, as the quadrant tracker.
    * An end with no reading (no light in its detector's field of view, or below its threshold): flat-sea
      Snell for that end. A reading taken with the gimbals parked at the reset is used as any other (the
      quadrant tracker waits for its own): the beacon's beam is wide, so the parked drone still lights the
      transmitter, and its centroid leans less toward the beacon's axis than the spot toward the laser's.
    """

    name = "beacon_tracker"
    required_extras = ("spot", "spot_valid", "beacon", "beacon_valid")

    def directions(self, tensordict):
        flat = FlatSeaSnell.directions(self, tensordict)
        observation, part = tensordict.get("observation"), self.env.observation_part
        beacon = (
            pointing(tensordict.get("pointed")[:, :2], up=True),  # read with the present pointing, at once
            part(observation, "beacon"),
            part(observation, "beacon_valid")[:, 0] > 0.5,
        )
        spot = (
            part(observation, "rx_pointing"),
            part(observation, "spot"),
            part(observation, "spot_valid")[:, 0] > 0.5,
        )
        return beacon_pointing(beacon, spot, flat, self.config.beacon.half_fov, self.env.optics.half_fov)


class BeaconPredictor(BeaconTracker):
    """The beacon tracker, each end carried one step ahead along its last move (docs/environment.md, "Classical
    controllers").

    The pointing chosen from a reading acts one step after the reading reached the controller, so the beacon
    tracker points the transmitter where the path was one step before (as ``tracking``), the receiver
    ``latency_steps + 1`` steps before (its reading comes over the return link). This controller adds to each
    end's direction the change between its last two readings, that step's angle clamped at ``max_step``
    (rad): where the light splits between refraction points the centroid jumps, and a jump carried on would
    throw the beam off. An end whose reading is lost, or whose last two readings are not both the tracking's
    (a link's first step, the readings of the gimbals parked at the reset), points as the beacon tracker does.
    The controller keeps each link's last directions.
    """

    name = "beacon_predictor"

    def __init__(self, env, max_step: float = 3e-3, config=None):
        super().__init__(env, config)
        self.max_step = max_step
        self.last: torch.Tensor | None = None  # [2, n, 3]: each end's direction from the last reading
        self.tracked: torch.Tensor | None = None  # [2, n]: whether that reading was seen while tracking

    def directions(self, tensordict):
        now = torch.stack(super().directions(tensordict))
        observation, part = tensordict.get("observation"), self.env.observation_part
        seen = torch.stack((part(observation, "beacon_valid")[:, 0], part(observation, "spot_valid")[:, 0])) > 0.5
        beacon_parked = parked_reading(self.env, observation, 0)  # the beacon is never late
        tracked = seen & ~torch.stack((beacon_parked, parked_reading(self.env, observation, self.config.latency_steps)))
        if self.last is None or self.last.shape != now.shape:
            self.last, self.tracked = now, torch.zeros_like(tracked)
        move = now - self.last
        move = move * (self.max_step / torch.linalg.vector_norm(move, dim=-1, keepdim=True).clamp(min=self.max_step))
        ahead = torch.where((tracked & self.tracked).unsqueeze(-1), unit_vector(now + move), now)
        self.last, self.tracked = now, tracked
        return ahead[0], ahead[1]


class KalmanTracker(BeaconTracker):
    """The beacon tracker's readings, each end's filtered and pointed ahead: a Kalman filter on each component's
    angle and rate (:mod:`waterair.envs.tracks`, the filter the ``kalman_tracker`` residual base runs inside the
    step), tuned from the configuration, not by hand.

    * The reading: each end's ``beacon_tracker`` direction, as a tilt; its variance the sensor's noise
      (``beacon_noise_rad`` at the transmitter, ``spot_noise_rad`` at the receiver), at least :data:`FLOOR`.
    * The motion: white acceleration of the variance the link's own sea gives the direction of its light, the
      slope's acceleration Σ a² k_c² ω⁴ / 2 per component c over the resolved harmonics, times the share of a
      slope the refracted light turns by (1 − n_air/n_water at the transmitter, n_water/n_air − 1 at the
      receiver); a track starts at the slope rate's variance, Σ a² k_c² ω² / 2 times the same. Where the ends
      move (``env.motion``), the drone's drift and transit add theirs (:func:`~waterair.envs.tracks.motion_terms`).
    * Pointing ahead over what separates the reading from the pointing it sets: one step at the transmitter,
      ``latency_steps + 1`` at the receiver, and the actuators' lag (``env.actuator``: how far the axis that
      points last trails a ramp commanded once a step; none without actuators), along the estimated rate times the
      share of it that carried over in this episode's steps so far (:class:`~waterair.envs.kalman.Carry`, a
      memory of :data:`MEMORY`, started at none of it, with one step's weight): the whole of it on a swell or a
      crossing drone, less where the light turns back within a step, where pointing along the rate overshoots.
    * A reading lost, read with the gimbals parked at the reset, or beyond :data:`GATE` standard deviations of its
      innovation (the centroid jumping between refraction points) starts that end's track again: it points as
      the beacon tracker does until its next reading, and at its filtered angle, not ahead, until :data:`READY`
      readings in a row have fallen within the gate.

    It keeps each link's tracks; the seas are the environment's (a batch of its links, or one replica's: the
    replicas share their seas).
    """

    name = "kalman_tracker"
    GATE, FLOOR, MEMORY, READY = tracks.GATE, tracks.FLOOR, tracks.MEMORY, tracks.READY

    def __init__(self, env, config=None):
        super().__init__(env, config)
        self.tracks: tracks.Tracks | None = None  # [n, 2 ends, 2 components]
        self.model = tracks.TrackModel.of(self.env.config)

    def _rows(self, rows: int):
        """The seas of this controller's ``rows`` links: its environment's batch, or one replica's (the replicas
        share their seas)."""
        sea, batch = self.env.surface.harmonics, self.env.batch_size[0]
        if rows not in (batch, batch // self.env.config.replicas):
            raise ValueError(f"kalman_tracker acts on its environment's {batch} links or one replica's, not {rows}")
        return type(sea)(*(each[:rows] for each in sea))

    def directions(self, tensordict):
        tracker = torch.stack(super().directions(tensordict), 1)  # [n, 2, 3]
        reading = tracker[..., :2].double()
        observation, part = tensordict.get("observation"), self.env.observation_part
        seen = torch.stack((part(observation, "beacon_valid")[:, 0], part(observation, "spot_valid")[:, 0]), 1) > 0.5
        parked = torch.stack((parked_reading(self.env, observation, 0),
                              parked_reading(self.env, observation, self.config.latency_steps)), 1)  # fmt: skip
        usable = (seen & ~parked).unsqueeze(-1).expand_as(reading)
        noise = torch.tensor([self.config.beacon_noise_rad, self.config.spot_noise_rad], dtype=torch.float64)
        variance = noise.clamp(min=self.FLOOR).square().to(reading.device).view(1, 2, 1).expand_as(reading)
        optics, sea = self.env.optics, self._rows(reading.shape[0])  # this episode's seas
        if self.tracks is None or self.tracks.last.shape != reading.shape:
            self.tracks = tracks.begin(reading, sea, optics.n_air, optics.n_water, self.model)
            usable = torch.zeros_like(usable)
        acceleration, rate = tracks.variances(reading, sea, optics.n_air, optics.n_water, self.model)
        self.tracks = self.tracks._replace(acceleration=acceleration, rate=rate)
        starting = parked.unsqueeze(-1).expand_as(reading)  # an episode's start: its sea is a new one
        self.tracks = tracks.follow(self.tracks, reading, variance, usable, starting, self.env.config.dt)
        leads = torch.tensor(self.model.leads(self.config.latency_steps), dtype=torch.float64)
        tilt = tracks.aim(self.tracks, leads.to(reading.device).view(1, 2, 1)).to(tracker.dtype)
        return pointing(tilt[:, 0], up=True), pointing(tilt[:, 1], up=False)


class AoATracker(PointingPolicy):
    """Quadrant-detector back-projection (angle of arrival).

    Assumes a quadrant detector or camera behind the receiver optics that reads the spot (the
    incoming direction in the receiver frame) with the boresight it was read with, both reaching
    the controller in the same packet, and the nominal positions T and R.

    * Receiver: boresight along the measured incoming direction (from R toward the surface point).
    * Transmitter: the incoming ray, back-projected from R to the mean sea level z = 0, gives a
      point P0; the transmitter points at P0 (the wave height at the true point is unknown). P0 is as far off
      as R is: a hovering drone's drift, which no controller knows, moves it by as much (docs/results.md, S1).
    * No reading (``spot_valid`` 0: no light, or below the detector threshold), or only the one read
      with the gimbals parked upright at the reset (acquisition: the first ``latency_steps + 1``
      decisions): flat-sea Snell. With the beam aimed away from the path, the centroid of the light
      on the detector leans toward the beam's axis, and its back-projection with it.
    """

    name = "aoa_tracker"
    required_extras = ("spot", "spot_valid")

    def directions(self, tensordict):
        flat_tx, flat_rx = FlatSeaSnell.directions(self, tensordict)
        observation = tensordict.get("observation")
        boresight = self.env.observation_part(observation, "rx_pointing")
        spot = self.env.observation_part(observation, "spot")
        parked = parked_reading(self.env, observation, self.config.latency_steps)
        seen = (self.env.observation_part(observation, "spot_valid")[:, 0] > 0.5) & ~parked
        tx, rx = tensordict.get("tx_position"), tensordict.get("rx_position")
        return back_projection(boresight, spot, seen, tx, rx, (flat_tx, flat_rx), self.env.optics.half_fov)


NOISY_SMOOTHING = 0.1
"""The intensity dither's share of each new fit with a noisy intensity: about ten fits averaged. With the
realistic sensor on the measured-slope sea and the full channel (16 links × 200 steps, 4/12/20 m/s at 10 %,
12 m/s at 50 %) it lifts the dither from 0.73–0.80 of the bound (every fit as it is) to 0.88–0.89."""


class IntensityDither(PointingPolicy):
    """Intensity-only beam triangulation for the transmitter; the receiver at flat-sea Snell.

    Assumes only the measured intensity and the pointing it was measured with (one packet), the
    nominal positions T and R, and the beam divergence ω_D from the laser's datasheet (each link's own, the
    ``divergence`` key).

    A Gaussian beam gives ln I = c − 2 |v − v*|² / ω_D² around the best tilt v*, which is linear in
    (c', v*) once |v|² is moved left: three probes determine it exactly. Each step fits v* through
    the last three (tilt, intensity) probes and points at v* plus a dither of ``radius`` × ω_D on a
    triangle that turns by 120° per step, so the next three probes stay well conditioned. Where a
    probe saw less than ``min_intensity``, or the fit is ill-conditioned or lands more than
    ``max_offset`` (tilt) from flat-sea Snell, it starts again from flat-sea Snell (acquisition).
    The reading of the gimbals parked at the reset (the first ``latency_steps + 1`` decisions) is no
    probe: it lies far from the dither's triangle, where the beam is no longer the fit's Gaussian.
    The controller keeps its last probes per link; a link whose time reads 0 starts afresh.

    With a noisy intensity reading a single fit chases the noise and the sea's own fluctuation from one
    probe to the next: the fits' offset from flat-sea Snell is then averaged exponentially, a share
    ``smoothing`` of each new fit (default :data:`NOISY_SMOOTHING` where the sensor is noisy, 1 where it
    is not; docs/environment.md, "Classical controllers", has the measurements).
    """

    name = "intensity_dither"
    required_extras = ()
    PROBES = 3

    def __init__(
        self,
        env,
        radius: float = 0.12,
        min_intensity: float = 1e-3,
        max_offset: float = 0.15,
        smoothing: float | None = None,
        config=None,
    ):
        super().__init__(env, config)
        self.radius, self.min_intensity, self.max_offset = radius, min_intensity, max_offset
        noisy = self.config.intensity_noise > 0 or self.config.intensity_noise_floor > 0
        self.smoothing = smoothing if smoothing is not None else (NOISY_SMOOTHING if noisy else 1.0)
        self.offset: torch.Tensor | None = None  # [n, 2]: the smoothed fit's tilt from flat-sea Snell
        self.probes: torch.Tensor | None = None  # [n, PROBES, 3]: tilt x, tilt y, ln I (newest first)
        self.count: torch.Tensor | None = None  # [n]: probes held
        self.turn: torch.Tensor | None = None  # [n]: dither step

    def directions(self, tensordict):
        flat_tx, flat_rx = FlatSeaSnell.directions(self, tensordict)
        observation = tensordict.get("observation")
        tilt = self.env.observation_part(observation, "tx_pointing")[:, :2]
        intensity = intensity_from_feature(self.env.observation_part(observation, "intensity")[:, 0])
        fresh = self.env.observation_part(observation, "time")[:, 0] == 0
        self._remember(tilt, intensity, fresh, parked_reading(self.env, observation, self.config.latency_steps))
        flat_tilt = flat_tx[:, :2]
        divergence = tensordict.get("divergence").double()  # [n] float64: what is derived from it, as from a float
        best, usable = self._fit(flat_tilt, divergence)
        if self.smoothing == 1.0:  # each step's fit as it is
            target = torch.where(usable.unsqueeze(-1), best, flat_tilt)
        else:  # the fits' offset from flat-sea Snell, averaged over about 1/smoothing steps
            fitted = torch.where(usable.unsqueeze(-1), best - flat_tilt, torch.zeros_like(flat_tilt))
            if self.offset is None or self.offset.shape != fitted.shape:
                self.offset = torch.zeros_like(fitted)
            moved = self.offset + self.smoothing * (fitted - self.offset)
            self.offset = torch.where((self.count == 0).unsqueeze(-1), fitted, moved)
            target = flat_tilt + self.offset
        angle = 2.0 * math.pi * (self.turn % self.PROBES) / self.PROBES
        turn = torch.stack((torch.cos(angle), torch.sin(angle)), -1)
        dither = per_link(self.radius * divergence, turn) * turn
        self.turn = self.turn + 1
        tx_tilt = target + dither.to(target.dtype)
        vertical = torch.sqrt((1.0 - (tx_tilt**2).sum(-1, keepdim=True)).clamp(min=0.0))
        return torch.cat((tx_tilt, vertical), dim=-1), flat_rx

    def _remember(self, tilt: torch.Tensor, intensity: torch.Tensor, fresh: torch.Tensor, parked: torch.Tensor) -> None:
        """Add this step's probe; links at their first step (or a new batch) forget older ones, and a reading
        of the ``parked`` gimbals counts as no light."""
        rows = tilt.shape[0]
        if self.probes is None or self.probes.shape[0] != rows:
            self.probes = torch.zeros(rows, self.PROBES, 3, dtype=tilt.dtype, device=tilt.device)
            self.count = torch.zeros(rows, dtype=torch.long, device=tilt.device)
            self.turn = torch.zeros(rows, dtype=torch.long, device=tilt.device)
        self.count = torch.where(fresh, torch.zeros_like(self.count), self.count)
        self.turn = torch.where(fresh, torch.zeros_like(self.turn), self.turn)
        probe = torch.cat((tilt, torch.log(intensity.clamp(min=1e-12)).unsqueeze(-1)), dim=-1)
        self.probes = torch.cat((probe.unsqueeze(1), self.probes[:, :-1]), dim=1)
        lit = (intensity >= self.min_intensity) & ~parked
        self.count = torch.where(lit, (self.count + 1).clamp(max=self.PROBES), torch.zeros_like(self.count))

    def _fit(self, flat_tilt: torch.Tensor, divergence: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """v* of the Gaussian through the held probes ``[n, 2]``, and where that fit is usable ``[n]``, for each
        link's ω_D ``[n]`` (float64). Solved in float64: at 5 mrad the system's tilt columns are about 4·10⁴ and
        differ between probes by about 10², so float32 lost the fit's last digits (6·10⁻⁴ ω_D of error) and, for
        probes on a line, the test of the determinant below (its rounding exceeded the threshold)."""
        scale = 4.0 / divergence**2
        probes = self.probes.double()
        tilt, log_intensity = probes[..., :2], probes[..., 2]
        system = torch.cat((torch.ones_like(log_intensity).unsqueeze(-1), per_link(scale, tilt) * tilt), dim=-1)
        rhs = log_intensity + per_link(0.5 * scale, tilt[..., 0]) * (tilt**2).sum(-1)
        determinant = torch.linalg.det(system)
        # 1 % of the determinant of the dither triangle itself: probes closer to a line are ignored.
        conditioned = determinant.abs() > per_link(0.01 * (scale * self.radius * divergence) ** 2, determinant)
        eye = torch.eye(3, dtype=system.dtype, device=system.device)
        solution, singular = torch.linalg.solve_ex(system + (~conditioned).to(system.dtype)[:, None, None] * eye, rhs)
        best = solution[:, 1:].to(flat_tilt.dtype)
        near = torch.linalg.vector_norm(best - flat_tilt, dim=-1) <= self.max_offset
        fitted = conditioned & (singular == 0) & near & torch.isfinite(best).all(-1)
        return best, (self.count >= self.PROBES) & fitted


def parked_reading(env, observation: torch.Tensor, latency_steps: int) -> torch.Tensor:
    """Whether each link's reading in ``observation`` ``[n]`` is the one read with the gimbals parked at the
    reset (:func:`waterair.envs.sensors.read_parked`), from the episode time the observation carries: the drone's
    readings, ``latency_steps`` late (the controller's replica's), or the beacon's (0: it is never late)."""
    steps = torch.round(env.observation_part(observation, "time")[:, 0] * env.config.max_steps)
    return read_parked(steps, latency_steps)


CONTROLLERS = {cls.name: cls for cls in (BeaconTracker, BeaconPredictor, KalmanTracker, AoATracker, IntensityDither)}
"""Classical controllers by name, the one that senses more first (of two that sense alike, the simpler)."""


def controller_for(observation_extras) -> str:
    """The name of the best classical controller a policy with these observation parts can be
    compared with: the first of :data:`CONTROLLERS` whose ``required_extras`` it has."""
    return next(name for name, cls in CONTROLLERS.items() if set(cls.required_extras) <= set(observation_extras))
