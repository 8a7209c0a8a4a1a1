"""Evaluation scenarios S1-S4 (docs/evaluation.md): which points, how many seas, how long.

A point is (wind U10 in m/s, offset ratio, drone azimuth in degrees from the wind direction +x).

* S1: a time trace at one point (the paper's "gain over time").
* S2: a horizontal-offset sweep (the paper's "average gain" and "σ²_diff").
* S3: a wind sweep (the paper's planned study).
* S4: a sweep of the drone's azimuth around the transmitter (the sea is not isotropic).
* S5: link rate against beam divergence: winds × offsets, each at every divergence ω_D, on a link budget of its
  own (``scenarios.S5.link``), with outage against transmit power at one of its points.
"""

from __future__ import annotations

from dataclasses import dataclass

from omegaconf import DictConfig, ListConfig, OmegaConf

from waterair.core.validation import check_int, check_range


@dataclass(frozen=True)
class PowerSweep:
    """Outage against transmit power at ``wind`` (m/s) and ``divergence`` (rad), every offset of S5."""

    wind: float
    divergence: float
    powers: tuple[float, ...]  # W


@dataclass(frozen=True)
class Scenario:
    """One evaluation scenario: points (wind m/s, offset ratio, azimuth deg), each over the same realisations."""

    name: str
    title: str
    axis: str | None  # the swept quantity: "offset_ratio", "wind", "offset_azimuth_deg" or "divergence"; None for S1
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


def scenarios_from_config(cfg: DictConfig) -> list[Scenario]:
    """S1 (time trace), S2 (offset), S3 (wind), S4 (azimuth) and S5 (divergence) from ``cfg.scenarios``; null (or
    absent) skips one."""
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
    if not out:
        raise ValueError("scenarios: every scenario is null; nothing to evaluate")
    return out


def _divergence_study(s: DictConfig, common: tuple[int, int, int]) -> Scenario:
    """S5 from ``scenarios.S5``: every (wind, offset) at every divergence, its link and its power sweep."""
    key = "scenarios.S5"
    divergences = _grid(f"{key}.divergences_mrad", s.divergences_mrad, 0.5, 1000.0, "mrad")
    winds = _grid(f"{key}.winds", s.winds, 0.0, 60.0, "m/s", low_open=True)
    offsets = _grid(f"{key}.offset_ratios", s.offset_ratios, 0.0, 10.0, "")
    link = OmegaConf.to_container(s.link, resolve=True) if s.get("link") is not None else {}
    if not isinstance(link, dict):
        raise ValueError(f"{key}.link = {link!r} must be a mapping of link keys (e.g. {{power_w: 0.001}})")
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
    return Scenario("S5", title, "divergence", points, *common, rad, tuple(sorted(link.items())), sweep)


def _grid(key: str, values, low: float, high: float, unit: str, low_open: bool = False) -> tuple[float, ...]:
    values = list(values) if isinstance(values, ListConfig | list | tuple) else [values]
    if not values:
        raise ValueError(f"{key} = [] must list at least one value")
    return tuple(check_range(f"{key}[{i}]", v, low, high, low_open=low_open, unit=unit) for i, v in enumerate(values))
