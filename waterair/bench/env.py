"""Environment benchmark: ``python -m waterair.bench env`` (see :mod:`waterair.bench`).

Each (B, solver) point runs in a fresh worker process so that its peak resident memory is its
own; the worker reports JSON on stdout. The sin+cos floor is measured inside the same worker.
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import time

import torch

from waterair.bench.common import machine, sincos_floor
from waterair.core.devices import resolve_device
from waterair.envs.env import WaterAirEnv
from waterair.physics import solve_path

SECONDS_PER_MEASUREMENT = 2.0
"""Each timing runs about this long (at least 5 steps)."""
SAMPLED_STEPS = 20
"""Steps over which the solver iterations per step are counted (outside the timed loop)."""


def worker(batch: int, solver: str, compile_kernel: bool, device: str, dtype: str) -> dict:
    """Time raw ``env.step`` and ``env.rollout`` at one batch size (runs inside the worker)."""
    baseline_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    env = WaterAirEnv(
        num_envs=batch,
        seed=0,
        solver=solver,
        compile_kernel=compile_kernel,
        device=device,
        dtype=dtype,
        max_steps=10**6,
    )
    td = env.reset()
    generator = torch.Generator().manual_seed(0)
    td["action"] = (2 * torch.rand(batch, 4, generator=generator) - 1).to(env.device)
    for _ in range(10):  # warm-up: compilation, allocator
        td = env.step(td)["next"].set("action", td["action"])
    start = time.perf_counter()
    for _ in range(3):
        td = env.step(td)["next"].set("action", td["action"])
    steps = max(5, int(SECONDS_PER_MEASUREMENT / ((time.perf_counter() - start) / 3)))
    start = time.perf_counter()
    for _ in range(steps):
        td = env.step(td)["next"].set("action", td["action"])
    if env.device.type == "cuda":
        torch.cuda.synchronize()
    step_s = (time.perf_counter() - start) / steps
    start = time.perf_counter()
    env.rollout(steps, break_when_any_done=False)
    if env.device.type == "cuda":
        torch.cuda.synchronize()
    rollout_s = (time.perf_counter() - start) / steps
    floor = sincos_floor(batch, env.surface.num_harmonics, 5, env.device, env.float_dtype)
    evaluations = 1.0 + mean_iterations(env, td, SAMPLED_STEPS)
    peak_mb = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - baseline_kb) / 1024
    if env.device.type == "cuda":
        peak_mb = torch.cuda.max_memory_allocated() / 2**20
    return {
        "batch": batch,
        "solver": solver,
        "steps_timed": steps,
        "step_s": step_s,
        "env_steps_per_s": batch / step_s,
        "rollout_env_steps_per_s": batch / rollout_s,
        "sincos_floor_s": floor,
        "evaluations_per_step": evaluations,
        "floor_ratio": step_s / (evaluations * floor),
        "peak_memory_mb": peak_mb,
    }


def mean_iterations(env: WaterAirEnv, td, steps: int) -> float:
    """Mean solver iterations of the path solve in each of the next ``steps`` steps.

    Before each step the same warm-started solve the step will make is repeated outside it (the
    path point of the last step, the next time), so the timed steps carry no counting.
    """
    counts = []
    for _ in range(steps):
        path = solve_path(
            env.surface,
            env.tx_position,
            env.rx_position,
            env.time + env.config.dt,
            env.config.solver,
            init=env.point[:, :2],
            n_water=env.optics.n_water,
            n_air=env.optics.n_air,
            compiled=env.config.compile_kernel,
        )
        counts.append(path.iterations.double().mean().item())
        td = env.step(td)["next"].set("action", td["action"])
    return sum(counts) / len(counts)


def bench_env(sizes, centroid_sizes, compile_kernel: bool, device: str, dtype: str) -> dict:
    """Run every (B, solver) point in its own process and collect the records."""
    rows = []
    for solver, solver_sizes in (("newton", sizes), ("centroid", centroid_sizes)):
        for batch in solver_sizes:
            args = [
                sys.executable,
                "-m",
                "waterair.bench.env",
                str(batch),
                solver,
                str(int(compile_kernel)),
                device,
                dtype,
            ]
            done = subprocess.run(args, capture_output=True, text=True, check=False)
            if done.returncode != 0:
                raise RuntimeError(f"env benchmark worker B={batch} {solver} failed:\n{done.stderr[-2000:]}")
            rows.append(json.loads(done.stdout.strip().splitlines()[-1]))
            print(env_row(rows[-1]), flush=True)
    resolved = resolve_device(device)
    return {
        "benchmark": "env",
        **machine(resolved, getattr(torch, dtype)),
        "compiled_kernel": compile_kernel,
        "rows": rows,
    }


ENV_HEADER = (
    "| B | solver | env-steps/s (step loop) | env-steps/s (rollout) | evals/step | floor ratio | peak memory (MB) |\n"
    "|---|---|---|---|---|---|---|"
)


def env_row(r: dict) -> str:
    return (
        f"| {r['batch']} | {r['solver']} | {r['env_steps_per_s']:,.0f} | {r['rollout_env_steps_per_s']:,.0f} "
        f"| {r['evaluations_per_step']:.2f} | {r['floor_ratio']:.2f} | {r['peak_memory_mb']:.0f} |"
    )


if __name__ == "__main__":
    batch_arg, solver_arg, compile_arg, device_arg, dtype_arg = sys.argv[1:6]
    print(json.dumps(worker(int(batch_arg), solver_arg, bool(int(compile_arg)), device_arg, dtype_arg)))
