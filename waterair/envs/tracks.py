"""Each end's Kalman track of its reading: the model ``kalman_tracker`` (:mod:`waterair.envs.controllers`) and the
``kalman_tracker`` residual base (:mod:`waterair.envs.kernel`) both run, one step of it in one place
(docs/environment.md, "Classical controllers").

A link's tracks are ``[..., 2 ends, 2 components]`` of :class:`Tracks`: each component of an end's reading (its
``beacon_tracker`` tilt, v_x or v_y) filtered as an angle and its rate (:mod:`waterair.envs.kalman`) under white
acceleration of the variance its link's sea (and the drone's motion) gives the direction of its light, pointed
ahead over the delay between the reading and the pointing it sets along the share of the rate that carried over.
Everything here is elementwise over the leading dimensions, in the tracks' dtype.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import torch

from waterair.envs import kalman
from waterair.physics.surface import Harmonics

TRACKED_BASE = "kalman_tracker"
"""The residual base (``env.residual_base``) that points along the tracks the environment's state keeps."""
GATE = 4.0
"""A reading beyond this many standard deviations of its innovation starts its track again (the centroid
jumping between refraction points)."""
FLOOR = 1e-4
"""The smallest reading noise (rad) assumed: the detectors' resolution, where the sensor model has none."""
MEMORY = 4.0
"""The time (s) over which the share of the rate that carries over fades (a few wave periods)."""
READY = 3
"""The readings in a row within the gate a track takes before it points ahead: the rate of a track started by a
jump comes from the jump's end, and pointed along at once it set the held rate's tail where the drone stands
still (docs/results.md, "S6 and S7")."""
WIDTH = 12
"""The numbers a track keeps (:meth:`Tracks.packed`)."""


class Tracks(NamedTuple):
    """Each end's tracks ``[..., 2, 2]`` (ends, components): the filter's ``track``; the rate's share that carried
    over (``carried``); the ``last`` reading; the readings in a row within the gate, up to :data:`READY`
    (``held``, 0 where the last reading started the track again or was not used); the white acceleration's and
    the starting rate's variances of the link's light (``acceleration``, ``rate``; rad²/s⁴, rad²/s²)."""

    track: kalman.Track
    carried: kalman.Carry
    last: torch.Tensor
    held: torch.Tensor
    acceleration: torch.Tensor
    rate: torch.Tensor

    def packed(self) -> torch.Tensor:
        """As one tensor ``[..., WIDTH]``, as the environment's state keeps it."""
        return torch.cat((self.track.state, self.track.covariance.flatten(-2),
                          torch.stack((*self.carried, self.last, self.held, self.acceleration, self.rate), -1)),
                         -1)  # fmt: skip

    @classmethod
    def unpacked(cls, packed: torch.Tensor) -> Tracks:
        """:meth:`packed`'s inverse."""
        state, covariance, rest = packed.split((2, 4, 6), dim=-1)
        moved, foretold, last, held, acceleration, rate = rest.unbind(-1)
        track = kalman.Track(state, covariance.unflatten(-1, (2, 2)))
        return cls(track, kalman.Carry(moved, foretold), last, held, acceleration, rate)


class TrackModel(NamedTuple):
    """What a configuration adds to the sea's share of the tracks' variances, and the pointing's delay, as plain
    floats: the drone's motion's white acceleration and starting rate variances at each end (:func:`motion_terms`),
    the actuators' lag (s; ``Actuator.lag``) and the step Δt (s)."""

    motion_acceleration: tuple[float, float]
    motion_rate: tuple[float, float]
    lag: float
    dt: float

    @classmethod
    def of(cls, config) -> TrackModel:
        """The model of an :class:`~waterair.envs.config.EnvConfig`."""
        acceleration, rate = motion_terms(config)
        return cls(acceleration, rate, config.actuator.lag(config.dt), config.dt)

    def leads(self, latency_steps) -> tuple:
        """How far (s) each end points ahead of its reading: one step at the transmitter, ``latency_steps`` + 1 at
        the receiver (its reading comes over the return link), each plus the actuators' lag."""
        if isinstance(latency_steps, torch.Tensor):  # each row's (int64): in float64, as the floats are
            latency_steps = latency_steps.to(torch.float64)
        return self.dt + self.lag, self.dt * (latency_steps + 1) + self.lag


def motion_terms(config) -> tuple[tuple[float, float], tuple[float, float]]:
    """What the drone's own motion (``env.motion``; none where the ends stand still) adds to each end's white
    acceleration and starting rate variances: a horizontal move of the drone turns each end's calm-sea direction
    by n_a (tx) or n_w (rx) over n_w h + n_a d per metre (small angles); the drift's rate variance ω² σ² and its
    oscillator's driving intensity 4 ζ ω³ σ² over a step, and the transit's speed², through those gains."""
    motion, geometry, optics = config.motion, config.geometry, config.optics
    if not motion.moves:
        return (0.0, 0.0), (0.0, 0.0)
    across = optics.n_water * geometry.rx_height + optics.n_air * geometry.tx_depth
    gains = (optics.n_air / across, optics.n_water / across)
    omega, sigma = 2.0 * math.pi / motion.drift_period, motion.drift_horizontal
    speed = motion.transit_speed if motion.kind == "transit" else 0.0
    acceleration = 4.0 * motion.drift_damping * omega**3 * sigma**2 / config.dt
    rate = (omega * sigma) ** 2 + speed**2
    return tuple(g * g * acceleration for g in gains), tuple(g * g * rate for g in gains)  # type: ignore[return-value]


def sea_variances(sea: Harmonics, n_air: float, n_water: float) -> tuple[torch.Tensor, torch.Tensor]:
    """The white acceleration's and the starting rate's variances ``[B, 2, 2]`` (links, ends, components) of the
    direction of each end's light on each link's sea ``[B, K]``, in float64: the slope's acceleration
    Σ a² k_c² ω⁴ / 2 per component c, and its rate's Σ a² k_c² ω² / 2, times the square of the share of a slope
    the refracted light turns by (1 − n_air/n_water at the transmitter, n_water/n_air − 1 at the receiver)."""
    slope = sea.amplitude.double().square().unsqueeze(-1) * torch.stack((sea.kx, sea.ky), -1).double().square()
    omega = sea.omega.double().unsqueeze(-1)
    share = torch.tensor([1 - n_air / n_water, n_water / n_air - 1], dtype=torch.float64, device=omega.device)
    share = share.square().view(1, 2, 1)
    return share * ((slope * omega**4).sum(1) / 2).unsqueeze(1), share * ((slope * omega**2).sum(1) / 2).unsqueeze(1)


def variances(reading: torch.Tensor, sea: Harmonics, n_air: float, n_water: float, model: TrackModel):
    """The white acceleration's and the starting rate's variances of each end's light ``[B, 2, 2]``, shaped and typed
    as ``reading``: :func:`sea_variances` on the links' seas ``sea`` plus what ``model`` says the motion adds."""
    sea_terms = sea_variances(sea, n_air, n_water)
    motion = [torch.tensor(each, dtype=torch.float64, device=reading.device).view(1, 2, 1) for each in model[:2]]
    together = zip(sea_terms, motion, strict=True)
    return tuple((each + more).to(reading.dtype).expand_as(reading) for each, more in together)


def begin(reading: torch.Tensor, sea: Harmonics, n_air: float, n_water: float, model: TrackModel) -> Tracks:
    """Tracks ``[B, 2, 2]`` before an episode's first reading ``reading`` (its ``last``), on the seas ``sea``, in
    ``reading``'s dtype: at rest, none of the rate carried over (one step's weight of it foretold), none held."""
    acceleration, rate = variances(reading, sea, n_air, n_water, model)
    zero = torch.zeros_like(reading)
    track = kalman.begin(zero, zero, zero)
    return Tracks(track, kalman.Carry(zero, rate * model.dt * model.dt), reading, zero, acceleration, rate)


def follow(tracks: Tracks, reading: torch.Tensor, variance: torch.Tensor, usable: torch.Tensor,
           starting: torch.Tensor, dt: float) -> Tracks:  # fmt: skip
    """``tracks`` after a step's ``reading`` of the given ``variance`` (rad²); ``usable`` where the reading is
    seen and was not read with the gimbals parked, ``starting`` where the episode starts (its sea is a new one:
    nothing of the rate carried over). A reading not usable, or outside the :data:`GATE`, starts its end's
    track again from it (both components of an end are tracked together)."""
    fresh = kalman.begin(reading, variance, tracks.rate)
    prior = kalman.Carry(torch.zeros_like(tracks.rate), tracks.rate * dt * dt)  # one step's weight, none carried
    carried = kalman.Carry(*(torch.where(starting, p, c) for p, c in zip(prior, tracks.carried, strict=True)))
    predicted = kalman.predict(tracks.track, dt, tracks.acceleration)
    updated, inside = kalman.update(predicted, reading, variance, GATE)
    tracking = (usable & inside).all(-1, keepdim=True).expand_as(reading)
    foretold = torch.where(tracking, tracks.track.state[..., 1] * dt, torch.zeros_like(reading))  # a fresh one's: 0
    carried = kalman.carry(carried, reading - tracks.last, foretold, math.exp(-dt / MEMORY))
    held = torch.where(tracking, (tracks.held + 1).clamp(max=READY), torch.zeros_like(tracks.held))
    track = kalman.choose(tracking, updated, fresh)
    return tracks._replace(track=track, carried=carried, last=reading, held=held)


def aim(tracks: Tracks, leads: torch.Tensor) -> torch.Tensor:
    """The tilts ``[..., 2, 2]`` each end points at: a tracked end (``held`` > 0) its filtered angle, ahead by
    ``leads`` ``[..., 2, 1]`` (s) along the estimated rate times the share that carried over once :data:`READY`
    readings in a row have held; an end whose track started again, its reading."""
    lead = leads * kalman.share(tracks.carried) * (tracks.held >= READY)
    return torch.where(tracks.held > 0, kalman.ahead(tracks.track, lead), tracks.last)
