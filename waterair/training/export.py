"""Export a run's trained policy as a small policy file: ``python -m waterair.training.export RUN_DIR OUT``.

Writes ``OUT.pt`` (the policy entries of the run's checkpoint: format tag, actor weights,
observation size, frames), ``OUT.yaml`` (the run's config) and ``OUT_metrics.json`` (its final
metrics, when present), like the policies shipped in ``waterair/assets``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from waterair.agents.checkpoint import POLICY_FORMAT, CheckpointError, read_policy, save_policy
from waterair.core.files import atomic_write_text
from waterair.training.checkpoint import CHECKPOINT


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
    metrics = run_dir / "final_metrics.json"
    if metrics.exists():
        atomic_write_text(out.with_name(out.stem + "_metrics.json"), metrics.read_text())
    return target


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m waterair.training.export", description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path, help="a training run directory")
    parser.add_argument("out", type=Path, help="output path without suffix, e.g. waterair/assets/default_policy")
    args = parser.parse_args(argv)
    try:
        print(export_policy(args.run_dir, args.out))
    except (CheckpointError, FileNotFoundError) as error:
        parser.exit(1, f"error: {error}\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
