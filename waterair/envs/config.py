"""Validated configuration of :class:`waterair.envs.env.WaterAirEnv` (the ``env`` config group).

The physics is held as the physics' own objects, one nested group each: the sea (``env.sea.wind``, a
:class:`~waterair.physics.sea.JonswapSea` or :class:`~waterair.physics.sea.ElfouhailySea`), the link's geometry
(``env.geometry.offset_ratio``, :class:`~waterair.physics.channel.LinkGeometry`) and the optics
(``env.optics.aperture_diameter``, :class:`~waterair.physics.channel.Transceiver`) and the drone's beacon
(``env.beacon.divergence``, :class:`~waterair.physics.channel.Beacon`). Each physics value is validated once, where
it is defined; the interface keys (``env.dt``, ...) are validated here. Every error names the key path
(``env.sea.wind``), the value and the allowed range; docs/reference/env.md (generated from these defaults, ``make
docs``) lists each key with its unit, default and range. The channel is a group too (``env.channel.nodes``,
:mod:`waterair.physics.channel.registry`), chosen by ``env/channel=``. A key of the first releases (``env.wind``,
``env.lattice_nodes``) is an error naming where it lives now; ``python -m waterair.cli.migrate RUN`` rewrites an old
run's config.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from waterair.core.devices import resolve_device
from waterair.core.validation import check_choice, check_int, check_range
from waterair.envs import operating_point
from waterair.envs.groups import (
    DEFAULT_SPECTRUM,
    PHYSICS,
    SHARED_SEA_KEYS,
    as_mapping,
    build_sea,
    physics_group,
    plain,
    unknown_key,
)
from waterair.envs.operating_point import LOW_OPEN, PER_LINK
from waterair.physics.actuator import Actuator
from waterair.physics.channel import CHANNELS, Beacon, Channel, ChannelModel, FullChannel, LinkGeometry, Transceiver
from waterair.physics.channel import channel as build_channel
from waterair.physics.motion import Motion
from waterair.physics.sea import SeaState, sea_state

ACTION_MODES = ("absolute", "delta", "residual")
RESIDUAL_BASES = ("flat_snell", "aoa_tracker", "beacon_tracker", "kalman_tracker")
"""What residual actions correct: flat-sea Snell pointing, the quadrant-detector back-projection, each end along
its own reading (the beacon at the transmitter, the spot at the receiver), or along its Kalman track of it."""
_BEACON_PARTS = ("spot", "spot_valid", "beacon", "beacon_valid")
BASE_NEEDS = {"aoa_tracker": ("spot", "spot_valid"), "beacon_tracker": _BEACON_PARTS, "kalman_tracker": _BEACON_PARTS}
"""The observation parts each residual base reads."""
ACTION_KEYS = ("action_mode", "residual_deg", "residual_beams", "residual_base", "actuated")
"""The keys that say how an action turns into tilts, which ``replica_actions`` may set per replica."""
OBSERVATION_EXTRAS = ("spot", "spot_valid", "beacon", "beacon_valid", "history", "action_history", "geometry",
                      "divergence")  # fmt: skip
"""Opt-in observation parts, in the order they follow the paper's 8 (docs/environment.md)."""
SENSOR_KEYS = ("latency_steps", "intensity_noise", "intensity_noise_floor", "intensity_saturation", "spot_noise_rad",
               "spot_threshold", "beacon_noise_rad", "beacon_threshold")  # fmt: skip
"""The sensing keys (presets: env/sensor=ideal|ideal_late|realistic)."""
DTYPES = ("float32", "float64")
DRAWS = ("stream", "keyed")
ENV_SOLVERS = ("newton", "centroid")
"""Path solvers of the step: fixed-iteration Newton in the step's graph, or the paper's centroid method."""


@dataclass(frozen=True)
class EnvConfig:
    """Everything that defines a batch of water-air links; units in the names and comments.

    The physics keys are described in docs/model.md, the interface keys in docs/environment.md.
    """

    num_envs: int = 16  # B, independent links stepped together
    device: str = "cpu"  # cpu, cuda, or auto (cuda when available)
    dtype: str = "float32"
    seed: int | None = None  # None: nondeterministic
    # the physics, each validated where it is defined (docs/model.md); a mapping of its keys is built into it
    sea: SeaState = sea_state(DEFAULT_SPECTRUM)  # env.sea.*; presets env/spectrum=elfouhaily|jonswap, env/sea=...
    geometry: LinkGeometry = LinkGeometry()  # env.geometry.*: where the ends are (docs/model.md §0)
    optics: Transceiver = Transceiver()  # env.optics.*: the ends' optics (docs/model.md §4-§5)
    beacon: Beacon = Beacon()  # env.beacon.*: the drone's beacon and the transmitter's detector (docs/model.md §4.9)
    actuator: Actuator = Actuator()  # env.actuator.*; env/actuator=ideal|gimbal|fsm|gimbal_fsm (docs/model.md §11)
    motion: Motion = Motion()  # env.motion.*; env/motion=static|hover|transit: how the ends move (docs/model.md §12)
    # env.channel.*; env/channel=full|single_path (the paper's)|montecarlo|counting (the last two: slow), §4
    channel: Channel = FullChannel()
    # dynamics and interface (docs/environment.md)
    dt: float = 0.05  # s
    max_steps: int = 500  # steps per episode (truncation)
    action_mode: str = "absolute"  # absolute | delta | residual (on top of residual_base's pointing)
    residual_deg: float = 15.0  # residual mode: the largest deviation from the base controller's pointing
    residual_beams: float | None = None  # residual mode: the transmitter's, at most this many of its link's ω_D
    residual_base: str = "flat_snell"  # residual mode: one of RESIDUAL_BASES (its readings: BASE_NEEDS)
    max_tilt_deg: float = 45.0  # largest pointing tilt from vertical
    max_slew_deg_s: float = 60.0  # delta mode: largest tilt change per second
    actuated: bool = True  # false: the ends point where commanded whatever env.actuator (the kinematic references)
    observation_extras: tuple[str, ...] = ()  # any of OBSERVATION_EXTRAS; presets: env/observation=
    history_length: int = 4  # readings kept by the "history" and "action_history" extras
    frames: int = 1  # the last `frames` observations side by side, newest first (1: no stacking)
    solver: str = "newton"  # newton | centroid
    newton_iterations: int = 3  # masked Newton iterations of the compiled step; the rare rest finish adaptively
    # sensing (docs/environment.md, "Sensing"); all 0 / null: the ideal sensor (preset env/sensor=ideal)
    latency_steps: int = 0  # extra steps before a measurement packet reaches the controller
    intensity_noise: float = 0.0  # relative standard deviation of the measured intensity
    intensity_noise_floor: float = 0.0  # additive standard deviation of the measured intensity (units of I)
    intensity_saturation: float | None = None  # largest measurable intensity I, or null
    spot_noise_rad: float = 0.0  # standard deviation of each quadrant-detector component, as an angle (rad)
    spot_threshold: float = 0.0  # measured intensity below which the detector reads no spot
    beacon_noise_rad: float = 0.0  # standard deviation of each component of the beacon reading, as an angle (rad)
    beacon_threshold: float = 0.0  # beacon intensity (of its calm-sea value) below which it reads nothing
    # the operating point: one value for every link, written into its group's key (operating_point.FIXED), exclusive
    # with the same quantity's range and values; None: the group's own (docs/environment.md, "The operating point")
    wind: float | None = None  # m/s: env.sea.wind
    wind_direction: float | None = None  # deg: env.sea.wind_direction_deg
    offset: float | None = None  # offset ratio: env.geometry.offset_ratio
    offset_azimuth: float | None = None  # deg: env.geometry.offset_azimuth_deg
    divergence: float | None = None  # rad: env.optics.divergence
    # domain randomisation: per-link values drawn uniformly at every reset (ω_D: uniformly in its log), or None
    wind_range: tuple[float, float] | None = None  # m/s
    offset_range: tuple[float, float] | None = None  # offset ratio
    offset_azimuth_range: tuple[float, float] | None = None  # deg: the drone anywhere around the transmitter
    wind_direction_range: tuple[float, float] | None = None  # deg: wind from any direction
    divergence_range: tuple[float, float] | None = None  # rad: the beam divergence ω_D (null: optics.divergence)
    # per-link scenario values (evaluation grids): link i uses values[i % len(values)], or None.
    # Given together, the lists have one entry per scenario point (link i is point i % len).
    wind_values: tuple[float, ...] | None = None  # m/s
    offset_values: tuple[float, ...] | None = None  # offset ratio
    offset_azimuth_values: tuple[float, ...] | None = None  # deg
    wind_direction_values: tuple[float, ...] | None = None  # deg
    divergence_values: tuple[float, ...] | None = None  # rad
    # the batch is `replicas` copies of num_envs / replicas links with identical seas (paired comparisons)
    replicas: int = 1
    # evaluation's groups: replica k acts as replica_actions[k] says, a mapping of ACTION_KEYS (the keys above
    # where it names none; kept as (key, value) pairs); null: every replica acts as the keys above say
    replica_actions: tuple[Mapping | tuple, ...] | None = None
    # and senses as replica_sensing[k] says, a mapping of SENSOR_KEYS (the same way)
    replica_sensing: tuple[Mapping | tuple, ...] | None = None
    # each link's random numbers (docs/model.md §10): one generator's, in order (stream), or hashed from what they are
    draws: str = "keyed"
    link_offset: int = 0  # keyed draws: the realisation of the batch's first link (a batch split over environments)
    # torch.compile the step into one graph (docs/environment.md, "The compiled step"); train.py and evaluate.py
    # decide. Not "compile": TorchRL's EnvBase metaclass takes that keyword for itself.
    compile_kernel: bool = False

    def __post_init__(self) -> None:
        defaults = {group: type(self).__dataclass_fields__[group].default for group in PHYSICS}
        for key, value in operating_point.fixed(self, defaults).items():  # written into the groups before they build
            object.__setattr__(self, key, value)
        object.__setattr__(self, "sea", physics_group("sea", self.sea, SeaState, build_sea))
        object.__setattr__(self, "geometry", physics_group("geometry", self.geometry, LinkGeometry, LinkGeometry))
        object.__setattr__(self, "optics", physics_group("optics", self.optics, Transceiver, Transceiver))
        object.__setattr__(self, "beacon", physics_group("beacon", self.beacon, Beacon, Beacon))
        object.__setattr__(self, "actuator", physics_group("actuator", self.actuator, Actuator, Actuator))
        object.__setattr__(self, "motion", physics_group("motion", self.motion, Motion, Motion))
        object.__setattr__(self, "channel", physics_group("channel", self.channel, Channel, build_channel))
        check_int("env.num_envs", self.num_envs, 1, 2**24)
        if not isinstance(self.compile_kernel, bool):  # a truthy 'auto' would compile silently
            raise ValueError(
                f"env.compile_kernel = {self.compile_kernel!r} is not allowed here; choose true or false "
                "(train.py and evaluate.py decide auto from the frames they will run)"
            )
        resolve_device(self.device, "env.device")  # cuda without a GPU is an error now
        check_choice("env.dtype", self.dtype, DTYPES)
        check_choice("env.draws", self.draws, DRAWS)
        check_int("env.link_offset", self.link_offset, 0, 2**40)
        if self.seed is not None:
            check_int("env.seed", self.seed, 0, 2**63 - 1)
        check_range("env.dt", self.dt, 0.0, 10.0, low_open=True, unit="s")
        check_int("env.max_steps", self.max_steps, 1, 10**7)
        check_choice("env.action_mode", self.action_mode, ACTION_MODES)
        if not isinstance(self.actuated, bool):
            raise ValueError(f"env.actuated = {self.actuated!r} must be true or false")
        check_range("env.max_tilt_deg", self.max_tilt_deg, 0.0, 90.0, low_open=True, high_open=True, unit="deg")
        check_range("env.max_slew_deg_s", self.max_slew_deg_s, 0.0, 1e5, low_open=True, unit="deg/s")
        check_range("env.residual_deg", self.residual_deg, 0.0, 90.0, low_open=True, high_open=True, unit="deg")
        if self.residual_beams is not None:
            check_range("env.residual_beams", self.residual_beams, 0.0, 100.0, low_open=True)
        _check_list("env.observation_extras", self.observation_extras)
        object.__setattr__(self, "observation_extras", tuple(self.observation_extras))
        for extra in self.observation_extras:
            check_choice("env.observation_extras", extra, OBSERVATION_EXTRAS)
        check_int("env.history_length", self.history_length, 1, 1000)
        check_choice("env.residual_base", self.residual_base, RESIDUAL_BASES)
        needs = set(BASE_NEEDS.get(self.residual_base, ())) - set(self.observation_extras)
        if self.action_mode == "residual" and needs:
            preset = "beacon" if "beacon" in BASE_NEEDS[self.residual_base] else "quadrant"
            raise ValueError(
                f"env.residual_base = {self.residual_base!r} needs its readings in the observation "
                f"(env.observation_extras lacks {', '.join(sorted(needs))}); use env/observation={preset} or "
                "env.residual_base=flat_snell"
            )
        check_int("env.frames", self.frames, 1, 64)
        check_int("env.latency_steps", self.latency_steps, 0, 1000)
        check_range("env.intensity_noise", self.intensity_noise, 0.0, 10.0)
        check_range("env.intensity_noise_floor", self.intensity_noise_floor, 0.0, 10.0)
        if self.intensity_saturation is not None:
            check_range("env.intensity_saturation", self.intensity_saturation, 0.0, 1e6, low_open=True)
        check_range("env.spot_noise_rad", self.spot_noise_rad, 0.0, 1.0, unit="rad")
        check_range("env.spot_threshold", self.spot_threshold, 0.0, 1e6)
        check_range("env.beacon_noise_rad", self.beacon_noise_rad, 0.0, 1.0, unit="rad")
        check_range("env.beacon_threshold", self.beacon_threshold, 0.0, 1e6)
        check_int("env.replicas", self.replicas, 1, self.num_envs)
        if self.num_envs % self.replicas:
            raise ValueError(
                f"env.replicas = {self.replicas} is not allowed; it must divide env.num_envs = {self.num_envs}"
            )
        self._check_replica_keys("replica_actions", ACTION_KEYS)
        self._check_replica_keys("replica_sensing", SENSOR_KEYS)
        check_choice("env.solver", self.solver, ENV_SOLVERS)
        self.channel_model()  # validates the channel's settings, once
        if self.solver == "centroid" and not self.channel.centroid_solver:
            serves = ", ".join(f"env/channel={name}" for name, kind in CHANNELS.items() if kind.centroid_solver)
            raise ValueError(
                f"env.solver = 'centroid' only works with {serves} (got env/channel={self.channel.name}); "
                "the other channels track their point with newton"
            )
        check_int("env.newton_iterations", self.newton_iterations, 1, 20)
        for name, (low, high, unit) in PER_LINK.items():
            range_key = f"{name}_range"
            if getattr(self, range_key) is not None:
                pair = _check_pair(f"env.{range_key}", getattr(self, range_key), low, high, unit, name in LOW_OPEN)
                object.__setattr__(self, range_key, pair)
            self._check_values(name, low, high, unit)
        lengths = {
            f"env.{n}_values": len(getattr(self, f"{n}_values")) for n in PER_LINK if getattr(self, f"{n}_values")
        }
        if len(set(lengths.values())) > 1:
            (first, count), *others = lengths.items()
            given = f"{first} has {count} entries and " + ", ".join(f"{key} {n}" for key, n in others)
            raise ValueError(f"{given}; given together they must have one entry per scenario point")

    def _check_replica_keys(self, name: str, allowed: tuple[str, ...]) -> None:
        """``env.<name>``: one mapping of some of ``allowed`` per replica, each valid; kept as (key, value) pairs."""
        given = getattr(self, name)
        if given is None:
            return
        _check_list(f"env.{name}", given)
        if len(given) != self.replicas:
            raise ValueError(f"env.{name} has {len(given)} entries for env.replicas = {self.replicas}; give one "
                             "per replica (or null)")  # fmt: skip
        entries = []
        for index, keys in enumerate(given):
            key = f"env.{name}[{index}]"
            keys = dict(keys) if isinstance(keys, Mapping | tuple) else keys
            if not isinstance(keys, dict) or not set(keys) <= set(allowed):
                raise ValueError(f"{key} = {keys!r} must map some of {', '.join(allowed)} to their values")
            try:
                self.replace(**keys, replica_actions=None, replica_sensing=None)
            except ValueError as error:
                raise ValueError(f"{key}: {error}") from None
            entries.append(tuple((each, keys[each]) for each in allowed if each in keys))  # hashable
        object.__setattr__(self, name, tuple(entries))

    def replica_configs(self) -> list[EnvConfig]:
        """The configuration each replica acts and senses by, one per replica (:data:`ACTION_KEYS` from
        ``replica_actions``, :data:`SENSOR_KEYS` from ``replica_sensing``; this one where neither is set)."""
        if self.replica_actions is None and self.replica_sensing is None:
            return [self] * self.replicas
        ways = [dict(keys) for keys in self.replica_actions or [{}] * self.replicas]
        sensing = [dict(keys) for keys in self.replica_sensing or [{}] * self.replicas]
        return [
            self.replace(**way, **senses, replica_actions=None, replica_sensing=None)
            for way, senses in zip(ways, sensing, strict=True)
        ]

    def _check_values(self, name: str, low: float, high: float, unit: str) -> None:
        key, values = f"{name}_values", getattr(self, f"{name}_values")
        if values is None:
            return
        _check_list(f"env.{key}", values)
        values = tuple(values)
        if not values:
            raise ValueError(f"env.{key} = [] must list at least one value (or be null)")
        if getattr(self, f"{name}_range") is not None:
            raise ValueError(f"env.{key} and env.{name}_range are both set; use one of them")
        for index, value in enumerate(values):
            check_range(f"env.{key}[{index}]", value, low, high, low_open=name in LOW_OPEN, unit=unit)
        object.__setattr__(self, key, tuple(float(v) for v in values))

    @classmethod
    def from_mapping(cls, values: Mapping) -> EnvConfig:
        """Build from a plain mapping (e.g. a resolved Hydra ``env`` group); unknown keys are errors.

        The groups (``sea``, ``geometry``, ``optics``, ``beacon``, ``channel``) are mappings of their keys or the
        objects themselves. A key of the first releases is an error naming where it lives now
        (:data:`~waterair.envs.groups.RENAMED`).
        """
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ValueError(unknown_key(unknown[0], known))
        return cls(**{k: plain(v) for k, v in values.items()})

    def to_mapping(self) -> dict:
        """The keys that rebuild this config, the physics groups as nested mappings (the ``env`` group's shape)."""
        values = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        return {key: as_mapping(value) if key in PHYSICS else value for key, value in values.items()}

    def replace(self, **changes) -> EnvConfig:
        """A copy with ``changes`` applied (validated; unknown keys are errors).

        A group given as a mapping changes only the keys it names (``sea={"wind": 8}``); one that names another
        sea keeps the shared keys and takes that sea's own defaults, one that names another channel takes its
        defaults (``channel={"name": "single_path"}``).
        """
        current = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}  # untouched groups stay built
        changes = operating_point.followed(changes)  # env.wind and env.sea.wind kept together
        for group in PHYSICS:
            given = changes.get(group)
            if not isinstance(given, Mapping):
                continue
            base = as_mapping(current[group])
            if group == "sea" and given.get("spectrum", base["spectrum"]) != base["spectrum"]:
                base = {key: base[key] for key in SHARED_SEA_KEYS}
            if group == "channel" and given.get("name", base["name"]) != base["name"]:
                base = {}
            changes = {**changes, group: {**base, **given}}
        return EnvConfig.from_mapping({**current, **changes})

    def channel_model(self) -> ChannelModel:
        """The model of ``channel`` for this sea and these optics (docs/environment.md, "Channel")."""
        return self._channel

    @functools.cached_property
    def _channel(self) -> ChannelModel:
        """Built once per config; an error names ``env.channel.<key>``."""
        try:
            return self.channel.model(self.optics, self.sea.two_scale)
        except ValueError as error:
            raise ValueError(f"env.channel.{error}") from None

    @property
    def sensing(self) -> dict:
        """The sensing keys and their values (:data:`SENSOR_KEYS`)."""
        return {key: getattr(self, key) for key in SENSOR_KEYS}

    @property
    def senses_beacon(self) -> bool:
        """Whether the step reads the beacon: its reading is observed, or the residual base follows it (the base's
        tilts are reported in every action mode)."""
        return "beacon" in self.observation_extras or "beacon" in BASE_NEEDS.get(self.residual_base, ())

    @property
    def max_tilt(self) -> float:
        """sin(max_tilt): the largest norm of a tilt vector."""
        return math.sin(math.radians(self.max_tilt_deg))

    @functools.cached_property
    def observation_layout(self) -> dict[str, slice]:
        """Where each named part sits in the observation vector, in order (docs/environment.md).

        ``tx_pointing`` (3), ``rx_pointing`` (3), ``intensity`` (1), ``time`` (1), then the opt-in
        extras in the order of :data:`OBSERVATION_EXTRAS`: ``spot`` (2), ``spot_valid`` (1), ``beacon`` (2),
        ``beacon_valid`` (1), ``history`` (``history_length``), ``action_history`` (4 × ``history_length``),
        ``geometry`` (2), ``divergence`` (1).
        """
        extra_sizes = {
            "spot": 2,
            "spot_valid": 1,
            "beacon": 2,
            "beacon_valid": 1,
            "history": self.history_length,
            "action_history": 4 * self.history_length,
            "geometry": 2,
            "divergence": 1,
        }
        sizes = {"tx_pointing": 3, "rx_pointing": 3, "intensity": 1, "time": 1}
        sizes.update({name: extra_sizes[name] for name in OBSERVATION_EXTRAS if name in self.observation_extras})
        layout, start = {}, 0
        for name, size in sizes.items():
            layout[name] = slice(start, start + size)
            start += size
        return layout

    @property
    def frame_size(self) -> int:
        """Length of one observation frame: 8 plus the opt-in extras (where the layout's parts sit)."""
        return max(part.stop for part in self.observation_layout.values())

    @property
    def observation_size(self) -> int:
        """Length of the observation vector: ``frames`` frames of :attr:`frame_size`, newest first."""
        return self.frame_size * self.frames

    def columns_in(self, wide: EnvConfig) -> list[int]:
        """The columns of ``wide``'s observation that make up this config's, frame by frame (newest first): where
        ``wide`` observes every part of this layout and at least as many frames (evaluation's groups, in which a
        policy reads its own observation out of one with more parts)."""
        if not set(self.observation_layout) <= set(wide.observation_layout) or self.frames > wide.frames:
            raise ValueError(f"the observation {list(wide.observation_layout)} × {wide.frames} frames lacks a part of "
                             f"{list(self.observation_layout)} × {self.frames}")  # fmt: skip
        return [
            frame * wide.frame_size + column
            for frame in range(self.frames)
            for name in self.observation_layout
            for column in range(wide.observation_layout[name].start, wide.observation_layout[name].stop)
        ]

    @property
    def episode_seconds(self) -> float:
        return self.dt * self.max_steps


def _check_pair(
    name: str, pair: Sequence[float], low: float, high: float, unit: str, low_open: bool
) -> tuple[float, float]:
    _check_list(name, pair)
    if len(pair) != 2:
        raise ValueError(f"{name} = {list(pair)!r} must be [low, high]")
    lo = check_range(f"{name}[0]", pair[0], low, high, low_open=low_open, unit=unit)
    hi = check_range(f"{name}[1]", pair[1], lo, high, unit=unit)
    return lo, hi


def _check_list(name: str, value) -> None:
    if isinstance(value, str) or not isinstance(value, Sequence):
        raise ValueError(f"{name} = {value!r} must be a list, e.g. [a, b]")
