"""Time to quality: ``python -m waterair.bench quality`` (see :mod:`waterair.bench`).

The wall time each pipeline needs to reach a greedy ratio to the upper bound of ``target`` (0.95) at the S1
point (12 m/s, 10 % offset, the default 50 mrad beam) on the defaults: the measured-slope sea, the full channel,
both ends sensed (``env/observation=beacon``) through the realistic sensor, all measured in this one process,
one after the other:

* **ours**: ``train()`` with the defaults (PPO) at that one point, for growing budgets (``budgets`` frames,
  each a fresh run until one reaches the target), the step and the update compiled. Its time is that of every
  run up to the one that reached (environment construction, compiles and training, without the closing
  evaluations): the runs share one process, so the compiles the first paid the later ones would pay again from
  scratch, and the sum is the bound that counts them.
  Its first policy is the zero residual, i.e. the beacon tracker, so a one-batch budget (1,600 frames) measures
  how soon the pipeline stands where it starts;
* **ours, flat-Snell base**: the same with residual actions on flat-sea Snell instead (``flat_budgets``), so
  that the agent must learn the tracking itself;
* **ours, eager**: both again with the step and the update eager (:data:`EAGER`), when asked;
* **sb3_ddpg, sb3_ppo**: Stable-Baselines3 DDPG and PPO on our Gymnasium view with the same observation,
  sensor, residual actions, reward and networks, each with our ``agent=ddpg`` or ``agent=ppo`` settings
  (:mod:`.sb3`), one link at a time, on each base; one run each, scored every :data:`SB3_CHUNK` frames until it
  reaches the target or ``sb3_frames`` (its wall time includes model construction, not the scoring).

Every greedy policy is scored with evaluation's own runner on the same 32 seas × 500 steps (evaluation seed
12345, never a training seed). The ratios are Stable-Baselines3's best time to the target over ours, per base.
Needs ``stable_baselines3`` for the SB3 rows.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from waterair.bench.sb3 import SB3Actor, sb3_ddpg, sb3_ppo
from waterair.bench.training import compose_training
from waterair.evaluation.runner import compare_policies
from waterair.evaluation.scenarios import Scenario
from waterair.training.builders import env_config

FLAT_BASE = ["env.residual_base=flat_snell", "env.residual_deg=15"]
"""Residual actions on flat-sea Snell (±15°): the agent must learn the tracking itself."""
POINT = [
    "env.wind_range=null",
    "env.offset_range=null",
    "env.offset_azimuth_range=null",
    "env.wind_direction_range=null",
    "env.divergence_range=null",
]
"""The S1 point (12 m/s, 10 % offset, drone at azimuth 0, wind from 0, the default divergence)."""
EAGER = ["env.compile_kernel=false", "compile_update=false"]
"""Our pipeline without its compiles: a short run does not pay them back."""
COMPILED = ["env.compile_kernel=true", "compile_update=true"]
"""Our pipeline compiled whatever its budget (``auto`` would not compile short budgets)."""
BASES = {"": [], "_flat_base": FLAT_BASE}
"""Each base's name suffix and overrides."""
SB3 = {"sb3_ddpg": ("agent=ddpg", sb3_ddpg), "sb3_ppo": ("agent=ppo", sb3_ppo)}
"""Each Stable-Baselines3 pipeline: our agent whose settings it takes, and its builder."""
SB3_CHUNK = 4_800
"""Frames between two scorings of a Stable-Baselines3 run (three of PPO's rollouts)."""
SCENARIO = Scenario("S1", "time to quality", None, ((12.0, 0.1, 0.0),), realisations=32, steps=500, seed=12345)
EVALUATING = "Evaluating the greedy policy"
"""How the training loop's progress line announcing its closing evaluation starts (waterair.training.loop)."""
PIPELINES = [f"{name}{base}{mode}" for base in BASES for name in ("ours", *SB3) for mode in ("", "_eager")]
"""Every pipeline's record key, in the table's order."""


def score(cfg, policy) -> float:
    """The greedy ``policy``'s ratio to the upper bound on :data:`SCENARIO`, scored eagerly whatever ``cfg``'s
    step (every pipeline the same way; the scoring is not timed)."""
    config = env_config(cfg, compile_kernel=False)
    return compare_policies(config, {"policy": policy}, SCENARIO)["policy"]["ratio_to_ub"]


def ours(budgets: list[int], target: float, overrides: list[str]) -> dict:
    """Fresh ``train()`` runs of growing budgets until one reaches ``target``: each (frames, seconds, ratio), and
    the seconds of all of them up to that one (the module docstring says why the sum).

    A run's seconds run from the call until its loop ends (the closing evaluation, announced by the
    progress line that starts with :data:`EVALUATING`, is not counted).
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
            train(cfg, Path(run_dir), progress=lambda line, ends=loop_end: _note_loop_end(line, ends))
            policy = load_policy(Path(run_dir) / "checkpoints" / "last.pt")
            actor = policy.actor(cfg.actor, env_config(cfg).observation_size)
        runs.append({"frames": frames, "seconds": loop_end[0] - start, "ratio_to_ub": score(cfg, actor)})
        if runs[-1]["ratio_to_ub"] >= target:
            break
    reached = runs[-1]["ratio_to_ub"] >= target
    return {
        "overrides": overrides,
        "runs": runs,
        "seconds_to_target": sum(r["seconds"] for r in runs) if reached else None,
    }


def sb3(name: str, frames: int, chunk: int, target: float, overrides: list[str]) -> dict | None:
    """Stable-Baselines3 ``name`` (a key of :data:`SB3`) on the Gymnasium view of the same link (the defaults with
    ``overrides`` and that agent's settings), scored after every ``chunk`` frames until it reaches ``target``
    or ``frames``: each (frames, seconds, ratio). Its seconds count model construction and learning, not the
    scoring."""
    agent, build = SB3[name]
    cfg = compose_training([agent, *POINT, *overrides])
    start = time.perf_counter()
    model = build(cfg)
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


def bench_quality(
    budgets: list[int], flat_budgets: list[int], sb3_frames: int, eager: bool = False, target: float = 0.95
) -> dict:
    """Every pipeline on each base, then per base the ratio of Stable-Baselines3's best seconds to ``target``
    over ours: exact where an SB3 run reached it, a lower bound (``..._at_least``) where none had by the end of
    its budget."""
    record = {"benchmark": "quality", "target": target, "scenario": "S1 point, 32 seas x 500 steps, seed 12345"}
    for base, overrides in BASES.items():
        frames = flat_budgets if base else budgets
        record[f"ours{base}"] = ours(frames, target, [*overrides, *COMPILED])
        if eager:
            record[f"ours{base}_eager"] = ours(frames, target, [*overrides, *EAGER])
    for base, overrides in BASES.items():
        for name in SB3:
            record[f"{name}{base}"] = sb3(name, sb3_frames, SB3_CHUNK, target, overrides)
    for base in BASES:
        theirs = [record[f"{name}{base}"] for name in SB3 if record[f"{name}{base}"] is not None]
        for mine in (f"ours{base}", f"ours{base}_eager"):
            if not theirs or mine not in record or record[mine]["seconds_to_target"] is None:
                continue
            reached = [run["seconds_to_target"] for run in theirs if run["seconds_to_target"] is not None]
            best = min(reached) if reached else min(run["runs"][-1]["seconds"] for run in theirs)
            key = f"sb3{base}_over_{mine}" + ("" if reached else "_at_least")
            record[key] = best / record[mine]["seconds_to_target"]
    return record


def quality_table(record: dict) -> str:
    lines = ["| pipeline | frames | seconds | greedy ratio to UB |", "|---|---|---|---|"]
    for name in (name for name in PIPELINES if record.get(name)):
        for run in record[name]["runs"]:
            lines.append(f"| {name} | {run['frames']:,} | {run['seconds']:.0f} | {run['ratio_to_ub']:.3f} |")
    for key, ratio in ((key, value) for key, value in record.items() if "_over_" in key):
        says = "at least " if key.endswith("_at_least") else ""
        mine = key.removesuffix("_at_least").split("_over_")[1]
        lines.append(f"| SB3's best seconds / {mine}'s to {record['target']} | | {says}{ratio:.1f} | |")
    return "\n".join(lines)


def _note_loop_end(line: str, ends: list[float]) -> None:
    """Note the time when ``line`` announces the closing evaluation (the training loop has ended)."""
    if line.startswith(EVALUATING):
        ends.append(time.perf_counter())


def _first_reaching(runs: list[dict], target: float) -> float | None:
    """The seconds of the first run whose ratio reaches ``target``, or None."""
    return next((run["seconds"] for run in runs if run["ratio_to_ub"] >= target), None)
