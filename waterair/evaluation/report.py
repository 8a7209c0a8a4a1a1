"""What an evaluation writes: metrics.json, metrics.csv, the figures and report.md (docs/evaluation.md)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from waterair.core.files import atomic_write_csv, atomic_write_json, atomic_write_text
from waterair.evaluation import plots
from waterair.evaluation.comparisons import COMPARISON_KEYS, WHERE
from waterair.evaluation.divergence import best_divergences, learned_gains
from waterair.evaluation.figures import physics_figures
from waterair.evaluation.metrics import ACQUISITION_SECONDS, HELD, METRICS, PHASE_METRICS
from waterair.evaluation.runner import UPPER_BOUND, Evaluation
from waterair.evaluation.scenarios import setting_label
from waterair.physics.link import fec_power

SCHEMA_VERSION = 8
"""8: the setting of the ends per row (``drone_speed``, ``drone_attitude_deg``, ``parked``, ``dt``, ``actuator``;
None but in S6 and S7, which are new) and S6's and S7's ``settings``; 6: ``rate_held`` and ``rate_held_999`` with
their bounds, per row and per phase, and ``comparisons``, each learned policy against its classical base at every
point; 5: ``rate_held_999`` and the acquisition's and the tracking's metrics apart (``acquisition_<name>``,
``tracking_<name>``) per row; 4: ``divergence``, ``received_power_dbm`` and ``rate_held`` per row, S5 and its
``power_sweep``; 3: the link budget's ``ber``, ``outage`` and ``rate`` per row, ``link`` at the top; 2's ``outage``
(P(G < 0.1 G_0)) is ``fade_10db``."""
AXES = ("wind", "offset_ratio", "offset_azimuth_deg")
"""The three coordinates of a scenario point, in order."""
ROW_KEYS = (
    *WHERE,
    "policy",
    "kind",
    *(f"{name}{suffix}" for name in (*METRICS, "received_power_dbm", *HELD) for suffix in ("", "_lo", "_hi")),
    *(
        f"{phase}_{name}{suffix}"
        for phase in ("acquisition", "tracking")
        for name in PHASE_METRICS
        for suffix in (("", "_lo", "_hi") if name in METRICS or name in HELD else ("",))
    ),
    "reference_gain",
    "realisations",
    "steps",
    "seed",
)
"""Columns of metrics.csv and the keys of every ``rows`` entry of metrics.json (docs/results.md)."""
POWER_KEYS = ("policy", "offset_ratio", "power_w", "outage", "outage_lo", "outage_hi", "no_light")
"""Columns of outage_vs_power.csv and of metrics.json's ``power_sweep`` (S5)."""


def write_outputs(result: Evaluation, out: Path, cfg: DictConfig, physics: bool = True) -> list[Path]:
    """metrics.json, metrics.csv, every figure and report.md in ``out``; returns the files written."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = [_write_json(result, out / "metrics.json", cfg), _write_csv(result, out / "metrics.csv")]
    if result.power_rows:
        written.append(atomic_write_csv(out / "outage_vs_power.csv", POWER_KEYS, result.power_rows))
    figures = plots.evaluation_figures(result, out)
    if physics:
        figures += physics_figures(out, result.env.sea)
    written += figures
    written.append(_write_report(result, out / "report.md", figures))
    return written


def _write_json(result: Evaluation, path: Path, cfg: DictConfig) -> Path:
    data = {
        "schema_version": SCHEMA_VERSION,
        "device": result.device,
        "seconds": round(result.seconds, 2),
        "bootstrap": OmegaConf.to_container(cfg.bootstrap, resolve=True),
        "link": _link_summary(result),
        "policies": result.policies,
        "scenarios": [
            {
                "name": s.name,
                "title": s.title,
                "axis": s.axis,
                "points": [{"wind": w, "offset_ratio": o, "offset_azimuth_deg": a} for w, o, a in s.points],
                "realisations": s.realisations,
                "steps": s.steps,
                "seed": s.seed,
                "dt": result.dt,
                **_study(result, s),
            }
            for s in result.scenarios
        ],
        "rows": [{key: row[key] for key in ROW_KEYS} for row in result.rows],
        "power_sweep": result.power_rows,
        "comparisons": [{key: row[key] for key in COMPARISON_KEYS} for row in result.comparisons],
    }
    return atomic_write_json(path, data, records=True)


def _study(result: Evaluation, scenario) -> dict:
    """S5's own keys in metrics.json: divergences (rad), the link keys it replaces and its power sweep."""
    if not scenario.divergences:
        return {}
    if scenario.settings:
        settings = [setting.columns(result.env) | {"steps": setting.steps} for setting in scenario.settings]
        return {"divergences": list(scenario.divergences), "link": dict(scenario.link), "settings": settings}
    sweep = scenario.power_sweep
    return {
        "divergences": list(scenario.divergences),
        "link": dict(scenario.link),
        "power_sweep": None if sweep is None else {"wind": sweep.wind, "divergence": sweep.divergence,
                                                   "powers_w": list(sweep.powers)},
        "best_divergence": best_divergences(result.rows, scenario),
    }  # fmt: skip


def _link_summary(result: Evaluation) -> dict:
    """The budget's values (its ``link`` keys) and what they give: P_r per gain, P_b and the FEC limit's power."""
    link = result.link
    receiver = dataclasses.asdict(link.receiver)
    own = {k: v for k, v in vars(link).items() if k not in ("receiver", "optics")}
    own["aperture_diameter"] = link.optics.aperture_diameter
    derived = {
        "received_power_per_gain": link.received_power_per_gain,
        "background_power": link.background_power,
        "fec_power": fec_power(link),
    }
    return {**own, **receiver, **derived}


def _write_csv(result: Evaluation, path: Path) -> Path:
    return atomic_write_csv(path, ROW_KEYS, result.rows)


def _write_report(result: Evaluation, path: Path, figures: list[Path]) -> Path:
    lines = ["# waterair evaluation", ""]
    lines += [f"Device {result.device}, {result.seconds:.0f} s. Policies:", ""]
    for policy in result.policies:
        if policy["kind"] == "learned":
            trained = ", ".join(f"{k} = {v}" for k, v in policy["trained_on"].items()) or "config not found"
            lines.append(f"- **{policy['label']}**: `{policy['source']}`, {policy['frames']} frames ({trained})")
            if "per_divergence" in policy:  # a policy per divergence: each acts at the divergences nearest its own
                each = ", ".join(f"{m['divergence'] * 1e3:g} mrad `{m['source']}`" for m in policy["per_divergence"])
                lines.append(f"  - trained per beam divergence, the nearest acting at each: {each}")
    lines += [
        f"- baselines: {', '.join(p['label'] for p in result.policies if p['kind'] == 'baseline')}",
        f"- `{UPPER_BOUND}`: both ends at their best pointing, one per step for every policy (docs/model.md §4.5)",
        "",
        "Ratios are mean(G) / mean(G_UB); σ²_diff = var(G_UB − G) in m⁻⁴; G < 0.1 G_0 is the share of "
        "steps in a 10 dB fade below the calm-sea gain. Brackets are 95 % bootstrap intervals over sea "
        "realisations. σ²_diff alone rewards a policy that receives nothing (then it is var(G_UB)): read it "
        "next to the ratio.",
        "",
        f"The link (docs/model.md §9): {_link_line(result.link)}. Outage is the share of steps with a BER above "
        f"the FEC limit {result.link.fec_limit:g}; BER is the mean over steps; rate is the mean bit rate the "
        "link sustains at the FEC limit.",
        "",
    ]
    for scenario in result.scenarios:
        lines += [f"## {scenario.title}", ""]
        seconds = scenario.steps * result.dt
        length = f"{scenario.steps} steps ({seconds:g} s)"
        if scenario.settings:  # S7's settings step at periods of their own
            setting = scenario.settings[0]
            length = f"{setting.steps * (setting.dt or result.dt):g} s at every setting"
        lines += [
            f"{scenario.realisations} sea realisations × {length}, seed {scenario.seed}; every policy on the same "
            "seas.",
            "",
        ]
        if scenario.settings:
            lines += _setting_lines(result, scenario)
        elif scenario.divergences:
            lines += _divergence_lines(result, scenario)
        elif scenario.axis is None:
            point = scenario.points[0]
            lines += [
                "| policy | mean G (m⁻²) | ratio to UB | σ²_diff (m⁻⁴) | outage | mean BER | rate (Mbit/s) "
                "| held 99 % (Mbit/s) | G < 0.1 G_0 | valid paths |",
                "|---|---|---|---|---|---|---|---|---|---|",
            ]
            for policy in result.policies:
                r = result.row(scenario.name, policy["label"], point)
                lines.append(
                    f"| {policy['label']} | {r['mean_gain']:.4g} [{r['mean_gain_lo']:.4g}, {r['mean_gain_hi']:.4g}] "
                    f"| {r['ratio_to_ub']:.3f} | {r['sigma2_diff']:.3g} "
                    f"| {r['outage']:.3%} [{r['outage_lo']:.3%}, {r['outage_hi']:.3%}] | {r['ber']:.2g} "
                    f"| {r['rate'] / 1e6:.3g} | {_held(r)} | {r['fade_10db']:.2%} | {r['valid_share']:.1%} |"
                )
            lines += ["", *_phase_lines(result, scenario, point)]
        else:
            column = {"offset_ratio": "offset", "wind": "U10 (m/s)", "offset_azimuth_deg": "azimuth (deg)"}[
                scenario.axis
            ]
            values = [dict(zip(AXES, p, strict=True))[scenario.axis] for p in scenario.points]
            labels = [p["label"] for p in result.policies]
            lines += ["Ratio to the upper bound, σ²_diff (m⁻⁴) below it, and the link's outage below that:", ""]
            lines += [f"| {column} | " + " | ".join(labels) + " |", "|---" * (len(labels) + 1) + "|"]
            for point, value in zip(scenario.points, values, strict=True):
                cells = []
                for label in labels:
                    r = result.row(scenario.name, label, point)
                    cells.append(f"{r['ratio_to_ub']:.3f}<br>{r['sigma2_diff']:.2g}<br>{r['outage']:.2%}")
                shown = f"{value:.0%}" if scenario.axis == "offset_ratio" else f"{value:g}"
                lines.append(f"| {shown} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += _comparison_lines(result)
    lines += ["## Figures", ""]
    for figure in figures:
        lines += [f"![{figure.stem}]({figure.name})", ""]
    return atomic_write_text(path, "\n".join(lines))


def _phase_lines(result: Evaluation, scenario, point) -> list[str]:
    """The acquisition (an episode's first :data:`ACQUISITION_SECONDS`) and the tracking after it, apart."""
    lines = [
        f"Acquisition (the first {ACQUISITION_SECONDS:g} s of each realisation) and tracking (the rest) apart: ratio "
        "to the upper bound, mean rate and the rates held in 99 % and 99.9 % of the phase's steps (Mbit/s).",
        "",
    ]
    rows = []
    for policy in result.policies:
        r = result.row(scenario.name, policy["label"], point)
        cells = [policy["label"]]
        for phase in ("acquisition", "tracking"):
            if math.isnan(r[f"{phase}_ratio_to_ub"]):
                cells += ["–"] * 4
                continue
            cells += [f"{r[f'{phase}_ratio_to_ub']:.3f}"]
            cells += [f"{r[f'{phase}_{name}'] / 1e6:.3g}" for name in ("rate", "rate_held", "rate_held_999")]
        rows.append(cells)
    header = ("policy", *(f"{phase} {what}" for phase in ("acquisition", "tracking")
                          for what in ("ratio", "rate", "held 99 %", "held 99.9 %")))  # fmt: skip
    return lines + _table(header, rows)


def _divergence_lines(result: Evaluation, scenario) -> list[str]:
    """S5: rate, held rate and outage per divergence at every point; each policy's best divergence; what the
    learned policies gain there; outage against transmit power."""
    labels = [p["label"] for p in result.policies]
    link = result.link_of(scenario.name, scenario.divergences[0])
    lines = [
        f"The study's link: {_link_line(link)} (at ω_D = {scenario.divergences[0] * 1e3:g} mrad; a narrower beam "
        "puts more power on the receiver per unit of gain, J_0/P_t = 2/(π ω_D′²)). Each cell: mean bit rate at "
        "the FEC limit (Mbit/s), the rates held in 99 % (its interval in brackets) and in 99.9 % of steps, and the "
        "outage.",
        "",
    ]
    for wind, offset, azimuth in scenario.points:
        lines += [f"**U10 = {wind:g} m/s, offset {offset:.0%}**", ""]
        lines += ["| ω_D (mrad) | " + " | ".join(labels) + " |", "|---" * (len(labels) + 1) + "|"]
        for divergence in scenario.divergences:
            rows = [result.row(scenario.name, label, (wind, offset, azimuth), divergence) for label in labels]
            cells = [
                f"{r['rate'] / 1e6:.3g}<br>{_held(r)}<br>{r['rate_held_999'] / 1e6:.3g}<br>{r['outage']:.1%}"
                for r in rows
            ]
            lines.append(f"| {divergence * 1e3:g} | " + " | ".join(cells) + " |")
        lines.append("")
    best = best_divergences(result.rows, scenario)
    lines += ["### Each policy's best divergence", "", "Where its mean rate is highest (ties: the widest beam).", ""]
    lines += _table(
        ("U10 (m/s)", "offset", "policy", "ω_D (mrad)", "rate (Mbit/s)", "held 99 %", "held 99.9 %", "P_r (dBm)",
         "outage"),
        [
            (f"{b['wind']:g}", f"{b['offset_ratio']:.0%}", b["policy"], f"{b['divergence'] * 1e3:g}",
             f"{b['rate'] / 1e6:.3g}", f"{b['rate_held'] / 1e6:.3g}", f"{b['rate_held_999'] / 1e6:.3g}",
             f"{b['received_power_dbm']:.1f}", f"{b['outage']:.2%}")
            for b in best
        ],
    )  # fmt: skip
    gains = learned_gains(best, result.policies)
    if gains:
        lines += ["", "### What the learned policies gain, each at its best divergence", ""]
        lines += _table(
            ("U10 (m/s)", "offset", "learned", "over", "P_r (dB)", "rate (Mbit/s)", "held 99 % (Mbit/s)"),
            [
                (f"{g['wind']:g}", f"{g['offset_ratio']:.0%}", g["policy"], g["baseline"], f"{g['db']:+.2f}",
                 f"{g['rate'] / 1e6:+.3g}", f"{g['rate_held'] / 1e6:+.3g}")
                for g in gains
            ],
        )  # fmt: skip
    sweep = scenario.power_sweep
    if sweep is not None and result.power_rows:
        where = f"U10 = {sweep.wind:g} m/s, ω_D = {sweep.divergence * 1e3:g} mrad"
        lines += ["", f"### Outage against transmit power, {where}", "",
                  "The share of steps with no light at all is the floor that no power lifts.", ""]  # fmt: skip
        powers = list(sweep.powers)
        lines += ["| policy | offset | " + " | ".join(f"{p * 1e3:g} mW" for p in powers) + " | no light |",
                  "|---" * (len(powers) + 3) + "|"]  # fmt: skip
        keyed = {(r["policy"], r["offset_ratio"], r["power_w"]): r for r in result.power_rows}
        for label in labels:
            for offset in dict.fromkeys(r["offset_ratio"] for r in result.power_rows):
                cells = [f"{keyed[(label, offset, p)]['outage']:.2%}" for p in powers]
                floor = keyed[(label, offset, powers[0])]["no_light"]
                lines.append(f"| {label} | {offset:.0%} | " + " | ".join(cells) + f" | {floor:.2%} |")
    return [*lines, ""]


TRACKED = "tracking_rate_held"
"""What S6 and S7 compare: the rate held 99 % of the time once tracking."""


def _setting_lines(result: Evaluation, scenario) -> list[str]:
    """S6 or S7: the rate held 99 % of the tracking's steps (Mbit/s, with its interval) of every policy at each
    setting, a table per point and actuator: after the acquisition, whose start-up (a filter's first estimates, a
    slow actuator's first steps) would otherwise set the 1 % tail of a short rollout."""
    period = scenario.name == "S7"
    link = _link_line(result.link_of(scenario.name, scenario.divergences[0]))
    lines = [f"Each setting of the ends is a batch of its own ({link}); the rate held in 99 % of the tracking's "
             f"steps (after the first {ACQUISITION_SECONDS:g} s, the acquisition, whose start-up would set a short "
             "rollout's tail: `acquisition_rate_held` in metrics.json), Mbit/s, with its 95 % interval:",
             ""]  # fmt: skip
    rows = [r for r in result.rows if r["scenario"] == scenario.name]
    for point in scenario.points:
        for actuator in dict.fromkeys(r["actuator"] for r in rows):
            mine = [r for r in rows if _point(r) == point and r["actuator"] == actuator]
            named = [(setting_label(r, period).removeprefix(f"{actuator}, "), r) for r in mine]
            settings = list(dict.fromkeys(name for name, _ in named))
            held = {(name, r["policy"]): _held(r, TRACKED) for name, r in named}
            lines += [f"U10 = {point[0]:g} m/s, offset {point[1]:.0%}, {actuator}:", ""]
            table = [(p["label"], *(held.get((name, p["label"]), "") for name in settings)) for p in result.policies]
            lines += [*_table(("policy", *settings), table), ""]
    return lines


def _point(row: dict) -> tuple:
    return row["wind"], row["offset_ratio"], row["offset_azimuth_deg"]


def _held(row: dict, name: str = "rate_held") -> str:
    """A held rate in Mbit/s with its interval."""
    return f"{row[name] / 1e6:.3g} [{row[f'{name}_lo'] / 1e6:.3g}, {row[f'{name}_hi'] / 1e6:.3g}]"


def _comparison_lines(result: Evaluation) -> list[str]:
    """Each learned policy against its classical base at every point: the paired differences and ratios."""
    if not result.comparisons:
        return []
    lines = [
        "## Learned policies against their classical bases",
        "",
        "Each learned policy against the controller its residual actions correct, sensing as it does, on the same "
        "seas: the difference in ratio to the upper bound and the ratio of the rates held in 99 % of steps, each "
        "with its 95 % paired bootstrap interval (both policies' seas resampled together). *ahead* or *behind* "
        "where the held rates' interval excludes 1, else *not separable*; *neither holds* where both hold under "
        "1 kbit/s (no link: their ratio is undefined).",
        "",
    ]
    rows = []
    for c in result.comparisons:
        point = f"{c['wind']:g} m/s, {c['offset_ratio']:.0%}" + (
            f", {c['divergence'] * 1e3:g} mrad" if result.scenario(c["scenario"]).divergences else ""
        )
        if c["actuator"] is not None:  # S6, S7: at a setting of the ends
            point += f", {setting_label(c, period=c['scenario'] == 'S7')}"
        rows.append((c["scenario"], point, c["policy"], c["base"],
                     f"{c['ratio_to_ub_diff']:+.4f} [{c['ratio_to_ub_diff_lo']:+.4f}, {c['ratio_to_ub_diff_hi']:+.4f}]",
                     _held_ratio(c),
                     c["rate_held_verdict"]))  # fmt: skip
    header = ("scenario", "point", "learned", "base", "ratio to UB: difference", "held 99 %: ratio", "held rate")
    return [*lines, *_table(header, rows), ""]


def _held_ratio(comparison: dict) -> str:
    """The held rates' ratio with its interval, or ``—`` where it is undefined (both hold nothing)."""
    c = comparison
    if math.isnan(c["rate_held_ratio"]):
        return "—"
    return f"{c['rate_held_ratio']:.3f} [{c['rate_held_ratio_lo']:.3f}, {c['rate_held_ratio_hi']:.3f}]"


def _table(header, rows) -> list[str]:
    """A markdown table: the ``header`` cells, a rule, then one line per row of cells."""
    return [" | ".join(("", *header, "")).strip(), "|---" * len(header) + "|"] + [
        " | ".join(("", *row, "")).strip() for row in rows
    ]


def _link_line(link) -> str:
    """E.g. ``50 mW at 520 nm, APD (M = 40) with a 40 MHz front end, background 0.005 W/(m² sr nm), 10 Mbit/s OOK``."""
    receiver = f"APD (M = {link.receiver.gain:g})" if link.receiver.gain > 1 else "PIN photodiode"
    receiver += f" with a {link.receiver.cutoff_hz / 1e6:g} MHz front end"
    return (
        f"{link.power_w * 1e3:g} mW at {link.optics.wavelength * 1e9:g} nm, {receiver}, background "
        f"{link.background_radiance:g} W/(m² sr nm), {link.bit_rate / 1e6:g} Mbit/s OOK; in outage below "
        f"P_r = {fec_power(link) * 1e9:.3g} nW, G = {fec_power(link) / link.received_power_per_gain:.3g} m⁻²"
    )
