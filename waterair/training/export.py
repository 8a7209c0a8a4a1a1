"""Export a run's trained policy as a small policy file: ``python -m waterair.training.export RUN_DIR OUT``.

Writes ``OUT.pt`` (the policy entries of the run's checkpoint: format tag, actor weights,
observation size, frames), ``OUT.yaml`` (the run's config) and ``OUT_metrics.json`` (its final
metrics, when present, and under ``check`` a short evaluation that anyone can repeat in seconds,
:func:`short_check`), like the policies shipped in ``waterair/assets``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from waterair.agents.checkpoint import POLICY_FORMAT, CheckpointError, read_policy, save_policy
from waterair.core.files import atomic_write_json, atomic_write_text
from waterair.evaluation.policies import load_policy
from waterair.evaluation.runner import compare_policies
from waterair.evaluation.scenarios import Scenario
from waterair.training.builders import env_config
from waterair.training.checkpoint import CHECKPOINT

CHECK = Scenario("check", "short check", None, ((12.0, 0.1, 0.0),), realisations=4, steps=60, seed=2468)
"""The short evaluation stored with an exported policy: the S1 point, 4 seas × 3 s, eager step."""


def export_policy(run_dir: str | Path, out: str | Path) -> Path:
    """Write ``OUT.pt``, ``OUT.yaml`` and ``OUT_metrics.json`` from ``run_dir``; return the ``.pt`` path."""
    run_dir, out = Path(run_dir), Path(out)
    policy = read_policy(run_dir / CHECKPOINT)
    out.parent.mkdir(parents=True, exist_ok=True)
    state = {
        "format": POLICY_FORMAT,
        "actor": policy.actor_state,
        "observation_size": policy.observation_size,
        "frames": policy.frames,
    }
    target = save_policy(out.with_suffix(".pt"), state)
    atomic_write_text(out.with_suffix(".yaml"), (run_dir / "config.yaml").read_text())
    metrics_path = run_dir / "final_metrics.json"
    metrics = json.loads(metrics_path.read_text()) if metrics_path.exists() else {}
    metrics["check"] = short_check(target)
    atomic_write_json(out.with_name(out.stem + "_metrics.json"), metrics)
    return target


def short_check(path: str | Path) -> dict[str, float]:
    """The greedy policy at ``path`` on :data:`CHECK` (its own training interface, eager step):
    ``ratio_to_ub`` and ``mean_gain``. Repeating it reproduces the numbers stored at export."""
    policy = load_policy(path)
    cfg = policy.config
    config = env_config(cfg, compile_kernel=False, device="cpu")
    actor = policy.actor(cfg.actor, config.observation_size)
    results = compare_policies(config, {"agent": actor}, CHECK)["agent"]
    return {key: results[key] for key in ("ratio_to_ub", "mean_gain")}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m waterair.training.export", description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path, help="a training run directory")
    parser.add_argument("out", type=Path, help="output path without suffix, e.g. waterair/assets/default")
    args = parser.parse_args(argv)
    try:
        print(export_policy(args.run_dir, args.out))
    except (CheckpointError, FileNotFoundError) as error:
        parser.exit(1, f"error: {error}\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
