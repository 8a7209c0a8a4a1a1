"""Controller benchmark: ``python -m waterair.bench controllers`` (see :mod:`waterair.bench`).

The cost the classical controllers and the sensor model add to an environment step: rollouts of
``steps`` steps at batch size B under the flat-sea Snell baseline (the reference), the
``aoa_tracker`` and the ``intensity_dither``, with the ideal and the realistic sensor.
"""

from __future__ import annotations

import time

import torch

from waterair.envs.baselines import FlatSeaSnell
from waterair.envs.controllers import AoATracker, IntensityDither
from waterair.envs.env import WaterAirEnv

REALISTIC = {
    "latency_steps": 1,
    "intensity_noise": 0.05,
    "intensity_noise_floor": 1e-3,
    "intensity_saturation": 4.0,
    "spot_noise_rad": 1e-3,
    "spot_threshold": 0.01,
}
"""The env/sensor=realistic preset."""


def bench_controllers(batch: int, steps: int, repeats: int, compile_kernel: bool, device: str) -> dict:
    """Seconds per step of each controller under each sensor, and the overhead over flat-sea Snell."""
    rows = []
    for sensor, keys in (("ideal", {}), ("realistic", REALISTIC)):
        env = WaterAirEnv(
            num_envs=batch,
            seed=0,
            device=device,
            compile_kernel=compile_kernel,
            observation_extras=("spot", "spot_valid"),
            **keys,
        )
        env.rollout(5, FlatSeaSnell(env), break_when_any_done=False)  # warm-up (compilation)
        timings = {}
        for policy in (FlatSeaSnell, AoATracker, IntensityDither):
            samples = []
            for _ in range(repeats):
                env.set_seed(0)
                start = time.perf_counter()
                env.rollout(steps, policy(env), break_when_any_done=False)
                if env.device.type == "cuda":
                    torch.cuda.synchronize()
                samples.append((time.perf_counter() - start) / steps)
            timings[policy.name] = sorted(samples)[len(samples) // 2]
        reference = timings["flat_snell"]
        for name, seconds in timings.items():
            rows.append({"sensor": sensor, "policy": name, "step_s": seconds, "overhead": seconds / reference - 1})
    return {"benchmark": "controllers", "batch": batch, "steps": steps, "compiled_kernel": compile_kernel, "rows": rows}


def controllers_table(record: dict) -> str:
    lines = [
        f"controllers at B = {record['batch']} ({record['steps']}-step rollouts), "
        f"{'compiled' if record['compiled_kernel'] else 'eager'} surface kernel",
        "",
        "| sensor | policy | ms per step | over flat-Snell |",
        "|---|---|---|---|",
    ]
    for r in record["rows"]:
        lines.append(f"| {r['sensor']} | {r['policy']} | {1e3 * r['step_s']:.2f} | {100 * r['overhead']:+.1f} % |")
    return "\n".join(lines)
