"""The numbers of one environment configuration that the step uses (:class:`StepConstants`), as the
kernel (:mod:`waterair.envs.kernel`) takes them: plain Python values, each link's own beam divergence put in
per step (:meth:`StepConstants.for_links`), and the copy a compiled step takes (:meth:`StepConstants.traced`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import NamedTuple

import torch

from waterair.envs.config import EnvConfig
from waterair.envs.rewards import Reward
from waterair.envs.sensors import Sensor
from waterair.envs.tracks import TRACKED_BASE, TrackModel
from waterair.physics.actuator import Actuator
from waterair.physics.channel import Beacon, ChannelModel, Transceiver
from waterair.physics.motion import Motion
from waterair.physics.optics import traced
from waterair.physics.paths import FixedNewtonOptions


class Actions(NamedTuple):
    """How an action turns into tilts (docs/environment.md, "Interface"): ``mode`` (``env.action_mode``), ``residual``
    sin(``env.residual_deg``), ``base`` (``env.residual_base``), ``beams`` (``env.residual_beams``), and whether the
    tilts go through the ends' actuators (``env.actuated``)."""

    mode: str
    residual: float
    base: str
    beams: float | None
    actuated: bool = True

    @classmethod
    def of(cls, config: EnvConfig) -> Actions:
        return cls(config.action_mode, math.sin(math.radians(config.residual_deg)), config.residual_base,
                   config.residual_beams, config.actuated)  # fmt: skip

    def traced(self, device: torch.device, dtype: torch.dtype) -> Actions:
        """With the residual's range as one-element tensors (:meth:`StepConstants.traced`; tensors only in the
        compiled step's copy)."""
        beams = None if self.beams is None else traced(self.beams, device, dtype)
        return self._replace(residual=traced(self.residual, device, dtype), beams=beams)  # type: ignore[arg-type]


@dataclass(frozen=True)
class StepConstants:
    """The numbers of one environment configuration that the step uses (all plain Python values)."""

    optics: Transceiver
    sensor: Sensor
    reward: Reward
    solver: FixedNewtonOptions
    tolerance: float
    actions: Actions
    """How the batch acts (where every replica acts alike)."""
    max_tilt: float
    slew_step: float
    dt: float
    episode_seconds: float
    max_steps: int
    vertical_distance: float
    channel: ChannelModel
    replicas: int = 1
    """The batch's copies of its links (``env.replicas``): the channel computes what does not depend on the
    pointing once per link of them."""
    beacon: Beacon | None = None
    """The drone's beacon where the step reads it (``EnvConfig.senses_beacon``); None: its reading stays 0."""
    replica_actions: tuple[Actions, ...] = ()
    """Where the replicas act differently (``env.replica_actions``): the distinct ways, and ``replica_choice``, which
    of them each replica takes; empty: every replica acts as ``actions`` says."""
    replica_choice: tuple[int, ...] = ()
    actuator: Actuator | None = None
    """The ends' actuators (``env.actuator``); None: none, the command is the pointing."""
    motion: Motion | None = None
    """How the ends move (``env.motion``); None: they stand still (``static``)."""
    motion_transitions: tuple = ()
    """Its oscillators' step (:meth:`Motion.transitions`), as floats: computed here, outside the step's graph."""
    tracks: TrackModel | None = None
    """Where a way of acting has ``kalman_tracker`` for its base (``env.residual_base``), what its tracks add to the sea
    and how far they point ahead (:class:`~waterair.envs.tracks.TrackModel`); None: the state keeps no tracks."""

    @classmethod
    def of(cls, config: EnvConfig, sensor: Sensor, reward: Reward, channel: ChannelModel) -> StepConstants:
        solver = FixedNewtonOptions(iterations=config.newton_iterations)
        each = [Actions.of(c) for c in config.replica_configs()]
        distinct = list(dict.fromkeys(each)) if len(set(each)) > 1 else []
        actions = each[0] if not distinct else Actions.of(config)  # every replica's way where they share one
        # the batch's base is read every step (its tilts are reported in every action mode), a replica's residually
        tracked = actions.base == TRACKED_BASE or any(a.mode == "residual" and a.base == TRACKED_BASE for a in each)
        return cls(
            optics=channel.optics,
            sensor=sensor,
            reward=reward,
            solver=solver,
            tolerance=solver.tolerance(getattr(torch, config.dtype)),
            actions=actions,
            max_tilt=config.max_tilt,
            slew_step=math.sin(math.radians(config.max_slew_deg_s * config.dt)),
            dt=config.dt,
            episode_seconds=config.episode_seconds,
            max_steps=config.max_steps,
            vertical_distance=config.geometry.tx_depth + config.geometry.rx_height,
            channel=channel,
            replicas=config.replicas,
            beacon=config.beacon if config.senses_beacon or tracked else None,  # the tracks follow the beacon
            replica_actions=tuple(distinct),
            replica_choice=tuple(distinct.index(a) for a in each) if distinct else (),
            actuator=config.actuator if config.actuator.moves and any(a.actuated for a in each) else None,
            motion=config.motion if config.motion.moves else None,
            motion_transitions=config.motion.transitions(config.dt) if config.motion.moves else (),
            tracks=TrackModel.of(config) if tracked else None,
        )

    def for_links(self, divergence: torch.Tensor, replica: torch.Tensor | None = None) -> StepConstants:
        """These constants for links with their own beam divergence ω_D ``[B]`` (rad; the state's): every gain
        the step computes and its misalignment read link b's for link b (:meth:`Transceiver.for_links`); where
        replicas sense differently, the sensor's settings each row's (:meth:`Sensor.at`), the rows of the
        replicas ``replica`` ``[B]`` (default: a whole batch, replica k's rows [k·n, (k+1)·n))."""
        optics = self.optics.for_links(divergence)
        sensor = self.sensor
        if sensor.replicas is not None:
            sensor = sensor.at(self.replica_of_rows(divergence) if replica is None else replica)
        return replace(self, optics=optics, channel=replace(self.channel, optics=optics), sensor=sensor)

    def replica_of_rows(self, like: torch.Tensor) -> torch.Tensor:
        """The replica of each row ``[B]`` (int64) of a whole batch shaped as ``like`` ``[B, ...]``."""
        return self.replica_of(torch.arange(like.shape[0], device=like.device), like.shape[0])

    def replica_of(self, rows: torch.Tensor, batch: int) -> torch.Tensor:
        """The replica of each of ``rows`` ``[n]`` (int64 indices into a batch of ``batch`` rows): replica k's rows
        are [k·m, (k+1)·m), m = ``batch`` / replicas."""
        return rows // (batch // self.replicas)

    def traced(self, device: torch.device, dtype: torch.dtype) -> StepConstants:
        """These constants as the compiled step takes them: the numbers that differ between an evaluation's
        environments as one-element tensors in ``dtype`` on ``device`` (:func:`~waterair.physics.optics.traced`):
        the sensor's noise levels and thresholds (:meth:`Sensor.traced`) and the residual's range (the beam
        divergence is each link's, from the state: :meth:`for_links`). A graph then serves every value of them,
        and is the same graph whichever value a process compiled first: a float would be compiled in, and
        compiled symbolic only once torch had seen it change (in that process, or in an earlier one of the same
        job), so the graphs, and the compile cache they could share between processes, depended on the order in
        which groups were run."""
        return replace(
            self,
            sensor=self.sensor.traced(device, dtype),
            actions=self.actions.traced(device, dtype),
            replica_actions=tuple(actions.traced(device, dtype) for actions in self.replica_actions),
        )
