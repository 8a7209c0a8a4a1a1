"""Time to quality: ``python -m waterair.bench quality`` (see :mod:`waterair.bench`).

The wall time each pipeline needs to reach a greedy ratio to the upper bound of ``target`` (0.95) at the S1
point (12 m/s, 10 % offset, the default 50 mrad beam) on the defaults: the measured-slope sea, the full channel,
both ends sensed (``env/observation=beacon``) through the realistic sensor, measured one after the other, each
in a Python process of its own (:func:`in_fresh_python`), every pipeline on the same torch threads (``threads``;
by default every CPU the process may use: train.py's ``auto`` would leave one of them idle, which
Stable-Baselines3 does not):

* **ours**: ``train()`` with the defaults (PPO) at that one point, one run of at most ``frames``, its greedy
  policy scored at every checkpoint (each ``chunk`` frames) until one reaches the target, which ends the run
  (``train``'s ``on_checkpoint``). Its time runs from the call to that checkpoint, less the scorings before it:
  environment construction, compiles (each run's from an empty cache of its own) and training counted, the
  scorings not. Its first policy is the zero residual, i.e. the beacon tracker, so the first scoring measures
  how soon the pipeline stands where it starts;
* **ours_ddpg**: the same with ``agent=ddpg`` (:data:`OURS`), Stable-Baselines3 DDPG's counterpart, which like
  it learns from its first batch and is scored on its live actor;
* each again with residual actions on flat-sea Snell (``_flat_base``, ``flat_frames``), so that the agent must
  learn the tracking itself, and compiled (:data:`COMPILED`), eager (``_eager``, :data:`EAGER`) or both
  (``modes``);
* **sb3_ddpg, sb3_ppo**: Stable-Baselines3 DDPG and PPO on our Gymnasium view with the same observation,
  sensor, residual actions, reward and networks, each with our ``agent=ddpg`` or ``agent=ppo`` settings
  (:mod:`.sb3`), one link at a time, on each base, scored every ``chunk`` frames until it reaches the target
  or ``sb3_frames`` (its wall time includes model construction, not the scoring).

Every pipeline runs once per training seed (``seeds``: one run of one seed varies, and seeds vary more; see
docs/benchmarks.md), seed by seed, every pipeline of a seed in turn, and counts the median of their seconds
(:func:`over_seeds`).

Every greedy policy is scored with evaluation's own runner on the same 32 seas × 500 steps (evaluation seed
12345, never a training seed), every pipeline at the same frames. The ratios are Stable-Baselines3's best median
time to the target over each of ours, per base.
Needs ``stable_baselines3`` for the SB3 rows.
"""

from __future__ import annotations

import json
import math
import os
import statistics
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import torch

from waterair.bench.common import COLLECTOR_OFF, last_line_of_fresh_python
from waterair.bench.sb3 import SB3Actor, installed, sb3_ddpg, sb3_ppo
from waterair.bench.training import compose_training
from waterair.core.process import set_up_process
from waterair.core.threads import choose_threads, torch_threads
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
MODES = {"compiled": ("", COMPILED), "eager": ("_eager", EAGER)}
"""Each way our pipelines run: its record keys' suffix and its overrides."""
BASES = {"": [], "_flat_base": FLAT_BASE}
"""Each base's name suffix and overrides; on the command line (``--bases``) ``default`` and ``flat_base``
(:func:`base_name`)."""
OURS = {"ours": [], "ours_ddpg": ["agent=ddpg", "+experiment=short_run"]}
"""Each of our pipelines: its overrides (the defaults are PPO). DDPG with the preset for short off-policy runs
(``conf/experiment/short_run.yaml``): learning from its first batch on, as Stable-Baselines3 DDPG does,
and scored on its live actor (the defaults' 16,000 random frames first, 64 links and the actor's Polyak average are
for long runs: docs/benchmarks.md, "Time to quality")."""
SB3 = {"sb3_ddpg": ("agent=ddpg", sb3_ddpg), "sb3_ppo": ("agent=ppo", sb3_ppo)}
"""Each Stable-Baselines3 pipeline: our agent whose settings it takes, and its builder."""
CHUNK = 1_600
"""Frames between two scorings of every pipeline (one batch of our PPO, one of Stable-Baselines3 PPO's rollouts)."""
SCENARIO = Scenario("S1", "time to quality", None, ((12.0, 0.1, 0.0),), realisations=32, steps=500, seed=12345)
PIPELINES = [f"{name}{base}{suffix}" for base in BASES for name in (*OURS, *SB3) for suffix, _ in MODES.values()]
"""Every pipeline's record key, in the table's order."""


def base_name(suffix: str) -> str:
    """A base's name on the command line: ``default`` for ``""``, ``flat_base`` for ``"_flat_base"``."""
    return suffix.removeprefix("_") or "default"


def known_names() -> tuple[list[str], list[str]]:
    """The names a suite may be asked to run: its pipelines' (:data:`OURS`, :data:`SB3`) and its bases'
    (:func:`base_name`), for ``--pipelines`` and ``--bases``."""
    return [*OURS, *SB3], [base_name(base) for base in BASES]


def score(cfg, policy) -> float:
    """The greedy ``policy``'s ratio to the upper bound on :data:`SCENARIO`, scored eagerly whatever ``cfg``'s
    step (every pipeline the same way; the scoring is not timed)."""
    config = env_config(cfg, compile_kernel=False)
    return compare_policies(config, {"policy": policy}, SCENARIO)["policy"]["ratio_to_ub"]


def ours(frames: int, chunk: int, target: float, overrides: list[str]) -> dict:
    """One ``train()`` run of at most ``frames``, scored at each checkpoint (every ``chunk`` frames) until it
    reaches ``target``, which ends it: each scoring's (frames, seconds, ratio), and the seconds to the first that
    reached (the module docstring says what they count). The scorings leave the run's random streams alone; the
    run compiles from scratch, as in a process of its own (an empty compile cache, dynamo's forgotten)."""
    from torch._inductor.utils import fresh_cache

    from waterair.evaluation.policies import load_policy
    from waterair.training.loop import train

    cfg = compose_training(
        [*POINT, *overrides, f"total_frames={frames}", "eval.realisations=1", "eval.steps=1"]
        + ["logger.progress_bar=false", f"checkpoint.every_frames={chunk}"]
    )
    observation_size = env_config(cfg).observation_size
    runs: list[dict] = []
    scoring = 0.0
    torch._dynamo.reset()
    with tempfile.TemporaryDirectory() as run_dir, fresh_cache():

        def scored(done: int) -> bool:
            nonlocal scoring
            now = time.perf_counter()
            with torch.random.fork_rng():
                actor = load_policy(Path(run_dir) / "checkpoints" / "last.pt").actor(cfg.actor, observation_size)
                ratio = score(cfg, actor)
            runs.append({"frames": done, "seconds": now - start - scoring, "ratio_to_ub": ratio})
            scoring += time.perf_counter() - now
            return ratio >= target

        start = time.perf_counter()
        train(cfg, Path(run_dir), progress=lambda line: None, on_checkpoint=scored)
    return {"overrides": overrides, "runs": runs, "seconds_to_target": _first_reaching(runs, target)}


def sb3(name: str, frames: int, chunk: int, target: float, threads: int, overrides: list[str]) -> dict | None:
    """Stable-Baselines3 ``name`` (a key of :data:`SB3`) on the Gymnasium view of the same link (the defaults with
    ``overrides`` and that agent's settings) on ``threads`` torch threads, scored after every ``chunk`` frames until
    it reaches ``target`` or ``frames``: each (frames, seconds, ratio). Its seconds count model construction and
    learning, not the scoring."""
    agent, build = SB3[name]
    cfg = compose_training([agent, *POINT, *overrides])
    with torch_threads(threads):
        start = time.perf_counter()
        model = build(cfg, cfg.seed)
        if model is None:
            return None
        runs: list[dict] = []
        seconds = 0.0
        while not runs or (runs[-1]["frames"] < frames and runs[-1]["ratio_to_ub"] < target):
            model.learn(chunk, reset_num_timesteps=not runs)
            seconds += time.perf_counter() - start
            ratio = score(cfg, SB3Actor(model))
            runs.append({"frames": model.num_timesteps, "seconds": seconds, "ratio_to_ub": ratio})
            start = time.perf_counter()
    return {"overrides": overrides, "runs": runs, "seconds_to_target": _first_reaching(runs, target)}


CHILD = COLLECTOR_OFF + (
    "import json, sys; from waterair.bench import quality as q; print(json.dumps(q.run_pipeline(sys.argv[1])))"
)
"""The child's program (its imports frozen by :func:`run_pipeline`)."""


def in_fresh_python(kind: str, *args) -> dict | None:
    """:func:`ours` or :func:`sb3` (``kind``) with ``args`` in a Python process of its own, as a user's run would
    start: no graph, allocator state or thread pool of the pipelines before it, which slowed both sides when all
    ran in one process (docs/benchmarks.md, "Time to quality")."""
    request = json.dumps({"kind": kind, "args": args})
    return json.loads(last_line_of_fresh_python(CHILD, [request], f"the time-to-quality pipeline {kind}{args}"))


def run_pipeline(request: str) -> dict | None:
    """The child of :func:`in_fresh_python`: the pipeline ``request`` names (JSON: ``kind``, ``args``), once its
    modules are imported and frozen (:func:`enter_child`)."""
    asked = json.loads(request)
    pipelines = {"ours": ours, "sb3": sb3}
    if asked["kind"] not in pipelines:
        raise ValueError(f"no time-to-quality pipeline {asked['kind']!r}: ours or sb3")
    enter_child(asked["kind"])
    return pipelines[asked["kind"]](*asked["args"])


def enter_child(kind: str) -> None:
    """Import what the pipeline ``kind`` (``ours`` or ``sb3``) runs, then set the process up as train.py does after
    its imports (:func:`~waterair.core.process.set_up_process`): every object alive kept out of the garbage
    collector's walks, so that its full collections walk only what the run makes (unfrozen, about one a run took
    0.16-0.19 s on either side). Stable-Baselines3's side gets the same, though its own scripts would not."""
    if kind == "ours":
        import waterair.evaluation.policies
        import waterair.training.loop  # noqa: F401
    elif installed():
        import stable_baselines3  # noqa: F401
    set_up_process()


def bench_quality(
    frames: int,
    flat_frames: int,
    sb3_frames: int,
    modes: Sequence[str] = ("compiled",),
    chunk: int = CHUNK,
    target: float = 0.95,
    threads: int | str | None = None,
    seeds: Sequence[int] = (0,),
    pipelines: Sequence[str] | None = None,
    bases: Sequence[str] | None = None,
) -> dict:
    """Every pipeline on each base (ours in each of ``modes``, keys of :data:`MODES`), once per training seed in
    ``seeds``, each on ``threads`` torch threads (a count, or ``auto``: train.py's rule; default: every CPU this
    process may use), then per base the ratio of Stable-Baselines3's best median seconds to ``target`` over each of
    ours (:func:`over_seeds`): exact where an SB3 pipeline's median reached it, a lower bound (``..._at_least``)
    where none had by the end of its budget. ``pipelines`` (names of :data:`OURS` and :data:`SB3`) and ``bases``
    (``default``, ``flat_base``) choose some of them (default: all)."""
    names, base_names = known_names()
    pipelines = names if pipelines is None else list(pipelines)
    bases = base_names if bases is None else list(bases)
    for asked, known, what in ((pipelines, names, "pipeline"), (bases, base_names, "base")):
        if unknown := sorted(set(asked) - set(known)):
            raise ValueError(f"no time-to-quality {what} {', '.join(unknown)}: one of {', '.join(known)}")
    threads = len(os.sched_getaffinity(0)) if threads is None else choose_threads(threads)[0]
    record = {"benchmark": "quality", "target": target, "chunk": chunk, "threads": threads, "seeds": list(seeds)}
    record |= {"scenario": "S1 point, 32 seas x 500 steps, seed 12345", "pipelines": pipelines, "bases": bases}
    chosen = {base: overrides for base, overrides in BASES.items() if base_name(base) in bases}
    ours = {name: agent for name, agent in OURS.items() if name in pipelines}
    sb3s = [name for name in SB3 if name in pipelines]
    jobs: dict[str, tuple] = {}  # each pipeline's record key: (kind, leading arguments, overrides)
    for base, overrides in chosen.items():
        budget = flat_frames if base else frames
        for name, agent in ours.items():
            for mode in modes:
                suffix, how = MODES[mode]
                ours_on = [*agent, *overrides, f"threads={threads}", *how]
                jobs[f"{name}{base}{suffix}"] = ("ours", (budget, chunk, target), ours_on)
    for base, overrides in chosen.items():
        for name in sb3s:
            jobs[f"{name}{base}"] = ("sb3", (name, sb3_frames, chunk, target, threads), overrides)
    record |= over_seeds(seeds, jobs)
    for base in chosen:
        theirs = [record[f"{name}{base}"] for name in SB3 if record.get(f"{name}{base}") is not None]
        if not theirs:
            continue
        reached = [run["seconds_to_target"] for run in theirs if run["seconds_to_target"] is not None]
        best = min(reached) if reached else min(run["seconds_at_least"] for run in theirs)
        for mine in (f"{name}{base}{suffix}" for name in OURS for suffix, _ in MODES.values()):
            if mine in record and record[mine]["seconds_to_target"] is not None:
                key = f"sb3{base}_over_{mine}" + ("" if reached else "_at_least")
                record[key] = best / record[mine]["seconds_to_target"]
    return record


def over_seeds(seeds: Sequence[int], jobs: dict[str, tuple]) -> dict[str, dict | None]:
    """Every pipeline of ``jobs`` (its record key: the kind, :func:`ours` or :func:`sb3`, its leading arguments and
    its overrides) once per training seed, :func:`in_fresh_python` with ``seed=N`` added to the overrides, seed by
    seed: each seed's pipelines one after the other, so that a machine's drift over the run's minutes (docs/
    benchmarks.md, "Machines") falls on ours and Stable-Baselines3's alike. Per pipeline (None: not installed):
    each seed's result, the median over the seeds of the seconds to the target (None when half or more of them
    never reached it) and a lower bound of that median, each seed counting its seconds to the target or, where it
    never reached, at the end of its budget."""
    by_key: dict[str, list[dict]] = {key: [] for key in jobs}
    for seed in seeds:
        for key, (kind, leading, overrides) in jobs.items():
            result = in_fresh_python(kind, *leading, [*overrides, f"seed={seed}"])
            if result is not None:
                by_key[key].append({"seed": seed, **result})
    return {key: _median_over_seeds(by_seed) if by_seed else None for key, by_seed in by_key.items()}


def _median_over_seeds(by_seed: list[dict]) -> dict:
    median = statistics.median(math.inf if r["seconds_to_target"] is None else r["seconds_to_target"] for r in by_seed)
    last = (r["runs"][-1]["seconds"] if r["seconds_to_target"] is None else r["seconds_to_target"] for r in by_seed)
    at_least = statistics.median(last)
    reached = None if median == math.inf else median
    return {"by_seed": by_seed, "seconds_to_target": reached, "seconds_at_least": at_least}


def quality_table(record: dict) -> str:
    lines = ["| pipeline | seed | frames | seconds | greedy ratio to UB |", "|---|---|---|---|---|"]
    for name in (name for name in PIPELINES if record.get(name)):
        for result in record[name]["by_seed"]:
            for run in result["runs"]:
                seconds, ratio = f"{run['seconds']:.0f}", f"{run['ratio_to_ub']:.3f}"
                lines.append(f"| {name} | {result['seed']} | {run['frames']:,} | {seconds} | {ratio} |")
    for key, ratio in ((key, value) for key, value in record.items() if "_over_" in key):
        says = "at least " if key.endswith("_at_least") else ""
        mine = key.removesuffix("_at_least").split("_over_")[1]
        lines.append(f"| SB3's best median seconds / {mine}'s to {record['target']} | | | {says}{ratio:.1f} | |")
    return "\n".join(lines)


def _first_reaching(runs: list[dict], target: float) -> float | None:
    """The seconds of the first run whose ratio reaches ``target``, or None."""
    return next((run["seconds"] for run in runs if run["ratio_to_ub"] >= target), None)
