"""The Hydra callback that summarises a sweep, and the seed study's table and learning curves.

At the end of a multirun :class:`SweepSummary` writes, at the sweep root, ``summary.csv`` (one row
per job: its overrides and final metrics), ``summary.md`` (the per-job table of the greedy ratio to
the upper bound beside the classical controller's, flat-sea Snell's and straight facing's, and the
spread) and ``learning_curves.png`` (the training links' ratio to the upper bound against frames:
the mean over jobs and their range).
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf

from waterair.core.files import atomic_write_csv, atomic_write_text
from waterair.envs.controllers import CONTROLLERS

CURVE_KEY = "train/gain_ratio_ub"
"""The column of each job's ``metrics.csv`` the learning curves plot."""


class SweepSummary(Callback):
    """At the end of a multirun, write the summary files described in the module docstring."""

    def on_multirun_end(self, config: DictConfig, **kwargs) -> None:
        summarise(Path(config.hydra.sweep.dir))


def summarise(root: Path) -> list[dict]:
    """Write ``summary.csv``, ``summary.md`` and ``learning_curves.png`` for the jobs under ``root``; the rows."""
    rows = []
    for metrics_path in sorted(root.glob("*/final_metrics.json"), key=lambda p: int(p.parent.name)):
        overrides_path = metrics_path.parent / ".hydra" / "overrides.yaml"
        overrides = OmegaConf.load(overrides_path) if overrides_path.exists() else []
        rows.append(
            {"job": metrics_path.parent.name, "overrides": " ".join(overrides), **json.loads(metrics_path.read_text())}
        )
    if not rows:
        return rows
    atomic_write_csv(root / "summary.csv", list(dict.fromkeys(key for row in rows for key in row)), rows)
    atomic_write_text(root / "summary.md", summary_table(rows))
    curves = {row["job"]: read_curve(root / row["job"] / "metrics.csv") for row in rows}
    learning_curves({job: curve for job, curve in curves.items() if curve[0].size}, root / "learning_curves.png")
    return rows


def summary_table(rows: list[dict]) -> str:
    """A Markdown table: per job, the greedy agent's, the classical controller's, flat-sea Snell's and
    straight facing's ratio to UB (the closing evaluation's, on the same seas at the job's own wind and
    offset), and the agent's spread over jobs."""
    classical = [name for name in CONTROLLERS if any(f"{name}/ratio_to_ub" in row for row in rows)]
    lines = [
        "| job | overrides | frames | training (s) | agent ratio to UB | "
        + "".join(f"{name} | " for name in classical)
        + "flat-Snell | straight facing |",
        "|---" * (7 + len(classical)) + "|",
    ]
    for row in rows:
        seconds = row.get("train_seconds")
        references = "".join(_ratio(row, name) + " | " for name in classical)
        lines.append(
            f"| {row['job']} | `{row['overrides']}` | {row['frames']} | {'–' if seconds is None else f'{seconds:.0f}'} "
            f"| {row['agent/ratio_to_ub']:.3f} | {references}{_ratio(row, 'flat_snell')} | "
            f"{_ratio(row, 'straight_facing')} |"
        )
    ratios = [row["agent/ratio_to_ub"] for row in rows]
    lines += [
        "",
        f"Agent ratio to UB over {len(rows)} jobs: mean {np.mean(ratios):.3f}, best {max(ratios):.3f}, "
        f"worst {min(ratios):.3f} (best − worst {max(ratios) - min(ratios):.3f}).",
    ]
    return "\n".join(lines) + "\n"


def _ratio(row: dict, name: str) -> str:
    value = row.get(f"{name}/ratio_to_ub")
    return "–" if value is None else f"{value:.3f}"


def read_curve(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(frames, :data:`CURVE_KEY`) of one job's ``metrics.csv`` (empty arrays if it has none)."""
    if not path.is_file():
        return np.array([]), np.array([])
    with path.open() as file:
        pairs = [(float(r["frames"]), float(r[CURVE_KEY])) for r in csv.DictReader(file) if r.get(CURVE_KEY)]
    return (np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs])) if pairs else (np.array([]), np.array([]))


def learning_curves(curves: dict[str, tuple[np.ndarray, np.ndarray]], path: Path, window: int = 5) -> Path | None:
    """Mean and range over jobs of the ratio to UB against frames (a ``window``-batch moving average):
    the whole run on the left, and on the right its last four fifths, scaled to the data, with each job's curve."""
    if not curves:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    length = min(frames.size for frames, _ in curves.values())
    frames = next(iter(curves.values()))[0][:length]
    kernel = np.ones(window) / window
    smooth = np.stack(
        [np.convolve(np.pad(v[:length], (window - 1, 0), mode="edge"), kernel, "valid") for _, v in curves.values()]
    )
    fig, (whole, late) = plt.subplots(1, 2, figsize=(11, 4))
    for ax in (whole, late):
        ax.fill_between(frames, smooth.min(0), smooth.max(0), color="tab:blue", alpha=0.25, label="range over jobs")
        ax.plot(frames, smooth.mean(0), color="tab:blue", linewidth=2, label=f"mean over {len(curves)} jobs")
        ax.set_xlabel("frames (environment steps over all links)")
        ax.xaxis.set_major_formatter(lambda value, _: f"{value / 1000:g}k")
        ax.grid(alpha=0.3)
    whole.set_ylabel("mean G / mean G_UB")
    whole.set_ylim(0, 1)
    whole.set_title("ratio to the upper bound on the training links (with exploration noise)", fontsize=10)
    whole.legend(loc="lower right")
    start = length // 5
    for job, values in zip(curves, smooth, strict=True):
        late.plot(frames[start:], values[start:], linewidth=0.8, alpha=0.8, label=f"job {job}")
    low, high = smooth[:, start:].min(), smooth[:, start:].max()
    margin = max(0.005, 0.1 * (high - low))
    late.set_xlim(frames[start], frames[-1])
    late.set_ylim(low - margin, high + margin)
    late.set_title("the last four fifths, scaled to the data", fontsize=10)
    late.legend(loc="lower right", fontsize=8, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
