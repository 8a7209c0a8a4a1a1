"""The environment step's data by name (:mod:`waterair.envs.kernel`): the state of B links that a step reads and
writes, the gimbals an action moves, the sensors' readings and the packet they travel in, the true measurement,
and what a step gives back.

Frozen dataclasses and named tuples of tensors, each ``[B, ...]``: ``torch.compile`` traces them as it traces
dicts and tuples, so the step stays one graph, its batch dimension symbolic by the same source names
(``L['state']...``, :data:`waterair.envs.stepper.BATCH_SOURCES`), and an entry a step leaves as it was comes back as
the same tensor.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import NamedTuple

import torch

from waterair.envs import tracks
from waterair.envs.sensors import packet_sizes
from waterair.physics.actuator import DRIVE_WIDTH
from waterair.physics.motion import MOTION_WIDTH
from waterair.physics.paths import Iterate
from waterair.physics.surface import Harmonics


class Tilts(NamedTuple):
    """The tilt vectors pointed at (v_x, v_y) of the transmitter and the receiver, ``[B, 2]`` each."""

    tx_tilt: torch.Tensor
    rx_tilt: torch.Tensor


class Placement(NamedTuple):
    """Where moving ends are at a step (:mod:`waterair.envs.platforms`): the true T, R and calm-sea point ``[B, 3]``
    each, what the controllers know of them (``known`` ``[B, 3, 3]``: T, R and their calm-sea point), and each end's
    true and inertially read attitude (``attitude`` ``[B, 8]``: tx roll, pitch, its reading's, then rx's), and the
    motion's state then (``motion`` ``[B, MOTION_WIDTH]``)."""

    tx_position: torch.Tensor
    rx_position: torch.Tensor
    flat_point: torch.Tensor
    known: torch.Tensor
    attitude: torch.Tensor
    motion: torch.Tensor


class Moved(NamedTuple):
    """The ends, the action history and the clock after an action (:func:`waterair.envs.kernel.advance`): the
    tilts pointed at ``[B, 2]`` (as the ends' controllers know them), the last actions ``[B, history_length, 4]``,
    newest first, the time (s) and the steps since the reset (int64), ``[B]`` each, the tilts commanded ``[B, 4]``
    and the actuators' drive state ``[B, 4, DRIVE_WIDTH]`` (:class:`StepState`); where the ends move
    (``env.motion``), where they are (``placed``) and the tilts they point at in the world ``[B, 4]`` (``world``),
    None on a still link, where the world's are the known ones."""

    tx_tilt: torch.Tensor
    rx_tilt: torch.Tensor
    action_history: torch.Tensor
    time: torch.Tensor
    steps: torch.Tensor
    command: torch.Tensor
    drive: torch.Tensor
    placed: Placement | None = None
    world: torch.Tensor | None = None

    @property
    def tilts(self) -> Tilts:
        return Tilts(self.tx_tilt, self.rx_tilt)

    @property
    def world_tilts(self) -> Tilts:
        """The tilts the ends point at in the world: the light's."""
        return self.tilts if self.world is None else Tilts(self.world[:, :2], self.world[:, 2:])


@dataclass(frozen=True)
class StepState:
    """Everything a step reads of B links and everything it changes; nothing in the kernel keeps state.

    Attributes:
        sea: the links' resolved seas (the environment's surface).
        time, steps: the time (s) and the steps since the reset (int64), ``[B]``.
        tx_tilt, rx_tilt: the tilt vectors each end points at ``[B, 2]``.
        command: the tilts commanded (tx_vx, tx_vy, rx_vx, rx_vy) ``[B, 4]``: where the ends point, without
            actuators (``env.actuator.kind=ideal``).
        drive: each axis's actuator state ``[B, 4, DRIVE_WIDTH]`` (the axes of ``command``; the gimbal's angle and
            rate, the mirror's, from the mount: :mod:`waterair.envs.drives`); zeros without actuators.
        tx_position, rx_position: T and R (m) ``[B, 3]``.
        divergence: each link's ω_D (rad) ``[B]``, drawn at its reset, float64: as exact as the configuration's
            float, the gains take what they derive from it in float64 (optics.per_link).
        point, previous_point: the last two path points (m) ``[B, 3]``, from which the next is predicted.
        flat_point: the calm-sea path point (m) ``[B, 3]``; reference_gain: G_0 (1/m²) ``[B]``.
        history: the previous measured intensity features ``[B, history_length]``, newest first;
            last_feature: the newest ``[B]``.
        action_history: the last actions ``[B, history_length, 4]``, newest first.
        packets: the packets in flight ``[B, latency_steps + 1, width]``, newest first; the controller sees the last
            (the beacon's parts: the first).
        base_tilt: the residual base controller's tilts ``[B, 4]`` for the next action, from this state (computed
            once, where a step concludes or the environment resets, and read by the next step's actions).
        tracks: each end's Kalman tracks ``[B, 2, 2, tracks.WIDTH]`` (:meth:`waterair.envs.tracks.Tracks.packed`)
            where a residual base follows them (``kalman_tracker``), updated where a step concludes; else ``[B, 0]``.
        prepared: the channel's per-episode constants, a named tuple (``ChannelModel.Prepared``) of ``[B, ...]``.
        home, known, motion: where the ends move (``env.motion``; zeros otherwise): each link's T and R as its
            reset drew them and the drone's transit velocity ``[B, 3, 3]``; T, R and their calm-sea point as the
            controllers know them now ``[B, 3, 3]``; the drift's, the attitudes' and the inertial errors' state
            ``[B, MOTION_WIDTH]`` (:func:`waterair.physics.motion.motion_step`). ``tx_position``, ``rx_position``
            and ``flat_point`` are the true ones.
    """

    sea: Harmonics
    time: torch.Tensor
    steps: torch.Tensor
    tx_tilt: torch.Tensor
    rx_tilt: torch.Tensor
    command: torch.Tensor
    drive: torch.Tensor
    tx_position: torch.Tensor
    rx_position: torch.Tensor
    divergence: torch.Tensor
    point: torch.Tensor
    previous_point: torch.Tensor
    flat_point: torch.Tensor
    reference_gain: torch.Tensor
    history: torch.Tensor
    last_feature: torch.Tensor
    action_history: torch.Tensor
    packets: torch.Tensor
    base_tilt: torch.Tensor
    tracks: torch.Tensor
    prepared: tuple
    home: torch.Tensor
    known: torch.Tensor
    motion: torch.Tensor

    @classmethod
    def zeros(
        cls, sea: Harmonics, prepared: tuple, history_length: int, latency_steps: int, tracking: bool = False
    ) -> StepState:
        """A state of zeros for the links of ``sea`` (their number, device and float dtype), with room for
        ``history_length`` features and actions, ``latency_steps + 1`` packets in flight, the channel's
        ``prepared`` constants (one link's worth of each is their shape) and, where ``tracking``, the Kalman
        tracks."""
        batch, dtype, device = sea.omega.shape[0], sea.omega.dtype, sea.omega.device

        def zeros(*shape: int, kind: torch.dtype = dtype) -> torch.Tensor:
            return torch.zeros(batch, *shape, dtype=kind, device=device)

        return cls(
            sea=sea,
            time=zeros(),
            steps=zeros(kind=torch.int64),
            tx_tilt=zeros(2),
            rx_tilt=zeros(2),
            command=zeros(4),
            drive=zeros(4, DRIVE_WIDTH),
            tx_position=zeros(3),
            rx_position=zeros(3),
            divergence=zeros(kind=torch.float64),
            point=zeros(3),
            previous_point=zeros(3),
            flat_point=zeros(3),
            reference_gain=zeros(),
            history=zeros(history_length),
            last_feature=zeros(),
            action_history=zeros(history_length, 4),
            packets=zeros(latency_steps + 1, sum(packet_sizes(history_length))),
            base_tilt=zeros(4),
            tracks=zeros(2, 2, tracks.WIDTH) if tracking else zeros(0),
            prepared=type(prepared)(*(zeros(*value.shape[1:]) for value in prepared)),
            home=zeros(3, 3),
            known=zeros(3, 3),
            motion=zeros(MOTION_WIDTH),
        )

    def placed(self, moved: Moved) -> StepState:
        """This state with its ends where they are after ``moved`` (as it is where they stand still)."""
        at = moved.placed
        if at is None:
            return self
        return replace(self, tx_position=at.tx_position, rx_position=at.rx_position, flat_point=at.flat_point,
                       known=at.known, motion=at.motion)  # fmt: skip

    def after(self, moved: Moved, **changes: torch.Tensor) -> StepState:
        """This state with the gimbals and the clock ``moved`` (and the ends, where they move: :meth:`placed`) and
        the entries ``changes`` replaced."""
        return replace(
            self.placed(moved),
            tx_tilt=moved.tx_tilt,
            rx_tilt=moved.rx_tilt,
            command=moved.command,
            drive=moved.drive,
            action_history=moved.action_history,
            time=moved.time,
            steps=moved.steps,
            **changes,
        )

    def write_rows(self, rows: torch.Tensor, links: StepState) -> None:
        """Write the state of ``links`` into the rows ``rows`` ``[n]`` of this one, in place: every entry, the
        channel's constants included, but the seas (the environment's surface holds them)."""
        for field in fields(self):
            mine, theirs = getattr(self, field.name), getattr(links, field.name)
            if field.name == "prepared":
                for constant, value in zip(mine, theirs, strict=True):
                    constant[rows] = value
            elif field.name != "sea":
                mine[rows] = theirs


class Readings(NamedTuple):
    """One step's sensor readings, in the order they travel (:data:`waterair.envs.sensors.PACKET_PARTS`): both
    pointings (unit, ``[n, 3]``), the intensity feature ``[n, 1]``, the spot ``[n, 2]`` and its validity ``[n, 1]``,
    the beacon reading ``[n, 2]`` and its validity ``[n, 1]``."""

    tx_pointing: torch.Tensor
    rx_pointing: torch.Tensor
    intensity: torch.Tensor
    spot: torch.Tensor
    spot_valid: torch.Tensor
    beacon: torch.Tensor
    beacon_valid: torch.Tensor


class Packet(NamedTuple):
    """A packet as delivered: the :class:`Readings` and the intensity history ``[n, history_length]`` read with
    them (the parts of :data:`waterair.envs.sensors.PACKET_PARTS`, in order)."""

    readings: Readings
    history: torch.Tensor


class Measurement(NamedTuple):
    """The true values each step reports beside the observation, ``[B]`` unless noted: G (1/m²), G_UB, the
    intensity I = G / G_0, whether the path is valid, α_D and α_A (rad), and the path's unit departure and
    arrival ``[B, 3]``."""

    gain: torch.Tensor
    gain_upper_bound: torch.Tensor
    intensity: torch.Tensor
    path_valid: torch.Tensor
    alpha_d: torch.Tensor
    alpha_a: torch.Tensor
    departure: torch.Tensor
    arrival: torch.Tensor


class Outputs(NamedTuple):
    """What a step reports: the true ``measurement``, the ``observation`` (every part: ``kernel.observe``), the
    ``reward`` and ``truncated`` ``[B, 1]``, and the residual base controller's tilts for the next action
    ``base_tilt`` ``[B, 4]``."""

    measurement: Measurement
    observation: torch.Tensor
    reward: torch.Tensor
    truncated: torch.Tensor
    base_tilt: torch.Tensor


class StepResult(NamedTuple):
    """A step of every link (:func:`waterair.envs.kernel.step`, ``finish``, ``conclude``): the new ``state``, its
    ``outputs``, the gimbals ``moved`` and the path ``solution`` it was concluded with (for finishing the links
    whose path has not converged)."""

    state: StepState
    outputs: Outputs
    moved: Moved
    solution: Iterate
