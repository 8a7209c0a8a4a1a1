"""The environment step as pure tensor functions, so that ``torch.compile`` makes it one graph.

:func:`step` turns the state of B links and their actions into the next state and everything the
step reports: the gimbal update, the path solve (a fixed number of masked Newton iterations from a
prediction of the path point, :mod:`waterair.physics.paths.fixed`), the channel gain, the sensor
readings and their delay, the observation and the reward. It has no Python branches on data and no
host synchronisation. :class:`waterair.envs.env.WaterAirEnv` calls it compiled or eagerly (the same
function, so both give the same numbers to float rounding), then hands the rare links whose path
has not converged to the adaptive solver and redoes :func:`conclude` for them.

The channel is a :class:`~waterair.physics.channel.ChannelModel` held by the step's constants
(:class:`~waterair.envs.constants.StepConstants`): the step asks it for the light and reads it through it;
nothing here knows which model it is.
The state, the readings and what a step gives back are named and typed (:mod:`waterair.envs.state`); nothing here
keeps state.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import NamedTuple

import torch

from waterair.envs import bases, drives, platforms
from waterair.envs.config import OBSERVATION_EXTRAS, EnvConfig
from waterair.envs.constants import Actions, StepConstants
from waterair.envs.drives import limit_tilt
from waterair.envs.packets import deliver, pack
from waterair.envs.sensors import (
    SensorNoise,
    intensity_feature,
    read_parked,
    spot_position,
)
from waterair.envs.state import Measurement, Moved, Outputs, Packet, Readings, StepResult, StepState
from waterair.physics.channel import LightSamples, LinkEnds, pointing, read_beacon
from waterair.physics.optics import per_link
from waterair.physics.paths import FixedNewtonOptions, Iterate, PathSolution, finish_path, near_calm_point
from waterair.physics.paths.fixed import fixed_newton_terms

DIVERGENCE_SPAN = (0.005, 0.1)
"""The beam divergences (rad) the observation's ``divergence`` part reads as −1 and 1: it is linear in log ω_D."""


class Record(NamedTuple):
    """What a solved path and its light give (:func:`record`): the true ``measurement``, the sensors'
    ``readings``, the ``stored`` warm start ``[n, 3]``, whether the path's own point was stored (``tracked``
    ``[n]``) and the measured intensity ``feature`` ``[n]``."""

    measurement: Measurement
    readings: Readings
    stored: torch.Tensor
    tracked: torch.Tensor
    feature: torch.Tensor


def advance(c: StepConstants, state: StepState, action: torch.Tensor, noise: SensorNoise | None = None) -> Moved:
    """The ends' pointing (through their actuators, where they have them), the action history and the clock after
    ``action`` ``[B, 4]`` (already clipped to [-1, 1]); where the ends move, with the step's draws ``noise``."""
    return _advance(c.for_links(state.divergence), state, action, noise)


def _advance(c: StepConstants, state: StepState, action: torch.Tensor, noise: SensorNoise | None = None) -> Moved:
    """:func:`advance` with ``c`` already for the links (each row's latency, where replicas sense otherwise)."""
    actuated: torch.Tensor | None = None  # the rows whose tilts go through the actuators (None: every row)
    if c.replica_actions:  # replica k's rows [k·n, (k+1)·n) act its own way: each way on every row, then chosen
        ways = [aimed_tilts(c, actions, state, action) for actions in c.replica_actions]
        way = torch.tensor(c.replica_choice, device=action.device)[c.replica_of_rows(action)].unsqueeze(-1)
        tx, rx = ways[0]
        for index, (tx_k, rx_k) in enumerate(ways[1:], start=1):
            tx, rx = torch.where(way == index, tx_k, tx), torch.where(way == index, rx_k, rx)
        if not all(actions.actuated for actions in c.replica_actions):
            actuated = torch.tensor([a.actuated for a in c.replica_actions], device=action.device)[way]
    else:
        tx, rx = aimed_tilts(c, c.actions, state, action)
        if not c.actions.actuated:
            actuated = torch.zeros_like(action[:, :1], dtype=torch.bool)
    tx, rx = limit_tilt(tx, c.max_tilt), limit_tilt(rx, c.max_tilt)
    command, drive = torch.cat((tx, rx), dim=-1), state.drive
    time, steps = state.time + c.dt, state.steps + 1
    normals = None if noise is None else noise.motion
    pointed, drive, placed, world = drives.point(c, state, command, actuated, time, normals)
    return Moved(
        tx_tilt=pointed[:, :2].contiguous(),  # each end's own [B, 2], as the reset lays it: no stride guard fails
        rx_tilt=pointed[:, 2:].contiguous(),
        action_history=torch.cat((action.unsqueeze(1), state.action_history[:, :-1]), dim=1),
        time=time,
        steps=steps,
        command=command,
        drive=drive,
        placed=placed,
        world=world,
    )


def aimed_tilts(c: StepConstants, actions: Actions, state: StepState, action: torch.Tensor):
    """The tilts ``[B, 2]`` each of the transmitter and the receiver that ``action`` asks for, acting as
    ``actions`` says (:data:`ACTION_MODES`), before the tilt limit."""
    return ACTION_MODES[actions.mode](c, actions, state, action)


def absolute_tilts(c: StepConstants, actions: Actions, state: StepState, action: torch.Tensor):
    """``absolute``: the action is the tilt, in units of the largest."""
    return action[:, :2] * c.max_tilt, action[:, 2:] * c.max_tilt


def residual_tilts(c: StepConstants, actions: Actions, state: StepState, action: torch.Tensor):
    """``residual``: the base controller's tilts, corrected within each link's reach from the first reading
    taken with the controller's own pointing."""
    # the state holds the default base's tilts, as the last step (or reset) concluded them
    base = state.base_tilt if actions.base == c.actions.base else base_tilts(c, state, actions.base)
    tracking = ~read_parked(state.steps, c.sensor.latency_steps)
    reach = residual_reach(actions, state.divergence.to(action.dtype)) * tracking.to(action.dtype).unsqueeze(-1)
    return base[:, :2] + action[:, :2] * reach[:, :1], base[:, 2:] + action[:, 2:] * reach[:, 1:]


def delta_tilts(c: StepConstants, actions: Actions, state: StepState, action: torch.Tensor):
    """``delta``: the present commanded tilts moved by at most a step's slew."""
    return state.command[:, :2] + action[:, :2] * c.slew_step, state.command[:, 2:] + action[:, 2:] * c.slew_step


def residual_reach(actions: Actions, divergence: torch.Tensor) -> torch.Tensor:
    """The largest residual correction ``[n, 2]`` (a tilt's sine) of each link's transmitter and receiver, for
    its ω_D ``[n]``: sin(residual_deg), the transmitter's at most residual_beams · ω_D where that is set, so that
    a narrow beam's correction stays within a few of its widths (docs/environment.md, "Residual actions")."""
    reach = torch.full_like(divergence, 1.0) * actions.residual
    tx = reach if actions.beams is None else torch.minimum(actions.beams * divergence, reach)
    return torch.stack((tx, reach), dim=-1)


def base_tilts(
    c: StepConstants, state: StepState, base: str | None = None, delivered: Packet | None = None
) -> torch.Tensor:
    """The residual base controller's tilts ``[B, 4]`` for the next action (``base``, default ``env.residual_base``;
    :data:`~waterair.envs.bases.RESIDUAL_BASES`), from the packet ``delivered`` of ``state`` (default:
    :func:`deliver`'s)."""
    delivered = deliver(state.packets, c.sensor.latency_steps) if delivered is None else delivered
    return bases.RESIDUAL_BASES[base or c.actions.base](c, state, delivered.readings)


ACTION_MODES = {"absolute": absolute_tilts, "delta": delta_tilts, "residual": residual_tilts}
"""How an action moves the gimbals, by ``env.action_mode``: each ``f(c, actions, state, action)`` → both tilts."""


def predicted_point(state: StepState) -> torch.Tensor:
    """The next path point's (x, y) ``[B, 2]``, extrapolated from the last two (it moves smoothly)."""
    return 2.0 * state.point[:, :2] - state.previous_point[:, :2]


def solve(
    c: StepConstants, state: StepState, time: torch.Tensor, start=None, options: FixedNewtonOptions | None = None
) -> Iterate:
    """Masked Newton iterations (``options``, by default ``c.solver``) from ``start`` (default: the predicted
    point)."""
    return fixed_newton_terms(
        state.sea,
        predicted_point(state) if start is None else start,
        time,
        state.tx_position,
        state.rx_position,
        c.optics.indices,
        c.solver if options is None else options,
    )


def channel_light(
    c: StepConstants,
    state: StepState,
    path: PathSolution,
    moved: Moved,
    generator: torch.Generator | None = None,
    copies: int | None = None,
) -> LightSamples:
    """The channel's light for the links of ``state`` (their seas, ends and the channel's per-episode
    constants) through the tracked ``path``, at the time and transmitter pointing of the gimbals ``moved``;
    ``copies`` as :func:`record`'s (default ``c.replicas``)."""
    tx_dir = pointing(moved.world_tilts.tx_tilt, up=True)
    ends = LinkEnds(state.tx_position, state.rx_position, state.flat_point, tx_dir)
    copies = c.replicas if copies is None else copies
    return c.channel.light(state.sea, path, ends, moved.time, state.prepared, generator, copies=copies)


def record(
    c: StepConstants,
    moved: Moved,
    path: PathSolution,
    light: LightSamples,
    reference_gain,
    flat_point,
    noise,
    *,
    copies: int = 1,
) -> Record:
    """What a solved path and its ``light`` give: the true measurement, the sensor readings and the next warm
    start (:class:`Record`). An invalid path stores the calm-sea point, so that the next solve does not
    start from a lost one. ``copies``: the links are that many copies of the first B / copies (a step's
    ``c.replicas``; a reset of some links, 1). The light is received along the ends' pointing in the world, and
    each end reads its pointing as its controller knows it (``moved``'s).
    """
    world = moved.world_tilts
    tx_dir, rx_dir = pointing(world.tx_tilt, up=True), pointing(world.rx_tilt, up=False)
    received = c.channel.receive(light, tx_dir, rx_dir, copies=copies)
    intensity = received.gain / reference_gain
    measured = c.sensor.intensity(intensity, noise)
    seen = spot_position(received.spot_arrival, rx_dir, c.optics.half_fov)
    spot, spot_valid = c.sensor.spot(seen, received.lit, measured, noise)
    feature = intensity_feature(measured)
    beacon, beacon_valid = read_beacon_packet(c, light, tx_dir, rx_dir, reference_gain, noise)
    if moved.world is not None:
        tx_dir, rx_dir = pointing(moved.tx_tilt, up=True), pointing(moved.rx_tilt, up=False)
    readings = Readings(
        tx_pointing=tx_dir,
        rx_pointing=rx_dir,
        intensity=feature.unsqueeze(-1),
        spot=spot,
        spot_valid=spot_valid.unsqueeze(-1),
        beacon=beacon,
        beacon_valid=beacon_valid.unsqueeze(-1),
    )
    measurement = Measurement(
        gain=received.gain,
        gain_upper_bound=received.upper_bound,
        intensity=intensity,
        path_valid=received.valid,
        alpha_d=received.alpha_d,
        alpha_a=received.alpha_a,
        departure=received.departure,
        arrival=received.arrival,
    )
    tracked = path.valid if c.channel.needs_exact_point else near_calm_point(path, flat_point)
    stored = torch.where(tracked.unsqueeze(-1), path.point, flat_point)
    return Record(measurement, readings, stored, tracked, feature)


def read_beacon_packet(c: StepConstants, light: LightSamples, tx_dir, rx_dir, reference_gain, noise):
    """The transmitter's beacon reading ``[n, 2]`` (the incoming direction in the transmitter's frame over
    tan of the detector's half field of view) and its validity ``[n]``; both 0 where the step reads no beacon."""
    if c.beacon is None:
        zero = torch.zeros_like(tx_dir[:, 0])
        return torch.zeros_like(tx_dir[:, :2]), zero
    seen = read_beacon(c.channel.unpointed_light(light), tx_dir, rx_dir, c.beacon, c.optics)
    level = seen.gain / c.beacon.reference_gain(reference_gain, c.optics)
    true = spot_position(-seen.incoming, tx_dir, c.beacon.half_fov)
    return c.sensor.beacon(true, seen.lit, level, noise)


def conclude(
    c: StepConstants, state: StepState, moved: Moved, solution: Iterate, noise, light: LightSamples | None = None
) -> StepResult:
    """The new state and the step's outputs, given the gimbals ``moved`` and the path ``solution``. The
    channel's light is computed here unless it comes as ``light`` (a model that does not compile)."""
    return _conclude(c.for_links(state.divergence), state, moved, solution, noise, light)


def _conclude(c: StepConstants, state: StepState, moved: Moved, solution: Iterate, noise, light) -> StepResult:
    """:func:`conclude` with ``c`` already for the links."""
    state = state.placed(moved)
    tx, rx = state.tx_position, state.rx_position
    path = finish_path(solution, tx, rx, c.optics.indices)
    if light is None:
        light = channel_light(c, state, path, moved)
    measurement, readings, stored, tracked, feature = record(
        c, moved, path, light, state.reference_gain, state.flat_point, noise, copies=c.replicas
    )
    history = torch.cat((state.last_feature.unsqueeze(-1), state.history[:, :-1]), dim=-1)
    packets = torch.cat((pack(readings, history).unsqueeze(1), state.packets[:, :-1]), dim=1)
    new = state.after(
        moved,
        point=stored,
        previous_point=torch.where(tracked.unsqueeze(-1), state.point, stored),
        history=history,
        last_feature=feature,
        packets=packets,
    )
    delivered = deliver(new.packets, c.sensor.latency_steps)  # what the controller reads next, once
    new = replace(new, tracks=bases.followed(c, new, delivered.readings))
    new = replace(new, base_tilt=base_tilts(c, new, delivered=delivered))
    reward = c.reward(measurement.intensity, misalignment(c, measurement), measurement.gain, state.divergence)
    outputs = Outputs(
        measurement=measurement,
        observation=observe(c, new, delivered),
        reward=reward.unsqueeze(-1),
        truncated=(new.steps >= c.max_steps).unsqueeze(-1),
        base_tilt=new.base_tilt,
    )
    return StepResult(new, outputs, moved, solution)


def start(
    c: StepConstants, links: StepState, path: PathSolution, noise: SensorNoise | None, generator=None, world=None
) -> tuple[StepState, Measurement]:
    """Links at their reset: the state they start from and its measurement, recorded as a step records
    (:func:`record`). ``links`` is their state with its seas, ends, ω_D, calm-sea point, G_0 and the channel's
    constants set and the rest zeros (at rest: t = 0, both ends upright, no history); ``path`` their cold path
    solve at t = 0. The first packet fills every slot in flight (a reset has no older one); ``generator``: a
    channel's that draws (the Monte Carlo tracer); ``world``: the tilts ``[n, 4]`` the ends point at in the world,
    where they move (their attitude)."""
    resting = Moved(links.tx_tilt, links.rx_tilt, links.action_history, links.time, links.steps, links.command,
                    links.drive, world=world)  # fmt: skip
    light = channel_light(c, links, path, resting, generator, copies=1)
    measurement, readings, stored, _, feature = record(
        c, resting, path, light, links.reference_gain, links.flat_point, noise
    )
    packets = pack(readings, links.history).unsqueeze(1).expand_as(links.packets)
    links = replace(links, point=stored, previous_point=stored, last_feature=feature, packets=packets)
    delivered = deliver(links.packets, c.sensor.latency_steps).readings
    return replace(links, tracks=bases.followed(c, links, delivered, start=True)), measurement


def step(c: StepConstants, state: StepState, action: torch.Tensor, noise: SensorNoise | None) -> StepResult:
    """One step of every link: the new state, its outputs, the gimbals ``moved`` and the path solve.

    The solve is returned for finishing the links that have not converged
    (:func:`waterair.physics.paths.fixed.finish_unconverged`) and concluding again. ``noise`` is the
    sensor's draw for this step (:meth:`Sensor.draw`), or None for a noiseless one.
    """
    links = c.for_links(state.divergence)  # once for the step's two stages
    moved = _advance(links, state, action, noise)
    return _conclude(links, state, moved, solve(c, state.placed(moved), moved.time), noise, None)


def finish(
    c: StepConstants, state: StepState, moved: Moved, solution: Iterate, noise, options: FixedNewtonOptions
) -> StepResult:
    """:func:`step`'s solve continued for ``options.iterations`` more masked iterations on every link, then
    concluded.

    For small batches, where a dense pass costs less than gathering the unconverged links; links
    that had converged take no step.
    """
    more = solve(c, state.placed(moved), moved.time, solution.xy, options)
    return conclude(c, state, moved, more._replace(iterations=solution.iterations + more.iterations), noise)


def misalignment(c: StepConstants, measurement: Measurement) -> torch.Tensor:
    """α_D / ω_D + α_A / ω_A ``[B]``: how far both ends point from the present path (0 on an invalid one)."""
    alpha_d = measurement.alpha_d
    angles = alpha_d / per_link(c.optics.divergence, alpha_d) + measurement.alpha_a / c.optics.half_fov
    return torch.where(measurement.path_valid, angles, torch.zeros_like(angles))


def observe(c: StepConstants, state: StepState, delivered: Packet | None = None) -> torch.Tensor:
    """Every observation part ``[B, 17 + 5 · history_length]``, in the order of the full layout.

    The delivered packet's parts, then the controller's own knowledge (time, action history,
    geometry), which is never late. An environment keeps the columns of the parts its layout asks
    for (:func:`observation_columns`), outside the graph, so that every preset shares one graph. ``delivered``:
    the packet that reaches the controller (:func:`deliver`'s), where the caller has it already.
    """
    delivered = deliver(state.packets, c.sensor.latency_steps) if delivered is None else delivered
    time = (state.time / c.episode_seconds).unsqueeze(-1)
    tx, rx, _ = platforms.known_ends(c, state)
    geometry = (rx - tx)[:, :2] / c.vertical_distance
    narrow, wide = DIVERGENCE_SPAN
    divergence = torch.log(state.divergence**2 / (narrow * wide)) / math.log(wide / narrow)
    divergence = divergence.to(time.dtype).unsqueeze(-1)
    late = delivered.readings
    parts = (late.tx_pointing, late.rx_pointing, late.intensity, time, late.spot, late.spot_valid, late.beacon)
    parts += (late.beacon_valid, delivered.history, state.action_history.flatten(1), geometry, divergence)
    return torch.cat(parts, dim=-1)


def observation_columns(config: EnvConfig) -> list[int] | None:
    """The columns of :func:`observe`'s output that make up ``config``'s layout, or None for all of them.

    :func:`observe` gives the layout of every part (:data:`OBSERVATION_EXTRAS` all on).
    """
    full = config.replace(observation_extras=OBSERVATION_EXTRAS, frames=1)
    if len(config.observation_layout) == len(full.observation_layout):
        return None
    return config.replace(frames=1).columns_in(full)
