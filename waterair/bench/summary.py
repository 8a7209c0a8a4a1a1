"""The speed targets as ratios: ``python -m waterair.bench summary DIR`` reads the suites' JSON files.

Each ratio comes from numbers measured in one round of a suite (one process tree, one machine, both sides of a
pair in turn), so they are comparable; the summary only divides and prints them beside their targets. A suite
run over several rounds (``--rounds N``: its JSON holds ``rounds``) is judged on each ratio's median over them,
the spread printed beside it: on these machines one round's ratio drifts 15-30 %.
"""

from __future__ import annotations

import json
import statistics
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

PAPER_FRAMES = 250_000

SEEDS_TO_JUDGE = 5
"""The fewest training seeds over which the time-to-quality target is judged: of the same code on the flat base,
seeds 0-2 read 10.5x and seeds 0-4 7.4x (docs/benchmarks.md, "Time to quality")."""


@dataclass(frozen=True)
class Row:
    """One target's row of one round: what it shows, and the number it judges (with how to judge and show it)."""

    name: str
    shown: str
    target: str
    value: float | None = None
    judge: Callable[[float], bool] | None = None  # None: shown, not judged
    form: str = "{:.2f}"

    def met(self, value: float | None) -> bool | None:
        """Whether ``value`` meets the target (None: not judged)."""
        return None if self.judge is None or value is None else self.judge(value)


def rounds(folder: Path, suite: str) -> list[dict]:
    """The rounds of ``suite``'s JSON in ``folder`` (one for a record of one round), or none."""
    path = folder / f"{suite}.json"
    if not path.exists():
        return []
    record = json.loads(path.read_text())
    return record["rounds"] if "rounds" in record else [record]


def summary_lines(folder: Path) -> list[str]:
    """One table row per target: what was measured, the ratio, the target, met or not; over several rounds the
    median's (its spread beside it), then a line that says so."""
    suites = {suite: rounds(folder, suite) for suite in ("env", "channel", "training", "quality")}
    count = max((len(each) for each in suites.values()), default=1)
    by_name: dict[str, list[Row]] = {}
    for index in range(count):
        for row in _round_rows(lambda suite, i=index: suites[suite][i] if i < len(suites[suite]) else None):
            by_name.setdefault(row.name, []).append(row)
    lines = ["| quantity | measured | target | met |", "|---|---|---|---|", *(_line(rows) for rows in by_name.values())]
    judged = sorted({len(rows) for rows in by_name.values() if len(rows) > 1})
    if judged:
        lines += ["", f"Judged on the median of {' or '.join(map(str, judged))} rounds, each a whole run of its suite."]
    return lines


def _line(rows: list[Row]) -> str:
    """A target's table line: its one round as measured, or the median of its rounds, judged."""
    first = rows[0]
    shown, met = first.shown, first.met(first.value)
    if len(rows) > 1 and first.value is not None:
        values = [row.value for row in rows if row.value is not None]
        median = statistics.median(values)
        spread = f"{first.form.format(min(values))}–{first.form.format(max(values))}"
        shown = f"{first.form.format(median)} (median of {len(values)}; {spread})"
        met = first.met(median)
    return f"| {first.name} | {shown} | {first.target} | {'–' if met is None else ('yes' if met else 'no')} |"


def _round_rows(load: Callable[[str], dict | None]) -> list[Row]:
    """The rows of one round of the suites ``load`` gives (None: a suite not run, or not in this round)."""
    rows: list[Row] = []

    def row(name: str, shown: str, target: str, value=None, judge=None, form="{:.2f}") -> None:
        rows.append(Row(name, shown, target, value, judge, form))

    env = load("env")
    if env is not None:
        by_batch = {r["batch"]: r for r in env["rows"] if r["solver"] == "newton"}
        for batch, target in ((1024, 100_000), (16, 20_000)):
            if batch in by_batch:
                rate = by_batch[batch]["env_steps_per_s"]
                judge = lambda v, t=target: v >= t  # noqa: E731
                name = f"env-steps/s at B = {batch}"
                row(name, f"{rate:,.0f}", f"≥ {target:,}", rate, judge, "{:,.0f}")
        if 1024 in by_batch:
            r = by_batch[1024]
            row(
                "step / (evaluations × sin+cos floor), B = 1024",
                f"{r['floor_ratio']:.2f} ({r['evaluations_per_step']:.0f} evaluations)",
                "≤ 1.5",
                r["floor_ratio"],
                lambda v: v <= 1.5,
            )
        if "compile" in env:
            c = env["compile"]
            cold_warm = f"{c['cold_s']:.0f} / {c['warm_s']:.0f}"
            row("compile, cold / warm cache (s)", cold_warm, "paid once per machine")
    channel = load("channel")
    if channel is not None:
        _channel_rows(channel, row)
    training = load("training")
    if training is not None:
        update = training["update"]
        row(
            "DDPG update / bare PyTorch (compiled, eager)",
            f"{update['ratio_compiled']:.2f}, {update['ratio_eager']:.2f}",
            "≤ 1.2",
            update["ratio_compiled"],
            lambda v: v <= 1.2,
        )
        for run in training["runs"]:
            if run["default"] and "over_sb3" in run:  # the mode train.py's auto runs at that length
                row(
                    f"train.py / SB3 DDPG frames/s, whole loop, {run['frames']:,} frames ({run['mode']})",
                    f"{run['over_sb3']:.1f}",
                    "none: what counts is the time to quality (below)",
                    run["over_sb3"],
                    None,
                    "{:.1f}",
                )
        for busy in (training.get("load") or {}).get("rows", []):
            ratio, name = (
                busy["loaded_over_quiet"],
                f"train.py frames/s beside a busy process / quiet, threads={busy['threads']}",
            )
            if busy["threads"] == str(training["threads"]["setting"]):
                row(name, f"{ratio:.2f}", "≥ 0.5", ratio, lambda v: v >= 0.5)
            else:  # torch's own count: the behaviour before the threads key
                row(name, f"{ratio:.2f}", "(before threads)", ratio)
        ddpg = training["train_ddpg"]  # the paper preset is DDPG; a long run's rate past its compiles
        minutes = PAPER_FRAMES / (ddpg["loop_after_first_batch_frames_per_s"] or ddpg["loop_frames_per_s"]) / 60
        paper = "paper budget (250,000 frames) at train.py's rate"
        row(paper, f"{minutes:.1f} min", "≤ 6 min", minutes, lambda v: v <= 6, "{:.1f} min")
    quality = load("quality") or {}
    flat = {
        key.removeprefix("sb3_flat_base_over_"): ratio for key, ratio in quality.items() if "flat_base_over_" in key
    }
    to = f"SB3's best seconds to {quality.get('target')} of the bound"

    def measured(mine: str) -> str:
        return f"{'at least ' if mine.endswith('_at_least') else ''}{flat[mine]:.1f}"

    for mine in flat:  # each of our pipelines: compiled, and eager (what auto runs at these budgets) when measured
        row(f"{to} / {mine.removesuffix('_at_least')}'s", measured(mine), "–", flat[mine], None, "{:.1f}")
    if flat:  # SB3's best pipeline against ours, each from scratch, its compiles counted where it compiles
        best = max(flat, key=flat.__getitem__)
        name = f"{to} / our best pipeline's ({best.removesuffix('_at_least')})"
        seeds = len(quality.get("seeds", [0]))  # a record from before the seeds key: one seed
        judged = seeds >= SEEDS_TO_JUDGE  # one seed's ratio, or three's, is not the target's
        target = f"≥ 10 over ≥ {SEEDS_TO_JUDGE} seeds, compiles included"
        count = f"{seeds} seed{'s' if seeds > 1 else ''}"
        judge = (lambda v: v >= 10) if judged else None
        row(name, f"{measured(best)} ({count})", target, flat[best], judge, "{:.1f}")
    return rows


def _channel_rows(channel: dict, row) -> None:
    """The defaults' full channel (the measured-slope sea, the default lattice): its step against the lattice
    floor at B = 1024 (compiled ≤ 0.35, eager ≤ 1.5) and, compiled, B = 16's rate against B = 1024's."""
    case = ("full", "ocean", "")
    defaults = {r["batch"]: r for r in channel["rows"] if (r["channel"], r["sea"], r.get("lattice", "")) == case}
    compiled = channel["compiled_kernel"]
    if "lattice_floor_ratio" in defaults.get(1024, {}):
        ratio, target = defaults[1024]["lattice_floor_ratio"], 0.35 if compiled else 1.5
        name = f"full channel step / lattice sin+cos floor, B = 1024, {'compiled' if compiled else 'eager'}"
        row(name, f"{ratio:.2f}", f"≤ {target}", ratio, lambda v: v <= target)
    if compiled and 16 in defaults and 1024 in defaults:
        ratio = defaults[16]["env_steps_per_s"] / defaults[1024]["env_steps_per_s"]
        name = "full channel env-steps/s, B = 16 / B = 1024, compiled"
        row(name, f"{ratio:.2f}", "≥ 0.4", ratio, lambda v: v >= 0.4)


def main(folder: Path) -> str:
    return "\n".join(summary_lines(folder))
