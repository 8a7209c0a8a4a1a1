"""The summary of a sweep: which jobs finished, which did not and why, and how the finished ones scored.

:func:`summarise` reads a sweep directory and writes, at its root, ``summary.csv`` (one row per
job: its number, overrides, status, log and final metrics), ``summary.md`` (the finished jobs'
greedy ratio to the upper bound beside the classical controller's, flat-sea Snell's and straight
facing's, their mean, best and spread, then every job that did not finish with why and its log) and
``learning_curves.png`` (the training links' ratio to the upper bound against frames: the mean over
the finished jobs and their range). It reads only the files the jobs and the launcher leave, so it
rebuilds the summary of any sweep, complete, failed or still running
(``python -m waterair.cli.sweep ROOT``). :class:`SweepSummary` runs it when a multirun ends.

What each job leaves in its folder ``ROOT/N``: ``.hydra/overrides.yaml`` when it starts,
``final_metrics.json`` when it finishes, :data:`ERROR_FILE` when it raised (written by the job,
its traceback in its ``train.log``), and :data:`LAUNCH_FILE` when a scheduler ran it (written by
:mod:`waterair.training.launchers`: its id, last state and log, so a job cancelled before it
started has a folder too).
"""

from __future__ import annotations

import csv
import json
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf

from waterair.core.files import atomic_write_csv, atomic_write_text
from waterair.envs.controllers import CONTROLLERS

CURVE_KEY = "train/gain_ratio_ub"
"""The column of each job's ``metrics.csv`` the learning curves plot."""
ERROR_FILE = "error.txt"
"""One line, ``Type: message``, that a job writes into its folder when it raises."""
LAUNCH_FILE = "job.json"
"""A scheduler's record of a job: ``{"id", "state", "log", "overrides"}``."""
JOB_LOG = "train.log"
"""The log every job writes into its folder (conf/hydra/job_logging/waterair.yaml)."""
FINISHED = "finished"
EVENTS = "tensorboard"
"""The folder at a sweep's root holding each job's TensorBoard run, named by its overrides
(:func:`waterair.cli.training.sweep_events_dir`)."""


@dataclass(frozen=True)
class Job:
    """One job of a sweep, as its files tell it."""

    number: int
    overrides: tuple[str, ...]
    status: str
    """``finished``; else why not: ``failed`` (it raised), the scheduler's state (``cancelled``,
    ``timeout``, ``out_of_memory``, ...), or ``not finished`` (still running, or killed without a trace)."""
    detail: str = ""
    log: Path | None = None
    metrics: dict = field(default_factory=dict)

    @property
    def finished(self) -> bool:
        return self.status == FINISHED


class SweepSummary(Callback):
    """At the end of a multirun, write the summary and say where it is (the last line on the console).

    If a job did not finish, the process exits with status 1 and one line naming each such job, why
    and its log. The exit is done here because Hydra turns an exception raised by a callback into a
    warning; this callback runs last, after every job has ended.
    """

    def on_multirun_end(self, config: DictConfig, **kwargs) -> None:
        conclude(Path(config.hydra.sweep.dir))


def conclude(root: Path) -> None:
    """Summarise the sweep at ``root``; print where the summary is, or exit with status 1 and one line
    naming each job that did not finish, why, its log, and where the summary is."""
    line, error = report(root, summarise(root))
    if error:
        sys.exit(f"error: {error}")
    # print, not logging: after a basic launcher's jobs the root logger still writes into the last job's log
    print(line, flush=True)


def summarise(root: Path) -> list[Job]:
    """Write ``summary.csv``, ``summary.md`` and ``learning_curves.png`` for the jobs under ``root``; the jobs."""
    jobs = read_jobs(root)
    if not jobs:
        return jobs
    keys = swept_keys(jobs)
    rows = [
        {"job": job.number, "overrides": " ".join(job.overrides), **{key: swept_value(job, key) for key in keys},
         "status": job.status, "log": _relative(job.log, root), **job.metrics}
        for job in jobs
    ]  # fmt: skip
    atomic_write_csv(root / "summary.csv", list(dict.fromkeys(key for row in rows for key in row)), rows)
    atomic_write_text(root / "summary.md", summary_table(jobs, root))
    finished = [job for job in jobs if job.finished]
    curves = {str(job.number): read_curve(root / str(job.number) / "metrics.csv") for job in finished}
    learning_curves({name: curve for name, curve in curves.items() if curve[0].size}, root / "learning_curves.png")
    return jobs


def read_jobs(root: Path) -> list[Job]:
    """Every job of the sweep at ``root`` (a numbered folder each), in order."""
    folders = [path for path in root.iterdir() if path.is_dir() and path.name.isdigit()] if root.is_dir() else []
    return [read_job(folder) for folder in sorted(folders, key=lambda path: int(path.name))]


def read_job(folder: Path) -> Job:
    """The job whose folder is ``folder``: finished, failed, stopped by its scheduler, or not finished."""
    launch = json.loads((folder / LAUNCH_FILE).read_text()) if (folder / LAUNCH_FILE).is_file() else {}
    overrides_path = folder / ".hydra" / "overrides.yaml"
    overrides = OmegaConf.load(overrides_path) if overrides_path.is_file() else launch.get("overrides", [])
    job_log = folder / JOB_LOG
    common = {"number": int(folder.name), "overrides": tuple(str(override) for override in overrides)}
    if (folder / "final_metrics.json").is_file():
        metrics = json.loads((folder / "final_metrics.json").read_text())
        return Job(**common, status=FINISHED, log=job_log, metrics=metrics)
    if (folder / ERROR_FILE).is_file():
        return Job(**common, status="failed", detail=(folder / ERROR_FILE).read_text().strip(), log=job_log)
    state = str(launch.get("state", "")).split(" ")[0]  # sacct adds "by UID" to CANCELLED
    scheduler_log = Path(launch["log"]) if launch.get("log") else None
    if state and state not in ("PENDING", "RUNNING", "SUBMITTED", "COMPLETED", "UNKNOWN"):
        started = scheduler_log is not None and scheduler_log.is_file()
        detail = f"the scheduler's state is {state}" + ("" if started else "; it never started")
        return Job(**common, status=state.lower(), detail=detail, log=scheduler_log if started else None)
    detail = "it is still running, or was stopped without leaving a trace"
    return Job(**common, status="not finished", detail=detail, log=job_log if job_log.is_file() else scheduler_log)


def report(root: Path, jobs: list[Job]) -> tuple[str, str | None]:
    """The line that says where the summary is, and a one-line error naming each job that did not finish."""
    finished = sum(job.finished for job in jobs)
    where = root / "summary.md"
    if not jobs:
        return f"No job folders under {root}: nothing to summarise", f"{root} holds no jobs (numbered folders)"
    if finished == len(jobs):
        events = root / EVENTS
        watch = f"TensorBoard, a run per job: .venv/bin/tensorboard --logdir {events}\n" if events.is_dir() else ""
        return f"{watch}Summary of {len(jobs)} jobs: {where}", None
    shown = varying(jobs)
    missing = [
        f"job {job.number} ({shown[job.number] or 'no overrides'}) {job.status}: {job.detail} (log: {job.log or '–'})"
        for job in jobs
        if not job.finished
    ]
    line = f"Summary of the {finished} finished of {len(jobs)} jobs: {where}"
    return line, f"{len(missing)} of {len(jobs)} jobs did not finish: {'; '.join(missing)}; summary: {where}"


def summary_table(jobs: list[Job], root: Path) -> str:
    """Markdown: per finished job, the greedy agent's, the classical controller's, flat-sea Snell's and
    straight facing's ratio to UB (the closing evaluation's, on the same seas at the job's own wind and
    offset), the agent's spread and best job; then the jobs that did not finish."""
    rows, shown, keys = [job for job in jobs if job.finished], varying(jobs), swept_keys(jobs)
    classical = [name for name in CONTROLLERS if any(f"{name}/ratio_to_ub" in job.metrics for job in rows)]
    common = [override for override in jobs[0].overrides if all(override in job.overrides for job in jobs)]
    lines = [f"Every job: `{' '.join(common)}`", ""] if common and len(jobs) > 1 else []
    columns = keys or ["overrides"]  # a value per swept key; one job's overrides whole
    lines += [
        "| job | " + "".join(f"{key} | " for key in columns) + "frames | training (s) | agent ratio to UB | "
        + "".join(f"{name} | " for name in classical)
        + "flat-Snell | straight facing |",
        "|---" * (6 + len(columns) + len(classical)) + "|",
    ]  # fmt: skip
    for job in rows:
        seconds, references = job.metrics.get("train_seconds"), "".join(_ratio(job, name) + " | " for name in classical)
        values = [swept_value(job, key) for key in keys] or [shown[job.number]]
        lines.append(
            f"| {job.number} | " + "".join(f"`{value}` | " for value in values) + f"{job.metrics['frames']} | "
            f"{'–' if seconds is None else f'{seconds:.0f}'} | {job.metrics['agent/ratio_to_ub']:.3f} | {references}"
            f"{_ratio(job, 'flat_snell')} | {_ratio(job, 'straight_facing')} |"
        )
    if rows:
        ratios = [job.metrics["agent/ratio_to_ub"] for job in rows]
        best = rows[int(np.argmax(ratios))]
        lines += [
            "",
            f"Agent ratio to UB over {len(rows)} job{'s' if len(rows) > 1 else ''}: mean {np.mean(ratios):.3f}, "
            f"best {max(ratios):.3f}, "
            f"worst {min(ratios):.3f} (best − worst {max(ratios) - min(ratios):.3f}).",
            "",
            f"Best: job {best.number} (`{shown[best.number]}`), {max(ratios):.3f}.",
        ]
    unfinished = [job for job in jobs if not job.finished]
    if unfinished:
        lines += ["", f"Did not finish ({len(unfinished)} of {len(jobs)} jobs):", "",
                  "| job | overrides | status | why | log |", "|---|---|---|---|---|"]  # fmt: skip
        for job in unfinished:
            where = _relative(job.log, root) or "–"
            lines.append(f"| {job.number} | `{shown[job.number]}` | {job.status} | {job.detail} | {where} |")
    return "\n".join(lines) + "\n"


def swept_at(root: Path) -> list[str]:
    """The keys the sweep at ``root`` sweeps (``agent.gamma`` of ``agent.gamma=0,0.9``; a search's too), as its
    ``multirun.yaml`` (written by the sweeper before the first job) gives them; none where it is missing."""
    path = root / "multirun.yaml"
    if not path.is_file():
        return []
    hydra = OmegaConf.load(path).hydra
    params = hydra.sweeper.get("params") or {}
    given = [*(f"{key}={value}" for key, value in params.items()), *hydra.overrides.task]
    parsed = OverridesParser.create().parse_overrides(given)
    return list(dict.fromkeys(o.get_key_element().lstrip("+~") for o in parsed if o.is_sweep_override()))


def swept_keys(jobs: list[Job]) -> list[str]:
    """The keys whose value is not the same in every job (a sweep's axes), in the order the overrides give them;
    none for a sweep of one job."""
    if len(jobs) < 2:
        return []
    keys = list(dict.fromkeys(override.partition("=")[0] for job in jobs for override in job.overrides))
    return [key for key in keys if len({swept_value(job, key) for job in jobs}) > 1]


def swept_value(job: Job, key: str) -> str:
    """The value ``job``'s overrides give ``key`` (``–`` where they give none)."""
    return next((o.partition("=")[2] for o in job.overrides if o.partition("=")[0] == key), "–")


def varying(jobs: list[Job]) -> dict[int, str]:
    """Per job, its overrides that not every job shares (all of them if the sweep has one job)."""
    common = set.intersection(*(set(job.overrides) for job in jobs)) if len(jobs) > 1 else set()
    return {job.number: " ".join(o for o in job.overrides if o not in common) for job in jobs}


def _ratio(job: Job, name: str) -> str:
    value = job.metrics.get(f"{name}/ratio_to_ub")
    return "–" if value is None else f"{value:.3f}"


def _relative(path: Path | None, root: Path) -> str:
    if path is None:
        return ""
    try:
        return str(path.resolve().relative_to(root.resolve()))
    except ValueError:
        return str(path)


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
    if frames[-1] > frames[start]:  # a run logged once has one point: matplotlib's own limits around it
        late.set_xlim(frames[start], frames[-1])
    late.set_ylim(low - margin, high + margin)
    late.set_title("the last four fifths, scaled to the data", fontsize=10)
    late.legend(loc="lower right", fontsize=8, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
