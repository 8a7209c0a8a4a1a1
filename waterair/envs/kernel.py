"""The environment step as pure tensor functions, so that ``torch.compile`` makes it one graph.

:func:`step` turns the state of B links and their actions into the next state and everything the
step reports: the gimbal update, the path solve (a fixed number of masked Newton iterations from a
prediction of the path point, :mod:`waterair.physics.paths.fixed`), the channel gain, the sensor
readings and their delay, the observation and the reward. It has no Python branches on data and no
host synchronisation. :class:`waterair.envs.env.WaterAirEnv` calls it compiled or eagerly (the same
function, so both give the same numbers to float rounding), then hands the rare links whose path
has not converged to the adaptive solver and redoes :func:`conclude` for them.

The state is a plain ``dict`` of tensors (:data:`STATE_KEYS`); nothing here keeps state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from waterair.envs import channels
from waterair.envs.config import OBSERVATION_EXTRAS, EnvConfig
from waterair.envs.rewards import Reward
from waterair.envs.sensors import (
    PACKET_PARTS,
    Sensor,
    back_projection,
    intensity_feature,
    packet_sizes,
    spot_position,
)
from waterair.physics.channel import Transceiver, pointing
from waterair.physics.optics import unit_vector
from waterair.physics.paths import FixedNewtonOptions, PathSolution, finish_path
from waterair.physics.paths.fixed import fixed_newton_terms

SURFACE_KEYS = ("omega", "phase", "kx", "ky", "amplitude")
STATE_KEYS = (
    *SURFACE_KEYS,
    "time",
    "steps",
    "tx_tilt",
    "rx_tilt",
    "tx_position",
    "rx_position",
    "point",
    "previous_point",
    "flat_point",
    "reference_gain",
    "history",
    "last_feature",
    "action_history",
    "packets",
)
"""What the step reads: the seas' components, the clock, the gimbals, the geometry, the last two
path points (the prediction), the sensor history and the packets in flight ``[B, slots, width]``."""
LATTICE_LEASH = 3.0
"""How far (m) the two-scale lattice's centre may stray from the calm-sea point before it is put back
there: the light comes from within a metre or so of it at any wind (docs/model.md §4.3)."""
MEASUREMENT_KEYS = ("gain", "gain_upper_bound", "intensity", "path_valid", "alpha_d", "alpha_a", "departure", "arrival")
"""The true values each step reports beside the observation."""


@dataclass(frozen=True)
class StepConstants:
    """The numbers of one environment configuration that the step uses (all plain Python values)."""

    optics: Transceiver
    sensor: Sensor
    reward: Reward
    solver: FixedNewtonOptions
    tolerance: float
    action_mode: str
    max_tilt: float
    residual: float
    residual_base: str
    slew_step: float
    dt: float
    episode_seconds: float
    max_steps: int
    vertical_distance: float
    channel: str
    two_scale: bool
    lattice_nodes: int
    lattice_span: float

    @classmethod
    def of(cls, config: EnvConfig, sensor: Sensor, reward: Reward) -> StepConstants:
        solver = FixedNewtonOptions(iterations=config.newton_iterations)
        return cls(
            optics=config.transceiver(),
            sensor=sensor,
            reward=reward,
            solver=solver,
            tolerance=solver.tolerance(getattr(torch, config.dtype)),
            action_mode=config.action_mode,
            max_tilt=config.max_tilt,
            residual=math.sin(math.radians(config.residual_deg)),
            residual_base=config.residual_base,
            slew_step=math.sin(math.radians(config.max_slew_deg_s * config.dt)),
            dt=config.dt,
            episode_seconds=config.episode_seconds,
            max_steps=config.max_steps,
            vertical_distance=config.tx_depth + config.rx_height,
            channel=config.channel,
            two_scale=config.spectrum == "elfouhaily",
            lattice_nodes=config.lattice_nodes,
            lattice_span=config.lattice_span,
        )

    @property
    def tracks_exactly(self) -> bool:
        """Whether the step needs the tracked refraction point converged (it does not when the
        two-scale lattice only centres on it, nor for the Monte Carlo tracer)."""
        return self.channel == "single_path" or (self.channel == "full" and not self.two_scale)


def advance(c: StepConstants, state: dict, action: torch.Tensor) -> dict:
    """Gimbals, action history and clock after ``action`` ``[B, 4]`` (already clipped to [-1, 1])."""
    if c.action_mode == "absolute":
        tx, rx = action[:, :2] * c.max_tilt, action[:, 2:] * c.max_tilt
    elif c.action_mode == "residual":
        base = base_tilts(c, state)
        tx, rx = base[:, :2] + action[:, :2] * c.residual, base[:, 2:] + action[:, 2:] * c.residual
    else:
        tx, rx = state["tx_tilt"] + action[:, :2] * c.slew_step, state["rx_tilt"] + action[:, 2:] * c.slew_step
    return {
        "tx_tilt": limit_tilt(tx, c.max_tilt),
        "rx_tilt": limit_tilt(rx, c.max_tilt),
        "action_history": torch.cat((action.unsqueeze(1), state["action_history"][:, :-1]), dim=1),
        "time": state["time"] + c.dt,
        "steps": state["steps"] + 1,
    }


def flat_tilts(point: torch.Tensor, tx: torch.Tensor, rx: torch.Tensor) -> torch.Tensor:
    """The tilts ``[n, 4]`` (tx_vx, tx_vy, rx_vx, rx_vy) pointing both ends at the calm-sea path point ``[n, 3]``."""
    return torch.cat((unit_vector(point - tx)[:, :2], unit_vector(point - rx)[:, :2]), dim=-1)


def base_tilts(c: StepConstants, state: dict) -> torch.Tensor:
    """The residual base controller's tilts ``[B, 4]`` for the next action: flat-sea Snell, or the
    quadrant-detector back-projection of the delivered packet (flat-sea Snell where it has no reading)."""
    point, tx, rx = state["flat_point"], state["tx_position"], state["rx_position"]
    if c.residual_base == "flat_snell":
        return flat_tilts(point, tx, rx)
    delivered = unpack(state["packets"][:, -1])
    flat = unit_vector(point - tx), unit_vector(point - rx)
    seen = delivered["spot_valid"][:, 0] > 0.5
    tx_dir, rx_dir = back_projection(delivered["rx_pointing"], delivered["spot"], seen, tx, rx, flat, c.optics.half_fov)
    return torch.cat((tx_dir[:, :2], rx_dir[:, :2]), dim=-1)


def limit_tilt(tilt: torch.Tensor, max_tilt: float) -> torch.Tensor:
    """Scale tilt vectors ``[n, 2]`` down to |v| ≤ sin(max_tilt)."""
    norm = torch.linalg.vector_norm(tilt, dim=-1, keepdim=True)
    return tilt * (max_tilt / norm.clamp(min=max_tilt))


def predicted_point(state: dict) -> torch.Tensor:
    """The next path point's (x, y) ``[B, 2]``, extrapolated from the last two (it moves smoothly)."""
    return 2.0 * state["point"][:, :2] - state["previous_point"][:, :2]


def solve(c: StepConstants, state: dict, time: torch.Tensor, start=None, iterations: int | None = None):
    """Masked Newton iterations (``c.solver.iterations`` by default) from ``start`` (default: the predicted
    point): (P ``[B, 3]``, slopes ``[B, 2]``, final (x, y) ``[B, 2]``, converged ``[B]``, iterations ``[B]``)."""
    return fixed_newton_terms(
        *(state[key] for key in SURFACE_KEYS),
        predicted_point(state) if start is None else start,
        time,
        state["tx_position"],
        state["rx_position"],
        c.optics.n_water,
        c.optics.n_air,
        c.solver.iterations if iterations is None else iterations,
        c.tolerance,
        c.solver.armijo,
        c.solver.max_step,
    )


def record(c: StepConstants, tilts: dict, path: PathSolution, reference_gain, flat_point, noise, light=None):
    """What a solved path (and, for the full channel, its ``light``) gives: the true measurement,
    the sensor packet and the next warm start.

    Returns (measurement dict, packet ``[n, width]``, stored point ``[n, 3]``, whether the path's own
    point was stored ``[n]``, intensity feature ``[n]``). An invalid path stores the calm-sea point,
    so that the next solve does not start from a lost one.
    """
    tx_dir, rx_dir = pointing(tilts["tx_tilt"], up=True), pointing(tilts["rx_tilt"], up=False)
    true, seen_arrival, lit = channels.measure(c.optics, path, light, tx_dir, rx_dir)
    intensity = true["gain"] / reference_gain
    measured = c.sensor.intensity(intensity, noise)
    spot, spot_valid = c.sensor.spot(spot_position(seen_arrival, rx_dir, c.optics.half_fov), lit, measured, noise)
    feature = intensity_feature(measured)
    packet = {
        "tx_pointing": tx_dir,
        "rx_pointing": rx_dir,
        "intensity": feature.unsqueeze(-1),
        "spot": spot,
        "spot_valid": spot_valid.unsqueeze(-1),
    }
    measurement = {**true, "intensity": intensity}
    tracked = tracked_point(c, path, flat_point)
    stored = torch.where(tracked.unsqueeze(-1), path.point, flat_point)
    return measurement, packet, stored, tracked, feature


def tracked_point(c: StepConstants, path: PathSolution, flat_point: torch.Tensor) -> torch.Tensor:
    """Whether each link keeps its path's point as the next warm start ``[n]``: a valid path, or, where
    the point only centres the two-scale lattice (or nothing), any finite point near the calm-sea one."""
    if c.tracks_exactly:
        return path.valid
    near = torch.linalg.vector_norm(path.point[:, :2] - flat_point[:, :2], dim=-1) < LATTICE_LEASH
    return torch.isfinite(path.point).all(-1) & near


def pack(packet: dict, history: torch.Tensor) -> torch.Tensor:
    """One packet ``[n, width]``: the parts of :data:`PACKET_PARTS` side by side."""
    return torch.cat([packet[name] for name in PACKET_PARTS[:-1]] + [history], dim=-1)


def unpack(packet: torch.Tensor) -> dict[str, torch.Tensor]:
    """The parts of one packet ``[n, width]`` by name (the inverse of :func:`pack`)."""
    history_length = packet.shape[-1] - sum(packet_sizes(0))
    return dict(zip(PACKET_PARTS, packet.split(packet_sizes(history_length), dim=-1), strict=True))


def conclude(c: StepConstants, state: dict, moved: dict, solution: tuple, noise, light=None):
    """The new state and the step's outputs, given the gimbals ``moved`` and the path ``solution``
    (P ``[B, 3]``, slopes ``[B, 2]``, converged ``[B]``, iterations ``[B]``). The full channel's light
    is computed here; the Monte Carlo tracer's comes as ``light``."""
    point, slope, converged, taken = solution
    n_w, n_a = c.optics.n_water, c.optics.n_air
    path = finish_path(point, slope, state["tx_position"], state["rx_position"], converged, taken, n_w, n_a)
    if c.channel == "full":
        light = full_light(c, state, path, moved["time"])
    measurement, packet, stored, tracked, feature = record(
        c, moved, path, state["reference_gain"], state["flat_point"], noise, light
    )
    history = torch.cat((state["last_feature"].unsqueeze(-1), state["history"][:, :-1]), dim=-1)
    packets = torch.cat((pack(packet, history).unsqueeze(1), state["packets"][:, :-1]), dim=1)
    new = {
        **moved,
        "point": stored,
        "previous_point": torch.where(tracked.unsqueeze(-1), state["point"], stored),
        "history": history,
        "last_feature": feature,
        "packets": packets,
    }
    outputs = {
        **measurement,
        "observation": observe(c, {**state, **new}),
        "reward": c.reward(measurement["intensity"], misalignment(c, measurement), measurement["gain"]).unsqueeze(-1),
        "truncated": (new["steps"] >= c.max_steps).unsqueeze(-1),
        "base_tilt": base_tilts(c, {**state, **new}),
    }
    return new, outputs


def full_light(c: StepConstants, state: dict, path: PathSolution, time: torch.Tensor):
    """The full channel's light for the links of ``state`` (:func:`waterair.envs.channels.light`), the
    lattice centred on the tracked point (or the calm-sea point where that is lost)."""
    tracked = tracked_point(c, path, state["flat_point"])
    centre = torch.where(tracked.unsqueeze(-1), path.point[:, :2], state["flat_point"][:, :2])
    components = tuple(state[key] for key in SURFACE_KEYS)
    return channels.light(
        c.optics,
        c.two_scale,
        c.lattice_nodes,
        c.lattice_span,
        components,
        state["tx_position"],
        state["rx_position"],
        time,
        path,
        centre,
        state["lattice_basis"],
        state["blur"],
    )


def step(c: StepConstants, state: dict, action: torch.Tensor, noise: torch.Tensor | None):
    """One step of every link: (new state entries, outputs, the gimbals ``moved``, the solve's result).

    The solve's result is (P, slopes, final (x, y), converged, iterations), for finishing the links
    that have not converged (:func:`waterair.physics.paths.fixed.finish_unconverged`) and concluding
    again. ``noise`` is the sensor's draw for this step (:meth:`Sensor.draw`), or None for a noiseless one.
    """
    moved = advance(c, state, action)
    point, slope, xy, converged, taken = solve(c, state, moved["time"])
    new, outputs = conclude(c, state, moved, (point, slope, converged, taken), noise)
    return new, outputs, moved, (point, slope, xy, converged, taken)


def finish(c: StepConstants, state: dict, moved: dict, solution: tuple, noise, iterations: int):
    """:func:`step`'s solve continued for ``iterations`` more masked iterations on every link, then concluded.

    For small batches, where a dense pass costs less than gathering the unconverged links; links
    that had converged take no step. Returns (new state entries, outputs, the solve's result).
    """
    xy, taken = solution[2], solution[4]
    point, slope, xy, converged, more = solve(c, state, moved["time"], xy, iterations)
    taken = taken + more
    new, outputs = conclude(c, state, moved, (point, slope, converged, taken), noise)
    return new, outputs, (point, slope, xy, converged, taken)


def misalignment(c: StepConstants, measurement: dict) -> torch.Tensor:
    """α_D / ω_D + α_A / ω_A ``[B]``: how far both ends point from the present path (0 on an invalid one)."""
    angles = measurement["alpha_d"] / c.optics.divergence + measurement["alpha_a"] / c.optics.half_fov
    return torch.where(measurement["path_valid"], angles, torch.zeros_like(angles))


def observe(c: StepConstants, state: dict) -> torch.Tensor:
    """Every observation part ``[B, 13 + 5 · history_length]``, in the order of the full layout.

    The delivered packet's parts, then the controller's own knowledge (time, action history,
    geometry), which is never late. An environment keeps the columns of the parts its layout asks
    for (:func:`observation_columns`), outside the graph, so that every preset shares one graph.
    """
    delivered = unpack(state["packets"][:, -1])
    time = (state["time"] / c.episode_seconds).unsqueeze(-1)
    geometry = (state["rx_position"] - state["tx_position"])[:, :2] / c.vertical_distance
    late = [delivered[name] for name in PACKET_PARTS]
    return torch.cat((*late[:3], time, *late[3:], state["action_history"].flatten(1), geometry), dim=-1)


def observation_columns(config: EnvConfig) -> list[int] | None:
    """The columns of :func:`observe`'s output that make up ``config``'s layout, or None for all of them.

    :func:`observe` gives the layout of every part (:data:`OBSERVATION_EXTRAS` all on).
    """
    full = config.replace(observation_extras=OBSERVATION_EXTRAS).observation_layout
    if len(config.observation_layout) == len(full):
        return None
    return [column for name in config.observation_layout for column in range(full[name].start, full[name].stop)]
