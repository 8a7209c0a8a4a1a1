"""Time to quality: ``python -m waterair.bench quality`` (see :mod:`waterair.bench`).

The wall time each pipeline needs to reach a greedy ratio to the upper bound of ``target`` (0.95)
on the S1 point (12 m/s, 10 % offset) with the quadrant observation and the ideal sensor, both
measured in this one process, one after the other:

* **ours**: ``train()`` with the defaults at that one point, for growing budgets (``budgets``
  frames, each a fresh run from scratch; the first that reaches the target counts). Its time is the
  whole run (environment construction, compiles and training) without the closing evaluation. Its
  first policy is the zero residual, i.e. the base controller, so a one-batch budget (1,600
  frames) measures how soon the pipeline stands where it starts;
* **ours, flat-Snell base**: the same with residual actions on flat-sea Snell instead of the
  quadrant back-projection, so that the agent must learn the tracking itself;
* **ours, eager**: both again with the step and the update eager (:data:`EAGER`), after the
  compiled runs;
* **sb3**: Stable-Baselines3 DDPG on our Gymnasium view with the same observation, sensor,
  residual actions, reward and networks, and ``agent=ddpg``'s learning rates, batch, discount, noise
  and updates per frame, one link at a time; one run, scored every :data:`SB3_CHUNK` frames until
  it reaches the target or ``sb3_frames`` (its wall time includes model construction, not the scoring);
* **sb3, flat-Snell base**: the same on the flat-Snell residual interface, beside ours on it.

Every greedy policy is scored with evaluation's own runner on the same 32 seas × 500 steps
(evaluation seed 12345, never a training seed). Needs ``stable_baselines3`` for the last row.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from waterair.bench.sb3 import SB3Actor, sb3_ddpg
from waterair.bench.training import compose_training
from waterair.evaluation.runner import compare_policies
from waterair.evaluation.scenarios import Scenario
from waterair.training.builders import env_config

FLAT_BASE = ["env.residual_base=flat_snell", "env.residual_deg=15"]
"""Residual actions on flat-sea Snell (±15°): the agent must learn the tracking itself."""
POINT = [
    "env/sensor=ideal",
    "env.wind_range=null",
    "env.offset_range=null",
    "env.offset_azimuth_range=null",
    "env.wind_direction_range=null",
]
"""The S1 point (12 m/s, 10 % offset, drone at azimuth 0, wind from 0) with the ideal sensor."""
EAGER = ["env.compile_kernel=false", "compile_update=false"]
"""Our pipeline without its compiles: a short run does not pay them back."""
COMPILED = ["env.compile_kernel=true", "compile_update=true"]
"""Our pipeline compiled whatever its budget (``auto`` would not compile short budgets)."""
PAIRS = (
    ("sb3", "ours"),
    ("sb3", "ours_eager"),
    ("sb3_flat_base", "ours_flat_base"),
    ("sb3_flat_base", "ours_flat_base_eager"),
)
"""(theirs, ours) pipelines whose times to the target are compared on the same interface."""
SB3_CHUNK = 5_000
"""Frames between two scorings of the Stable-Baselines3 run."""
SCENARIO = Scenario("S1", "time to quality", None, ((12.0, 0.1, 0.0),), realisations=32, steps=500, seed=12345)


def score(cfg, policy) -> float:
    """The greedy ``policy``'s ratio to the upper bound on :data:`SCENARIO`."""
    return compare_policies(env_config(cfg), {"policy": policy}, SCENARIO)["policy"]["ratio_to_ub"]


def ours(budgets: list[int], target: float, overrides: list[str]) -> dict:
    """Fresh ``train()`` runs of growing budgets until one reaches ``target``: each (frames, seconds, ratio).

    A run's seconds run from the call until its loop ends (the closing evaluation, announced by the
    loop's first progress line, is not counted).
    """
    from waterair.evaluation.policies import load_policy
    from waterair.training.loop import train

    runs = []
    for frames in budgets:
        cfg = compose_training(
            [*POINT, *overrides, f"total_frames={frames}", "eval.realisations=1", "eval.steps=1"]
            + ["logger.progress_bar=false", f"checkpoint.every_frames={frames}"]
        )
        loop_end = []
        with tempfile.TemporaryDirectory() as run_dir:
            start = time.perf_counter()
            train(cfg, Path(run_dir), progress=lambda line, ends=loop_end: ends.append(time.perf_counter()))
            policy = load_policy(Path(run_dir) / "checkpoints" / "last.pt")
            actor = policy.actor(cfg.actor, env_config(cfg).observation_size)
        runs.append({"frames": frames, "seconds": loop_end[0] - start, "ratio_to_ub": score(cfg, actor)})
        if runs[-1]["ratio_to_ub"] >= target:
            break
    return {"overrides": overrides, "runs": runs, "seconds_to_target": _first_reaching(runs, target)}


def sb3(frames: int, chunk: int, target: float, overrides: list[str]) -> dict | None:
    """Stable-Baselines3 DDPG on the Gymnasium view of the same link (the defaults with ``overrides``
    and ``agent=ddpg``'s settings), scored after every ``chunk`` frames until it reaches ``target``
    or ``frames``: each (frames, seconds, ratio). Its seconds count model construction and learning,
    not the scoring."""
    cfg = compose_training(["agent=ddpg", *POINT, *overrides])
    start = time.perf_counter()
    model = sb3_ddpg(cfg)
    if model is None:
        return None
    runs: list[dict] = []
    seconds = 0.0
    while not runs or (runs[-1]["frames"] < frames and runs[-1]["ratio_to_ub"] < target):
        model.learn(chunk, reset_num_timesteps=not runs)
        seconds += time.perf_counter() - start
        runs.append({"frames": model.num_timesteps, "seconds": seconds, "ratio_to_ub": score(cfg, SB3Actor(model))})
        start = time.perf_counter()
    return {"overrides": overrides, "runs": runs, "seconds_to_target": _first_reaching(runs, target)}


def bench_quality(budgets: list[int], flat_budgets: list[int], sb3_frames: int, target: float = 0.95) -> dict:
    """Every pipeline, then each ratio of SB3's seconds to 0.95 over ours: exact where both reached
    it, a lower bound (``..._at_least``) where SB3 had not by the end of its budget."""
    record = {"benchmark": "quality", "target": target, "scenario": "S1 point, 32 seas x 500 steps, seed 12345"}
    record["ours"] = ours(budgets, target, COMPILED)
    record["ours_flat_base"] = ours(flat_budgets, target, [*FLAT_BASE, *COMPILED])
    record["ours_eager"] = ours(budgets, target, EAGER)
    record["ours_flat_base_eager"] = ours(flat_budgets, target, [*FLAT_BASE, *EAGER])
    record["sb3"] = sb3(sb3_frames, SB3_CHUNK, target, [])
    record["sb3_flat_base"] = sb3(sb3_frames, SB3_CHUNK, target, FLAT_BASE)
    for theirs, mine in PAIRS:
        if record[theirs] is None or record[mine]["seconds_to_target"] is None:
            continue
        reached = record[theirs]["seconds_to_target"]
        key = f"{theirs}_over_{mine}" + ("" if reached is not None else "_at_least")
        record[key] = (reached or record[theirs]["runs"][-1]["seconds"]) / record[mine]["seconds_to_target"]
    return record


def quality_table(record: dict) -> str:
    lines = ["| pipeline | frames | seconds | greedy ratio to UB |", "|---|---|---|---|"]
    for name in ("ours", "ours_flat_base", "ours_eager", "ours_flat_base_eager", "sb3", "sb3_flat_base"):
        for run in (record[name] or {"runs": []})["runs"]:
            lines.append(f"| {name} | {run['frames']:,} | {run['seconds']:.0f} | {run['ratio_to_ub']:.3f} |")
    for theirs, mine in PAIRS:
        for suffix, says in (("", ""), ("_at_least", "at least ")):
            if f"{theirs}_over_{mine}{suffix}" in record:
                ratio = record[f"{theirs}_over_{mine}{suffix}"]
                lines.append(f"| {theirs} seconds / {mine}'s to {record['target']} | | {says}{ratio:.1f} | |")
    return "\n".join(lines)


def _first_reaching(runs: list[dict], target: float) -> float | None:
    """The seconds of the first run whose ratio reaches ``target``, or None."""
    return next((run["seconds"] for run in runs if run["ratio_to_ub"] >= target), None)
