"""Controller benchmark: ``python -m waterair.bench controllers`` (see :mod:`waterair.bench`).

The cost the classical controllers and the sensor model add to an environment step: rollouts of
``steps`` steps at batch size B under the flat-sea Snell baseline (the reference), the
``aoa_tracker`` and the ``intensity_dither``, with the ideal and the realistic sensor; and what a residual base
adds inside the step: ``kalman_tracker``'s tracks against ``beacon_tracker``, both ends sensed (their rows
``sensor`` "beacon").
"""

from __future__ import annotations

import time

import torch

from waterair.envs.baselines import FlatSeaSnell
from waterair.envs.config import BASE_NEEDS
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
    rows.extend(_bases(batch, steps, repeats, compile_kernel, device))
    return {"benchmark": "controllers", "batch": batch, "steps": steps, "compiled_kernel": compile_kernel, "rows": rows}


def _bases(batch: int, steps: int, repeats: int, compile_kernel: bool, device: str) -> list[dict]:
    """Seconds per step of residual actions of 0 on ``beacon_tracker`` and on ``kalman_tracker``, timed in turn,
    the realistic sensor, both ends sensed; the Kalman base's overhead over the beacon tracker's."""
    envs = {
        base: WaterAirEnv(num_envs=batch, seed=0, device=device, compile_kernel=compile_kernel, action_mode="residual",
                          residual_base=base, observation_extras=BASE_NEEDS[base], beacon_noise_rad=1e-3, **REALISTIC)
        for base in ("beacon_tracker", "kalman_tracker")
    }  # fmt: skip
    samples: dict[str, list[float]] = {base: [] for base in envs}
    for env in envs.values():
        env.rollout(5, break_when_any_done=False)  # warm-up (compilation)
    for _ in range(repeats):
        for base, env in envs.items():
            env.set_seed(0)
            zero = torch.zeros(batch, 4, device=env.device)
            td = env.reset()
            start = time.perf_counter()
            for _ in range(steps):
                td = env.step(td.set("action", zero))["next"]
            if env.device.type == "cuda":
                torch.cuda.synchronize()
            samples[base].append((time.perf_counter() - start) / steps)
    timings = {base: sorted(each)[len(each) // 2] for base, each in samples.items()}
    reference = timings["beacon_tracker"]
    return [
        {"sensor": "beacon", "policy": f"residual on {base}", "step_s": seconds, "overhead": seconds / reference - 1}
        for base, seconds in timings.items()
    ]


def controllers_table(record: dict) -> str:
    lines = [
        f"controllers at B = {record['batch']} ({record['steps']}-step rollouts), "
        f"{'compiled' if record['compiled_kernel'] else 'eager'} surface kernel",
        "",
        "| sensor | policy | ms per step | over flat-Snell (beacon: over residual on beacon_tracker) |",
        "|---|---|---|---|",
    ]
    for r in record["rows"]:
        lines.append(f"| {r['sensor']} | {r['policy']} | {1e3 * r['step_s']:.2f} | {100 * r['overhead']:+.1f} % |")
    return "\n".join(lines)
