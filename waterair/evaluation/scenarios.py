"""Evaluation scenarios S1-S7 (docs/evaluation.md): which points, how many seas, how long.

A point is (wind U10 in m/s, offset ratio, drone azimuth in degrees from the wind direction +x).

* S1: a time trace at one point (the paper's "gain over time").
* S2: a horizontal-offset sweep (the paper's "average gain" and "σ²_diff").
* S3: a wind sweep (the paper's planned study).
* S4: a sweep of the drone's azimuth around the transmitter (the sea is not isotropic).
* S5: link rate against beam divergence: winds × offsets, each at every divergence ω_D, on a link budget of its
  own (``scenarios.S5.link``), with outage against transmit power at one of its points.
* S6: the ends moving (``env.motion``) and slewing (``env.actuator``): the rate held against the drone's speed
  across the link, each speed also parked on its crossing (the same geometry standing still), and against the
  drone's attitude jitter hovering.
* S7: the rate held against the loop period ``env.dt``, with each actuator, over the same seconds.

S6 and S7 run each :class:`Setting` of the ends as a batch of its own, eager (each setting is a step of its own):
``+scenarios=moving`` runs them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from omegaconf import DictConfig, ListConfig, OmegaConf

from waterair.core.validation import check_choice, check_int, check_range
from waterair.envs.config import EnvConfig
from waterair.physics.actuator import TERMINALS
from waterair.physics.motion import MOTIONS

SETTING_COLUMNS = ("drone_speed", "drone_attitude_deg", "parked", "dt", "actuator")
"""The row columns of a :class:`Setting` (S6, S7): the drone's speed (m/s), its roll and pitch σ (deg), whether it
stands parked on its crossing, the loop period (s) and the ends' actuator; None in the other scenarios' rows."""


@dataclass(frozen=True)
class PowerSweep:
    """Outage against transmit power at ``wind`` (m/s) and ``divergence`` (rad), every offset of S5."""

    wind: float
    divergence: float
    powers: tuple[float, ...]  # W


@dataclass(frozen=True)
class Setting:
    """One setting of the ends a study (S6, S7) runs all its points at; None keeps the scenario env's value.

    ``speed``: the drone crossing the link (m/s), over its home half-way through the rollout (0: hovering);
    ``parked``: instead standing still where that crossing is at a time drawn per link; ``attitude``: σ of the
    drone's roll and pitch (rad); ``dt``: the loop period (s), at the env's episode length in seconds;
    ``actuator``: each end's; ``motion``: the ends' motion where ``speed`` is None; ``steps``: the rollout's.
    """

    steps: int
    speed: float | None = None
    parked: bool = False
    attitude: float | None = None
    dt: float | None = None
    actuator: str | None = None
    motion: str | None = None

    def changes(self, env: EnvConfig) -> dict:
        """The env keys this setting replaces in ``env`` (:meth:`EnvConfig.replace`'s)."""
        motion, dt = {}, self.dt or env.dt
        if self.speed is not None:
            kind = "parked" if self.parked else "transit" if self.speed > 0 else "hover"
            motion = {"kind": kind, "transit_speed": self.speed, "crossing_time": 0.5 * self.steps * dt}
        elif self.motion is not None:
            motion = {"kind": self.motion}
        if self.attitude is not None:
            motion["drone_attitude"] = self.attitude
        changes = {"motion": motion} if motion else {}
        if self.actuator is not None:
            changes["actuator"] = {"kind": self.actuator}
        if self.dt is not None:  # the same episode in seconds: the observation's time means what it did
            changes |= {"dt": self.dt, "max_steps": max(1, round(env.episode_seconds / self.dt))}
        return changes

    def applied(self, env: EnvConfig, eager: bool = False) -> EnvConfig:
        """``env`` at this setting (:meth:`changes`), uncompiled with ``eager``."""
        changed = env.replace(**self.changes(env))
        return changed.replace(compile_kernel=False) if eager else changed

    def name(self, env: EnvConfig) -> str:
        """How a progress line names this setting in ``env`` (:func:`setting_label`)."""
        return setting_label(self.columns(env), period=self.dt is not None)

    def columns(self, env: EnvConfig) -> dict:
        """This setting's :data:`SETTING_COLUMNS` in ``env`` changed by it (:meth:`changes`)."""
        moved = self.applied(env)
        motion = moved.motion
        speed = motion.transit_speed if motion.kind in ("transit", "parked") else 0.0
        return {
            "drone_speed": speed,
            "drone_attitude_deg": math.degrees(motion.drone_attitude) if motion.moves else 0.0,
            "parked": motion.kind == "parked",
            "dt": moved.dt,
            "actuator": moved.actuator.kind,
        }


def setting_label(columns: dict, period: bool) -> str:
    """A setting's :data:`SETTING_COLUMNS` ``columns`` (a row's) in words: ``1.5 m/s parked, 1° drone`` (S6), or
    with ``period`` ``gimbal_fsm, 5 ms`` (S7)."""
    if period:
        return f"{columns['actuator']}, {columns['dt'] * 1e3:g} ms"
    parked = " parked" if columns["parked"] else ""
    return f"{columns['drone_speed']:g} m/s{parked}, {columns['drone_attitude_deg']:g}° drone"


@dataclass(frozen=True)
class Scenario:
    """One evaluation scenario: points (wind m/s, offset ratio, azimuth deg), each over the same realisations."""

    name: str
    title: str
    axis: str | None  # the swept quantity: "offset_ratio", "wind", "offset_azimuth_deg", "divergence", "drone_speed"
    # or "dt"; None for S1
    points: tuple[tuple[float, float, float], ...]
    realisations: int
    steps: int
    seed: int
    divergences: tuple[float, ...] = ()
    """S5: the beam divergences ω_D (rad) every point runs at; empty: the ``env`` group's."""
    link: tuple[tuple[str, object], ...] = ()
    """S5: ``link`` keys this scenario replaces (key, value)."""
    power_sweep: PowerSweep | None = None
    """S5: outage against transmit power, from the rollouts at one wind and divergence."""
    settings: tuple[Setting, ...] = ()
    """S6, S7: the settings of the ends every point runs at, each a batch of its own."""


def scenarios_from_config(cfg: DictConfig) -> list[Scenario]:
    """S1 (time trace), S2 (offset), S3 (wind), S4 (azimuth), S5 (divergence), S6 (the drone's speed and attitude)
    and S7 (the loop period) from ``cfg.scenarios``; null (or absent) skips one."""
    spec, out = cfg.scenarios, []

    def common(name):
        s = spec[name]
        return (
            check_int(f"scenarios.{name}.realisations", s.realisations, 1, 1 << 20),
            check_int(f"scenarios.{name}.steps", s.steps, 1, 10**7),
            check_int(f"scenarios.{name}.seed", s.seed, 0, 2**63 - 1),
        )

    if spec.get("S1") is not None:
        wind = check_range("scenarios.S1.wind", spec.S1.wind, 0.0, 60.0, low_open=True, unit="m/s")
        offset = check_range("scenarios.S1.offset_ratio", spec.S1.offset_ratio, 0.0, 10.0)
        title = f"S1: gain over time, U10 = {wind:g} m/s, offset {offset:.0%}"
        out.append(Scenario("S1", title, None, ((wind, offset, 0.0),), *common("S1")))
    if spec.get("S2") is not None:
        wind = check_range("scenarios.S2.wind", spec.S2.wind, 0.0, 60.0, low_open=True, unit="m/s")
        offsets = _grid("scenarios.S2.offset_ratios", spec.S2.offset_ratios, 0.0, 10.0, "")
        title = f"S2: horizontal offset sweep, U10 = {wind:g} m/s"
        out.append(Scenario("S2", title, "offset_ratio", tuple((wind, o, 0.0) for o in offsets), *common("S2")))
    if spec.get("S3") is not None:
        offset = check_range("scenarios.S3.offset_ratio", spec.S3.offset_ratio, 0.0, 10.0)
        winds = _grid("scenarios.S3.winds", spec.S3.winds, 0.0, 60.0, "m/s", low_open=True)
        title = f"S3: wind sweep, offset {offset:.0%}"
        out.append(Scenario("S3", title, "wind", tuple((w, offset, 0.0) for w in winds), *common("S3")))
    if spec.get("S4") is not None:
        wind = check_range("scenarios.S4.wind", spec.S4.wind, 0.0, 60.0, low_open=True, unit="m/s")
        offset = check_range("scenarios.S4.offset_ratio", spec.S4.offset_ratio, 0.0, 10.0)
        azimuths = _grid("scenarios.S4.azimuths_deg", spec.S4.azimuths_deg, -360.0, 360.0, "deg")
        title = f"S4: drone azimuth sweep, U10 = {wind:g} m/s, offset {offset:.0%}"
        points = tuple((wind, offset, a) for a in azimuths)
        out.append(Scenario("S4", title, "offset_azimuth_deg", points, *common("S4")))
    if spec.get("S5") is not None:
        out.append(_divergence_study(spec.S5, common("S5")))
    if spec.get("S6") is not None:
        out.append(_speed_study(spec.S6, common("S6")))
    if spec.get("S7") is not None:
        out.append(_period_study(spec.S7))
    if not out:
        raise ValueError("scenarios: every scenario is null; nothing to evaluate")
    return out


def _divergence_study(s: DictConfig, common: tuple[int, int, int]) -> Scenario:
    """S5 from ``scenarios.S5``: every (wind, offset) at every divergence, its link and its power sweep."""
    key = "scenarios.S5"
    divergences = _grid(f"{key}.divergences_mrad", s.divergences_mrad, 0.5, 1000.0, "mrad")
    winds = _grid(f"{key}.winds", s.winds, 0.0, 60.0, "m/s", low_open=True)
    offsets = _grid(f"{key}.offset_ratios", s.offset_ratios, 0.0, 10.0, "")
    link = _link(key, s)
    sweep = None
    if s.get("power_sweep") is not None:
        p = s.power_sweep
        wind = check_range(f"{key}.power_sweep.wind", p.wind, 0.0, 60.0, low_open=True, unit="m/s")
        divergence = check_range(f"{key}.power_sweep.divergence_mrad", p.divergence_mrad, 0.5, 1000.0, unit="mrad")
        for name, value, grid in (("wind", wind, winds), ("divergence_mrad", divergence, divergences)):
            if value not in grid:
                raise ValueError(f"{key}.power_sweep.{name} = {value:g} must be one of {key}'s: {list(grid)}")
        powers = _grid(f"{key}.power_sweep.powers_w", p.powers_w, 0.0, 1.0e3, "W", low_open=True)
        sweep = PowerSweep(wind, divergence * 1e-3, powers)
    points = tuple((w, o, 0.0) for w in winds for o in offsets)
    title = f"S5: link rate against beam divergence, {len(winds)} winds × {len(offsets)} offsets"
    rad = tuple(d * 1e-3 for d in divergences)
    return Scenario("S5", title, "divergence", points, *common, rad, link, sweep)


S6_KEYS = {"winds", "offset_ratio", "divergence_mrad", "speeds", "attitude_deg", "attitudes_deg", "actuator",
           "realisations", "steps", "seed", "link"}  # fmt: skip
S7_KEYS = {"wind", "offset_ratio", "divergence_mrad", "periods_ms", "actuators", "motion", "seconds",
           "realisations", "seed", "link"}  # fmt: skip


def _speed_study(s: DictConfig, common: tuple[int, int, int]) -> Scenario:
    """S6 from ``scenarios.S6``: every wind at each speed of the drone crossing the link (each also parked) at
    ``attitude_deg``, then hovering at each of ``attitudes_deg``, all on ``actuator``."""
    key = "scenarios.S6"
    _known(key, s, S6_KEYS)
    winds = _grid(f"{key}.winds", s.winds, 0.0, 60.0, "m/s", low_open=True)
    offset = check_range(f"{key}.offset_ratio", s.offset_ratio, 0.0, 10.0)
    divergence = check_range(f"{key}.divergence_mrad", s.divergence_mrad, 0.5, 1000.0, unit="mrad") * 1e-3
    speeds = _grid(f"{key}.speeds", s.speeds, 0.0, 50.0, "m/s")
    attitude = math.radians(check_range(f"{key}.attitude_deg", s.attitude_deg, 0.0, 28.0, unit="deg"))
    attitudes = [math.radians(a) for a in _grid(f"{key}.attitudes_deg", s.attitudes_deg, 0.0, 28.0, "deg")]
    actuator = check_choice(f"{key}.actuator", s.actuator, TERMINALS)
    steps = common[1]
    settings = [Setting(steps, v, parked, attitude, actuator=actuator) for v in speeds for parked in (False, True)
                if v > 0 or not parked]  # fmt: skip
    settings += [Setting(steps, 0.0, False, a, actuator=actuator) for a in attitudes]
    points = tuple((w, offset, 0.0) for w in winds)
    title = f"S6: rate held against the drone's speed and attitude, {actuator}, {divergence * 1e3:g} mrad"
    return Scenario("S6", title, "drone_speed", points, *common, (divergence,), _link(key, s),
                    settings=tuple(dict.fromkeys(settings)))  # fmt: skip


def _period_study(s: DictConfig) -> Scenario:
    """S7 from ``scenarios.S7``: its point at every loop period with each actuator, over the same ``seconds``."""
    key = "scenarios.S7"
    _known(key, s, S7_KEYS)
    wind = check_range(f"{key}.wind", s.wind, 0.0, 60.0, low_open=True, unit="m/s")
    offset = check_range(f"{key}.offset_ratio", s.offset_ratio, 0.0, 10.0)
    divergence = check_range(f"{key}.divergence_mrad", s.divergence_mrad, 0.5, 1000.0, unit="mrad") * 1e-3
    periods = _grid(f"{key}.periods_ms", s.periods_ms, 0.1, 1000.0, "ms")
    actuators = [check_choice(f"{key}.actuators[{i}]", a, TERMINALS) for i, a in enumerate(s.actuators)]
    motion = check_choice(f"{key}.motion", s.motion, MOTIONS)
    seconds = check_range(f"{key}.seconds", s.seconds, 0.0, 1.0e4, low_open=True, unit="s")
    realisations = check_int(f"{key}.realisations", s.realisations, 1, 1 << 20)
    seed = check_int(f"{key}.seed", s.seed, 0, 2**63 - 1)
    settings = tuple(Setting(max(1, round(seconds / (p * 1e-3))), dt=p * 1e-3, actuator=a, motion=motion)
                     for a in actuators for p in periods)  # fmt: skip
    title = f"S7: rate held against the loop period, each actuator, U10 = {wind:g} m/s, {divergence * 1e3:g} mrad"
    steps = max(setting.steps for setting in settings)
    return Scenario("S7", title, "dt", ((wind, offset, 0.0),), realisations, steps, seed, (divergence,),
                    _link(key, s), settings=settings)  # fmt: skip


def _known(key: str, s: DictConfig, allowed: set[str]) -> None:
    unknown = sorted(set(s) - allowed)
    if unknown:
        raise ValueError(f"{key}.{unknown[0]} is not a key of {key}; its keys: {', '.join(sorted(allowed))}")


def _link(key: str, s: DictConfig) -> tuple:
    link = OmegaConf.to_container(s.link, resolve=True) if s.get("link") is not None else {}
    if not isinstance(link, dict):
        raise ValueError(f"{key}.link = {link!r} must be a mapping of link keys (e.g. {{power_w: 0.001}})")
    return tuple(sorted(link.items()))


def _grid(key: str, values, low: float, high: float, unit: str, low_open: bool = False) -> tuple[float, ...]:
    values = list(values) if isinstance(values, ListConfig | list | tuple) else [values]
    if not values:
        raise ValueError(f"{key} = [] must list at least one value")
    return tuple(check_range(f"{key}[{i}]", v, low, high, low_open=low_open, unit=unit) for i, v in enumerate(values))
