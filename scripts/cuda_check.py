"""The package on a CUDA GPU, end to end (``make cuda-check`` on a machine with one; not part of ``make test``).

CI has no GPU, so what "unchanged on CUDA" promises is checked here. Each part's result goes to
``OUT/cuda_check_<parts>.json`` as soon as it is known (the benchmark's after each point), so a part that fails or
a run cut short keeps the rest:
  1. ``agree``: the defaults' environment and the paper's (``+experiment=paper``), eager, on the CPU and on CUDA
     from the same seed and actions: float64 to 1e-9 relative, float32 to 1e-4;
  2. ``bench``: env-steps/s at B = 1024 and 65,536 of the paper's one path compiled and the defaults' full
     channel eager and compiled (:func:`waterair.bench.env.run_worker`, each point in a fresh process);
  3. ``montecarlo``: the local estimate's rays/s (``python -m waterair.bench montecarlo``);
  4. ``compiled``: the defaults' environment compiled on CUDA against itself eager, link by link;
  5. ``train``: a short train.py run on CUDA (networks, updates, environment and its closing evaluation);
  6. ``evaluate``: ``make evaluate``'s evaluate.py (the shipped policies, S1-S5) on CUDA, timed.
The whole takes longer than one 10-minute call on an H200 (compiles of about a minute each, evaluate.py over
3 minutes): ``--parts`` runs some, each call writing its own file.
Exit status 1 if a part disagrees or fails. ``--device cpu`` runs the parts on the CPU alone (a dry run: the
comparisons are then of the CPU with itself). On a machine with its own CUDA build of torch and no network, the
other packages can come as wheels on ``PYTHONPATH`` (torchrl, tensordict, hydra-core, omegaconf, antlr4 and
their small dependencies), with this repository's root on it too.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
import traceback
from pathlib import Path

import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from waterair.bench.env import run_worker  # noqa: E402
from waterair.bench.training import compose_training  # noqa: E402
from waterair.envs.config import EnvConfig  # noqa: E402
from waterair.envs.env import WaterAirEnv  # noqa: E402
from waterair.training import builders  # noqa: E402

COMPARED = ("observation", "gain", "gain_upper_bound", "intensity", "reward", "path_valid")
SHORT = ["total_frames=3200", "eval.realisations=4", "eval.steps=20", "logger.progress_bar=false"]
"""train.py's defaults, shortened: two of the default collector's batches, a small closing evaluation."""


def env_config(overrides: list[str], batch: int, dtype: str, device: str, compile_kernel: bool) -> EnvConfig:
    """train.py's env for ``overrides``, ``batch`` links on ``device``."""
    settings = {"num_envs": batch, "seed": 11, "max_steps": 10**6, "device": device, "dtype": dtype}
    return builders.env_config(compose_training(overrides), compile_kernel=compile_kernel, **settings)


def rollout(config: EnvConfig, actions: torch.Tensor) -> dict[str, torch.Tensor]:
    env = WaterAirEnv(config)
    td, trace = env.reset(), {key: [] for key in COMPARED}
    start = time.perf_counter()
    for action in actions:
        td = env.step(td.set("action", action.to(env.device, env.float_dtype)))["next"]
        for key in COMPARED:
            trace[key].append(td[key].cpu())
    return {key: torch.stack(v) for key, v in trace.items()} | {"seconds": time.perf_counter() - start}


def gap(got: dict, want: dict, key: str) -> torch.Tensor:
    """``got[key]``'s difference from ``want[key]``, elementwise, relative to ``want[key]``'s largest value."""
    a, b = got[key].double(), want[key].double()
    return (a - b).abs() / b.abs().amax().clamp_min(1e-30)


def differences(got: dict, want: dict) -> dict:
    """Per key: the largest :func:`gap`, and whether ``got``'s values are all finite."""
    return {
        key: {"max_rel": gap(got, want, key).max().item(), "finite": bool(torch.isfinite(got[key].double()).all())}
        for key in COMPARED
    }


def part_agree(device: str, quick: bool) -> dict:
    batch, steps = (4, 5) if quick else (16, 30)
    actions = 0.3 * torch.randn(steps, batch, 4, generator=torch.Generator().manual_seed(3))
    record, ok = {}, True
    for name, overrides in (("defaults", []), ("paper", ["+experiment=paper"])):
        for dtype, rtol in (("float64", 1e-9), ("float32", 1e-4)):
            cpu = rollout(env_config(overrides, batch, dtype, "cpu", False), actions)
            other = rollout(env_config(overrides, batch, dtype, device, False), actions)
            diff = differences(other, cpu)
            passed = all(d["finite"] and d["max_rel"] <= rtol for d in diff.values())
            record[f"{name}_{dtype}"] = {
                "tolerance": rtol,
                "passed": passed,
                "keys": diff,
                "cpu_s": cpu["seconds"],
                f"{device}_s": other["seconds"],
            }
            ok &= passed
    return {"passed": ok, **record}


def links_apart(got: dict, want: dict, steps: int, batch: int, tolerance: float = 1e-4) -> torch.Tensor:
    """``[batch]``: the links whose ``COMPARED`` outputs in ``got`` differ from ``want``'s at some step by more
    than ``tolerance`` of the key's largest value."""
    apart = torch.zeros(batch, dtype=torch.bool)
    for key in COMPARED:
        apart |= gap(got, want, key).reshape(steps, batch, -1).amax(dim=(0, 2)) > tolerance
    return apart


def part_compiled(device: str, quick: bool) -> dict:
    """Compiled against eager, link by link: a link whose readings cross a threshold (a reading lost, a spot
    saturating) one way in one and the other way in the other steers apart from there on, through its closed loop,
    as rounding decides; so the check is that nearly every link agrees to float32 rounding, not every one."""
    batch, steps = (4, 5) if quick else (64, 20)
    actions = 0.3 * torch.randn(steps, batch, 4, generator=torch.Generator().manual_seed(5))
    start = time.perf_counter()
    compiled = rollout(env_config([], batch, "float32", device, True), actions)
    compiled_s = time.perf_counter() - start
    eager = rollout(env_config([], batch, "float32", device, False), actions)
    apart, keys = links_apart(compiled, eager, steps, batch), differences(compiled, eager)
    finite = all(key["finite"] for key in keys.values())
    return {
        "passed": finite and apart.float().mean().item() <= 0.05,
        "links_apart": apart.sum().item(),
        "links": batch,
        "finite": finite,
        "keys": keys,
        "compiled_first_rollout_s": compiled_s,
        "eager_rollout_s": eager["seconds"],
    }


def part_train(device: str, out: Path) -> dict:
    run = out / "train_run"
    start = time.perf_counter()
    trained = subprocess.run(
        [sys.executable, "train.py", f"device={device}", *SHORT, f"hydra.run.dir={run}"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
    )
    train_s = time.perf_counter() - start
    record = {
        "train_exit": trained.returncode,
        "train_s": train_s,
        "train_tail": trained.stdout[-1500:] + trained.stderr[-3000:],
    }
    if trained.returncode == 0:
        metrics = json.loads((run / "final_metrics.json").read_text())
        record["final_metrics"] = metrics
        record["finite"] = all(v == v and abs(v) != float("inf") for v in metrics.values() if isinstance(v, float))
    record["passed"] = trained.returncode == 0 and record.get("finite", False)
    return record


def part_bench(device: str, quick: bool, chosen: list[str], save) -> dict:
    """Env-steps/s at B = 1024 and 65,536, each point in a fresh process; ``chosen``: "channel:sea:compiled:B"
    cases instead. ``save`` is called with the rows so far after each point (a run cut short keeps them)."""
    cases = [
        (channel, sea, compiled, batch)
        for batch in (1024, 65536)
        for channel, sea, compiled in (
            ("single_path", "paper", True),
            ("full", "ocean", False),
            ("full", "ocean", True),
        )
    ]
    if chosen:
        cases = [(c, s, k == "1", int(b)) for c, s, k, b in (case.split(":") for case in chosen)]
    if quick:
        cases = [(c, s, k, 16) for c, s, k, _ in cases[:1]]
    rows: list[dict] = []
    for channel, sea, compile_kernel, batch in cases:
        start = time.perf_counter()
        try:
            row = run_worker(batch, "newton", compile_kernel, device, "float32", channel, sea)
        except RuntimeError as error:
            row = {"batch": batch, "channel": channel, "sea": sea, "error": str(error)[-1500:]}
        row.update(compiled=compile_kernel, process_s=time.perf_counter() - start)
        rows.append(row)
        save({"passed": all("error" not in r for r in rows), "rows": rows})
        print(
            json.dumps(
                {
                    k: row.get(k)
                    for k in (
                        "batch",
                        "channel",
                        "sea",
                        "compiled",
                        "env_steps_per_s",
                        "first_step_s",
                        "peak_memory_mb",
                        "process_s",
                    )
                }
            ),
            flush=True,
        )
    return {"passed": all("error" not in r for r in rows), "rows": rows}


def part_montecarlo(device: str, out: Path, quick: bool) -> dict:
    """The local estimate's rays/s (``python -m waterair.bench montecarlo``, one wind)."""
    size = ["--seas", "2", "--steps", "1", "--rays", "200"] if quick else ["--seas", "64", "--steps", "5"]
    command = [
        sys.executable,
        "-m",
        "waterair.bench",
        "montecarlo",
        "--device",
        device,
        "--winds",
        "12",
        "--rays",
        "10000",
        *size,
        "--reference",
        "local",
        "--dtype",
        "float64",
        "--out",
        str(out / "mc.json"),
    ]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, check=False)
    record = {
        "passed": done.returncode == 0,
        "exit": done.returncode,
        "tail": done.stdout[-2000:] + done.stderr[-2000:],
    }
    if done.returncode == 0:
        record["speed"] = json.loads((out / "mc.json").read_text())["speed"]
    return record


def part_evaluate(device: str, out: Path) -> dict:
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "evaluate.py", f"device={device}", f"hydra.run.dir={out / 'evaluate'}"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
    )
    return {
        "passed": done.returncode == 0,
        "exit": done.returncode,
        "seconds": time.perf_counter() - start,
        "tail": done.stdout[-3000:] + done.stderr[-3000:],
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "outputs" / "cuda_check")
    parser.add_argument("--work", type=Path, default=None, help="where the runs go (default: OUT)")
    parser.add_argument("--device", default="cuda")
    parser.add_argument("--parts", nargs="+", default=["agree", "bench", "montecarlo", "compiled", "train", "evaluate"])
    parser.add_argument("--cases", nargs="*", default=[], help='bench cases "channel:sea:compiled(0|1):B"')
    parser.add_argument("--quick", action="store_true", help="small batches and few steps (a dry run)")
    args = parser.parse_args()
    record: dict = {"torch": torch.__version__, "cuda": torch.version.cuda, "device": args.device}
    if args.device == "cuda":
        if not torch.cuda.is_available():
            parser.exit(1, "error: no CUDA device here (torch.cuda.is_available() is False); --device cpu: a dry run\n")
        record["gpu"] = torch.cuda.get_device_name()
    work = args.work or args.out
    for folder in (args.out, work):
        folder.mkdir(parents=True, exist_ok=True)
    name_of_file = args.out / f"cuda_check_{'_'.join(args.parts)}.json"

    def save(name: str, value: dict) -> None:
        record[name] = value
        name_of_file.write_text(json.dumps(record, indent=1, default=str))

    parts = {
        "agree": lambda: part_agree(args.device, args.quick),
        "compiled": lambda: part_compiled(args.device, args.quick),
        "train": lambda: part_train(args.device, work),
        "bench": lambda: part_bench(args.device, args.quick, args.cases, lambda rows: save("bench", rows)),
        "montecarlo": lambda: part_montecarlo(args.device, work, args.quick),
        "evaluate": lambda: part_evaluate(args.device, work),
    }
    for name in args.parts:
        start = time.perf_counter()
        try:
            record[name] = parts[name]()
        except Exception:  # noqa: BLE001 - a failed part is recorded and the others still run
            record[name] = {"passed": False, "error": traceback.format_exc()[-3000:]}
        record[name]["part_s"] = time.perf_counter() - start
        print(
            f"[cuda-check] {name}: {'passed' if record[name]['passed'] else 'FAILED'} "
            f"in {record[name]['part_s']:.0f} s",
            flush=True,
        )
        save(name, record[name])
    return 0 if all(record[name]["passed"] for name in args.parts) else 1


if __name__ == "__main__":
    from waterair.core.process import set_up_process

    set_up_process()  # as train.py's process
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    sys.exit(main())
