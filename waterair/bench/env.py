"""Environment benchmark: ``python -m waterair.bench env`` (see :mod:`waterair.bench`).

Each (B, solver) point runs in a fresh worker process so that its peak resident memory is its
own; the worker reports JSON on stdout. The sin+cos floor is measured inside the same worker.
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import tempfile
import time

import torch

from waterair.bench.common import machine, seconds_in_fresh_python, sincos_floor, sincos_per_element
from waterair.core.devices import resolve_device
from waterair.envs.env import WaterAirEnv
from waterair.physics.channel import TwoScale

SECONDS_PER_MEASUREMENT = 2.0
"""Each timing runs about this long (at least 5 steps)."""
SAMPLED_STEPS = 20
"""Steps over which the path solve's convergence is counted (outside the timed loop)."""


LATTICES_PER_STEP = 2
"""Lattices of the full channel a link-step evaluates: the bound's around the tracked point and the beam's
(``TwoScale.light`` given the transmitter's pointing; docs/model.md §4.3)."""

SEAS = {"paper": {"sea": {"spectrum": "jonswap"}}, "ocean": {"sea": {"spectrum": "elfouhaily", "n_dir": 16}}}
"""The seas of ``env/spectrum=jonswap|elfouhaily`` (conf/env/spectrum), by short names."""


def worker(
    batch: int,
    solver: str,
    compile_kernel: bool,
    device: str,
    dtype: str,
    channel: str = "single_path",
    sea="paper",
    lattice: str = "",
    actuator: str = "ideal",
    motion: str = "static",
) -> dict:
    """Time raw ``env.step`` and ``env.rollout`` at one batch size (runs inside the worker); ``lattice``
    "nodes:span" sets the full channel's lattice (default: the env's), ``actuator`` the ends' (``env/actuator``),
    ``motion`` how they move (``env/motion``)."""
    baseline_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    start = time.perf_counter()
    env = WaterAirEnv(
        num_envs=batch,
        seed=0,
        solver=solver,
        compile_kernel=compile_kernel,
        device=device,
        dtype=dtype,
        max_steps=10**6,
        channel={"name": channel, **lattice_settings(lattice)},
        actuator={"kind": actuator},
        motion={"kind": motion},
        **SEAS[sea],
    )
    td = env.reset()
    generator = torch.Generator().manual_seed(0)
    td["action"] = (2 * torch.rand(batch, 4, generator=generator) - 1).to(env.device)
    td = env.step(td)["next"].set("action", td["action"])
    first_step_s = time.perf_counter() - start  # construction, reset and the first step: the compile
    for _ in range(40):  # warm-up: the finishing graphs compile when first needed, allocator
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
    solves = solver_counts(env, td, SAMPLED_STEPS) if solver == "newton" else {}
    evaluations = solves.get("evaluations_per_step", float("nan"))
    peak_mb = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - baseline_kb) / 1024
    if env.device.type == "cuda":
        peak_mb = torch.cuda.max_memory_allocated() / 2**20
    lattice = {}
    if isinstance(env.channel, TwoScale):  # the full channel on a two-scale sea (on the paper's: ray tubes)
        per_element = sincos_per_element(5, env.device, env.float_dtype)
        lattice["lattice_floor_s"] = lattice_floor(per_element, batch, env.channel.nodes, env.surface.num_harmonics)
        lattice["lattice_floor_ratio"] = step_s / lattice["lattice_floor_s"]
    return {
        "batch": batch,
        "solver": solver,
        "channel": channel,
        "sea": sea,
        "actuator": actuator,
        "motion": motion,
        "steps_timed": steps,
        "step_s": step_s,
        "env_steps_per_s": batch / step_s,
        "rollout_env_steps_per_s": batch / rollout_s,
        "sincos_floor_s": floor,
        **solves,
        "floor_ratio": step_s / (evaluations * floor),
        "first_step_s": first_step_s,
        "peak_memory_mb": peak_mb,
        **lattice,
    }


def lattice_floor(per_element: float, batch: int, nodes: int, harmonics: int) -> float:
    """Seconds of the naive floor of a full-channel step on lattices of ``nodes`` × ``nodes``: one sin and one
    cos (``per_element`` s) per link, node of each of its :data:`LATTICES_PER_STEP` lattices and harmonic."""
    return per_element * batch * LATTICES_PER_STEP * nodes**2 * harmonics


def solver_counts(env: WaterAirEnv, td, steps: int) -> dict:
    """How the step's path solve fares over the next ``steps`` steps (counted outside the timed loop).

    Before each step the step's own fixed-iteration solve is repeated eagerly on the same state:
    ``evaluations_per_step`` surface evaluations per link in the step's graph (1 + iterations),
    ``unconverged_fraction`` the links it leaves to the finishing stage, ``finishing_steps`` the
    share of steps that need that stage at all.
    """
    unconverged, finishing = [], []
    for _ in range(steps):
        left = env.unconverged_links()
        unconverged.append(left.double().mean().item())
        finishing.append(float(left.any()))
        td = env.step(td)["next"].set("action", td["action"])
    return {
        "evaluations_per_step": 1.0 + env.config.newton_iterations,
        "unconverged_fraction": sum(unconverged) / steps,
        "finishing_steps": sum(finishing) / steps,
    }


def compile_times(batch: int = 16) -> dict:
    """Seconds to build a compiled env and take its first step with torch's compile cache cold, then warm.

    Each runs in a fresh process with its own (new, then reused) ``TORCHINDUCTOR_CACHE_DIR``.
    """
    code = (
        "import time, torch; start = time.perf_counter(); "
        "from waterair.core.process import set_up_process; set_up_process(); "  # as train.py's process
        "from waterair.envs.env import WaterAirEnv; "
        f"env = WaterAirEnv(num_envs={batch}, seed=0, compile_kernel=True); td = env.reset(); "
        f"env.step(td.set('action', torch.zeros({batch}, 4))); print(time.perf_counter() - start)"
    )
    with tempfile.TemporaryDirectory() as cache:
        record = {name: seconds_in_fresh_python(code, [], cache, "compile-time probe") for name in ("cold_s", "warm_s")}
    return {"batch": batch, **record}


def lattice_settings(lattice: str) -> dict:
    """``"nodes:span"`` as the full channel's keys (none for "")."""
    if not lattice:
        return {}
    nodes, span = lattice.split(":")
    return {"nodes": int(nodes), "span": float(span)}


def run_worker(batch: int, solver: str, compile_kernel: bool, device: str, dtype: str, *case: str):
    """One :func:`worker` in a fresh process; its record. ``case``: the channel, the sea, the lattice, the actuator
    and the motion, each as :func:`worker` takes it (the last three may be left out)."""
    case = (*case, *("single_path", "paper", "", "ideal", "static")[len(case) :])
    args = [sys.executable, "-m", "waterair.bench.env", str(batch), solver, str(int(compile_kernel))]
    done = subprocess.run([*args, device, dtype, *case], capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"env benchmark worker B={batch} {solver} {' '.join(case)} failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def bench_channels(sizes, compile_kernel: bool, device: str, dtype: str, lattices=("",)) -> dict:
    """The channel models side by side, in one run: (channel, sea) for every B, each in its own process; the
    full channel on the measured-slope sea once per lattice ("nodes:span", "" the default), and once more through
    a gimbal carrying a mirror at each end (``env/actuator=gimbal_fsm``: what the actuators cost a step), and with
    the ends moving too (``env/motion=hover``)."""
    rows = []
    cases = [
        ("single_path", "paper", "", "ideal", "static"),
        ("full", "paper", "", "ideal", "static"),
        ("single_path", "ocean", "", "ideal", "static"),
    ]
    cases += [("full", "ocean", lattice, "ideal", "static") for lattice in lattices]
    cases += [("full", "ocean", "", "gimbal_fsm", "static"), ("full", "ocean", "", "gimbal_fsm", "hover")]
    for batch in sizes:
        for case in cases:
            rows.append(run_worker(batch, "newton", compile_kernel, device, dtype, *case))
            rows[-1]["lattice"] = case[2]
            print(env_row(rows[-1]), flush=True)
    resolved = resolve_device(device)
    return {
        "benchmark": "channel",
        **machine(resolved, getattr(torch, dtype)),
        "compiled_kernel": compile_kernel,
        "rows": rows,
    }


def bench_env(sizes, centroid_sizes, compile_kernel: bool, device: str, dtype: str) -> dict:
    """Run every (B, solver) point in its own process and collect the records."""
    rows = []
    for solver, solver_sizes in (("newton", sizes), ("centroid", centroid_sizes)):
        for batch in solver_sizes:
            rows.append(run_worker(batch, solver, compile_kernel, device, dtype, "single_path", "paper"))
            print(env_row(rows[-1]), flush=True)
    resolved = resolve_device(device)
    record = {
        "benchmark": "env",
        **machine(resolved, getattr(torch, dtype)),
        "compiled_kernel": compile_kernel,
        "rows": rows,
    }
    if compile_kernel:
        record["compile"] = compile_times()
        print(
            f"\ncompile (B = 16, build + first step): cold cache {record['compile']['cold_s']:.1f} s, "
            f"warm cache {record['compile']['warm_s']:.1f} s"
        )
    return record


ENV_HEADER = (
    "| B | solver / channel, sea | env-steps/s (step loop) | env-steps/s (rollout) | evals/step | left to finish "
    "| steps finishing | floor ratio | lattice floor ratio | peak memory (MB) |\n"
    "|---|---|---|---|---|---|---|---|---|---|"
)
"""The printed table's head; the lattice floor ratio (step / :func:`lattice_floor`) is the two-scale full
channel's (the measured-slope sea)."""


def env_row(r: dict) -> str:
    solve = (
        f"| {r['evaluations_per_step']:.0f} | {100 * r['unconverged_fraction']:.1f} % "
        f"| {100 * r['finishing_steps']:.0f} % | {r['floor_ratio']:.2f} "
        if "unconverged_fraction" in r
        else "| – | – | – | – "
    )
    lattice = f"{r['lattice_floor_ratio']:.2f}" if "lattice_floor_ratio" in r else "–"
    return (
        f"| {r['batch']} | {_label(r)} | {r['env_steps_per_s']:,.0f} | {r['rollout_env_steps_per_s']:,.0f} "
        f"{solve}| {lattice} | {r['peak_memory_mb']:.0f} |"
    )


def _label(r: dict) -> str:
    if r.get("channel", "single_path") == "single_path" and r.get("sea", "paper") == "paper":
        return r["solver"]
    lattice = f" ({r['lattice'].replace(':', ' nodes ±')} σ)" if r.get("lattice") else ""
    actuator = f", {r['actuator']}" if r.get("actuator", "ideal") != "ideal" else ""
    motion = f", {r['motion']}" if r.get("motion", "static") != "static" else ""
    return f"{r['channel']}, {r['sea']}{lattice}{actuator}{motion}"


if __name__ == "__main__":
    from waterair.core.process import set_up_process

    set_up_process()  # as train.py's process
    batch_arg, solver_arg, compile_arg, device_arg, dtype_arg, *case_args = sys.argv[1:11]
    print(json.dumps(worker(int(batch_arg), solver_arg, bool(int(compile_arg)), device_arg, dtype_arg, *case_args)))
