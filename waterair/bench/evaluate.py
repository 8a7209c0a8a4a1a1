"""Evaluation benchmark: ``python -m waterair.bench evaluate`` (see :mod:`waterair.bench`).

Times ``evaluate.py``'s work on the default scenarios (shipped policies, every baseline) twice in one
process: all policies of a scenario in one batch (``batch_policies=true``, the default) and one
rollout per policy. The kernel is compiled by a small warm-up first, so neither pays for it. With
``--compile``, the evaluation's compile is also timed alone from an empty compile cache (:func:`cold_compile`):
its graphs have a symbolic batch, and a layout that the environment's step compiles quickly can compile
several times slower there.
"""

from __future__ import annotations

import tempfile
import time

from hydra import compose, initialize_config_dir

from waterair.bench.common import seconds_in_fresh_python
from waterair.evaluation.runner import evaluate
from waterair.training.config import CONF_DIR

CONF = CONF_DIR
COLD = [
    "scenarios.S1.realisations=2",
    "scenarios.S1.steps=5",
    *(f"scenarios.{name}=null" for name in ("S2", "S3", "S4", "S5")),
    "workers=1",
    "physics_figures=false",
]
WARM_UP = [
    "scenarios.S1.realisations=2",
    "scenarios.S1.steps=5",
    "scenarios.S2.realisations=2",
    "scenarios.S2.steps=5",
    "scenarios.S3.realisations=2",
    "scenarios.S3.steps=5",
]


def bench_evaluate(device: str, compile_kernel: bool, overrides: list[str] | None = None) -> dict:
    """Seconds and link-steps per second of the default evaluation, batched and one policy at a time."""
    base = [f"device={device}", f"env.compile_kernel={str(compile_kernel).lower()}", *(overrides or [])]
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        warm = compose(config_name="evaluate", overrides=[*base, *WARM_UP])
        configs = {
            mode: compose(config_name="evaluate", overrides=[*base, f"batch_policies={mode == 'batched'}"])
            for mode in ("batched", "one_at_a_time")
        }
    clock = time.perf_counter()
    evaluate(warm, progress=lambda _: None)
    record = {"warm_up_s": time.perf_counter() - clock, "modes": {}}
    for mode, cfg in configs.items():
        result = evaluate(cfg, progress=lambda _: None)
        policies = len(result.policies) - 1  # the upper bound is not a rollout
        links = {}
        for scenario in result.scenarios:  # S2 and S3 share a batch: count each distinct point once
            key = (scenario.realisations, scenario.steps, scenario.seed)
            links.setdefault(key, set()).update(scenario.points)
        link_steps = sum(len(points) * r * steps for (r, steps, _), points in links.items()) * policies
        record["modes"][mode] = {
            "seconds": result.seconds,
            "policies": policies,
            "link_steps": link_steps,
            "link_steps_per_s": link_steps / result.seconds,
        }
    modes = record["modes"]
    record["speedup_batched"] = modes["one_at_a_time"]["seconds"] / modes["batched"]["seconds"]
    if compile_kernel:
        record["cold_compile_s"] = cold_compile(base)
    return record


def cold_compile(overrides: list[str]) -> float:
    """Seconds of a fresh process's evaluation of S1 on two seas for five steps, its step compiled, with a new
    (empty) ``TORCHINDUCTOR_CACHE_DIR``: the evaluation's compile, as a first ``evaluate.py`` on a machine pays it."""
    code = (
        "import sys, time; start = time.perf_counter(); "
        "from waterair.core.process import set_up_process; set_up_process(); "  # as evaluate.py's process
        "from hydra import compose, initialize_config_dir; "
        "from waterair.evaluation.runner import evaluate; "
        f"initialize_config_dir(config_dir={str(CONF)!r}, version_base='1.3'); "
        "evaluate(compose(config_name='evaluate', overrides=sys.argv[1:]), progress=lambda _: None); "
        "print(time.perf_counter() - start)"
    )
    with tempfile.TemporaryDirectory() as cache:
        return seconds_in_fresh_python(code, [*overrides, *COLD], cache, "cold evaluation compile")


def evaluate_table(record: dict) -> str:
    lines = ["| mode | seconds | link-steps | link-steps/s |", "|---|---|---|---|"]
    for mode, r in record["modes"].items():
        lines.append(f"| {mode} | {r['seconds']:.1f} | {r['link_steps']:,} | {r['link_steps_per_s']:,.0f} |")
    lines.append(f"\nbatched is {record['speedup_batched']:.2f}x faster; warm-up (compile) {record['warm_up_s']:.1f} s")
    if "cold_compile_s" in record:
        lines.append(f"S1's evaluation compiled from an empty cache: {record['cold_compile_s']:.1f} s")
    return "\n".join(lines)
