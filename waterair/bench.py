"""Benchmarks: ``python -m waterair.bench physics|env|evaluate [--out FILE.json]``.

Every number in one JSON file comes from one run on one machine, so ratios between them are
meaningful. Timings are wall-clock medians over ``--repeats`` runs after one warm-up run.

* ``physics``: path-solve time per batch (Newton cold and warm start, centroid), surface
  evaluations per second, the "sin+cos floor" (one ``sin`` and one ``cos`` over ``[B, K]``) and the
  ratio of a Newton solve to (evaluations per solve × floor).
* ``env``: raw ``env.step`` loop and TorchRL ``rollout`` env-steps per second and peak memory per
  batch size, with the floor ratio (step time / (surface evaluations per step × floor)); see
  :mod:`waterair.bench_env`.
* ``evaluate``: the default evaluation (shipped policy, every baseline, S1-S3), all policies in
  one batch against one rollout per policy; see :mod:`waterair.bench_eval`.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from collections.abc import Callable
from pathlib import Path

import torch

from waterair.channel import LinkGeometry
from waterair.env_config import resolve_device
from waterair.paths import solve_path
from waterair.sea import SeaState
from waterair.surface import WaveSurface, use_compiled_kernel

DT = 0.05
"""Time between a cold solve and the warm-started one (s), the environment's step."""


def timed(fn: Callable[[], object], repeats: int, device: torch.device) -> float:
    """Median wall-clock seconds of ``fn()`` over ``repeats`` runs, after one warm-up run."""
    fn()
    samples = []
    for _ in range(repeats):
        _sync(device)
        start = time.perf_counter()
        fn()
        _sync(device)
        samples.append(time.perf_counter() - start)
    return statistics.median(samples)


def sincos_floor(batch: int, harmonics: int, repeats: int, device: torch.device, dtype: torch.dtype) -> float:
    """Seconds for one ``sin`` and one ``cos`` over a ``[batch, harmonics]`` tensor."""
    x = torch.rand(batch, harmonics, device=device, dtype=dtype) * 100.0
    return timed(lambda: (torch.sin(x), torch.cos(x)), repeats, device)


def bench_physics(
    sizes: list[int], centroid_sizes: list[int], repeats: int, device: torch.device, dtype: torch.dtype, sea: SeaState
) -> dict:
    """Run the physics benchmark and return its JSON-ready record."""
    tx, rx = LinkGeometry().positions(dtype, device)
    harmonics = sea.n_freq * sea.n_dir
    rows = []
    for batch in sizes:
        surface = WaveSurface.sample(sea, batch, seed=0, device=device, dtype=dtype)
        floor = sincos_floor(batch, harmonics, repeats, device, dtype)
        x = torch.zeros(batch, device=device, dtype=dtype)
        evaluate = timed(lambda: surface.evaluate(x, x, 1.0, order=2), repeats, device)  # noqa: B023
        cold = solve_path(surface, tx, rx, 1.0)
        start = cold.point[:, :2]
        warm = solve_path(surface, tx, rx, 1.0 + DT, init=start)
        row = {
            "batch": batch,
            "sincos_floor_s": floor,
            "surface_eval_s": evaluate,
            "surface_evals_per_s": batch / evaluate,
            "newton_cold_s": timed(lambda: solve_path(surface, tx, rx, 1.0), repeats, device),  # noqa: B023
            "newton_cold_iterations": cold.iterations.float().mean().item(),
            "newton_cold_valid": cold.valid.float().mean().item(),
            "newton_warm_s": timed(lambda: solve_path(surface, tx, rx, 1.0 + DT, init=start), repeats, device),  # noqa: B023
            "newton_warm_iterations": warm.iterations.float().mean().item(),
            "newton_warm_valid": warm.valid.float().mean().item(),
        }
        # One evaluation per iteration plus the initial one; backtracking adds a few on some rows.
        for start_kind in ("cold", "warm"):
            evaluations = 1.0 + row[f"newton_{start_kind}_iterations"]
            row[f"newton_{start_kind}_floor_ratio"] = row[f"newton_{start_kind}_s"] / (evaluations * floor)
        if batch in centroid_sizes:
            centroid = solve_path(surface, tx, rx, 1.0, method="centroid")
            row["centroid_s"] = timed(lambda: solve_path(surface, tx, rx, 1.0, method="centroid"), 1, device)  # noqa: B023
            row["centroid_valid"] = centroid.valid.float().mean().item()
            agree = torch.linalg.vector_norm(centroid.point - cold.point, dim=-1) < 0.01
            row["centroid_within_1cm_of_newton"] = agree.float().mean().item()
        rows.append(row)
    return {"benchmark": "physics", **machine(device, dtype), "harmonics": harmonics, "wind": sea.wind, "rows": rows}


def physics_table(record: dict) -> str:
    """A Markdown table of a physics record."""
    lines = [
        f"physics benchmark: {record['device_name']}, {record['dtype']}, K = {record['harmonics']} harmonics, "
        f"{record['threads']} threads, {'compiled' if record.get('compiled_kernel') else 'eager'} surface kernel",
        "",
        "| B | sin+cos floor (ms) | surface evals/s | Newton cold (ms) | iters | ratio | Newton warm (ms) | iters "
        "| ratio | centroid (s) | centroid ≤ 1 cm |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in record["rows"]:
        centroid = (
            f"{r['centroid_s']:.2f} | {100 * r['centroid_within_1cm_of_newton']:.1f} %"
            if "centroid_s" in r
            else "– | –"
        )
        newton = " | ".join(
            f"{1e3 * r[f'newton_{kind}_s']:.2f} | {r[f'newton_{kind}_iterations']:.2f} "
            f"| {r[f'newton_{kind}_floor_ratio']:.2f}"
            for kind in ("cold", "warm")
        )
        floor = f"{1e3 * r['sincos_floor_s']:.3f} | {r['surface_evals_per_s']:.3g}"
        lines.append(f"| {r['batch']} | {floor} | {newton} | {centroid} |")
    return "\n".join(lines)


def machine(device: torch.device, dtype: torch.dtype) -> dict:
    """Where the numbers were measured."""
    name = torch.cuda.get_device_name(device) if device.type == "cuda" else (platform.processor() or platform.machine())
    return {
        "device": str(device),
        "device_name": name,
        "dtype": str(dtype).removeprefix("torch."),
        "threads": torch.get_num_threads(),
        "cpu_count": os.cpu_count(),
        "torch": torch.__version__,
        "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }


def _sync(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m waterair.bench", description="waterair benchmarks (JSON out)")
    sub = parser.add_subparsers(dest="suite", required=True)
    physics = sub.add_parser("physics", help="path solvers and surface evaluation")
    physics.add_argument("--sizes", type=int, nargs="+", default=[1, 64, 1024, 4096], help="batch sizes B")
    physics.add_argument(
        "--centroid-sizes",
        type=int,
        nargs="*",
        default=[1, 64, 1024],
        help="batch sizes at which the (slow) centroid solver is also timed",
    )
    physics.add_argument("--wind", type=float, default=12.0, help="wind speed U10 (m/s)")
    env = sub.add_parser("env", help="environment steps per second and memory")
    env.add_argument("--sizes", type=int, nargs="+", default=[1, 16, 256, 1024, 4096], help="batch sizes B")
    env.add_argument(
        "--centroid-sizes", type=int, nargs="*", default=[1, 16], help="batch sizes for the centroid solver"
    )
    evaluation = sub.add_parser("evaluate", help="the default evaluate.py work, batched vs one policy at a time")
    for p in (physics, env, evaluation):
        p.add_argument("--repeats", type=int, default=5, help="timed runs per measurement (median reported)")
        p.add_argument("--device", default="auto", help="cpu, cuda or auto")
        p.add_argument("--dtype", choices=["float32", "float64"], default="float32")
        p.add_argument("--compile", action="store_true", help="torch.compile the surface kernel first")
        p.add_argument("--out", type=Path, default=None, help="JSON output file (default outputs/bench/SUITE.json)")
    args = parser.parse_args(argv)
    device, dtype = resolve_device(args.device), getattr(torch, args.dtype)
    if args.suite == "evaluate":
        from waterair.bench_eval import bench_evaluate, evaluate_table

        record = {"machine": machine(device, dtype), **bench_evaluate(args.device, args.compile)}
        print(evaluate_table(record))
    elif args.suite == "env":
        from waterair.bench_env import ENV_HEADER, bench_env

        print(f"env benchmark: {device}, {'compiled' if args.compile else 'eager'} surface kernel\n\n{ENV_HEADER}")
        record = bench_env(args.sizes, args.centroid_sizes, args.compile, args.device)
    else:
        if args.compile:
            use_compiled_kernel(True)
        try:
            sea = SeaState(wind=args.wind)
        except ValueError as error:
            parser.exit(2, f"error: {error}\n")
        record = bench_physics(args.sizes, args.centroid_sizes, args.repeats, device, dtype, sea)
        record["compiled_kernel"] = args.compile
        print(physics_table(record))
    out = args.out or Path("outputs/bench") / f"{args.suite}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(record, indent=2))
    print(f"\nwritten {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
