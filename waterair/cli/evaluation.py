"""What ``evaluate.py`` does around :func:`waterair.evaluation.runner.evaluate`: checks, progress, outputs."""

from __future__ import annotations

import logging
from pathlib import Path

from omegaconf import DictConfig

from waterair.cli.console import quiet_dependencies
from waterair.evaluation.report import write_outputs
from waterair.evaluation.runner import evaluate, prepare

log = logging.getLogger("waterair.evaluate")


def check(cfg: DictConfig, overrides: list[str]) -> None:
    """Every config value and checkpoint, checked before anything is written (one-line errors)."""
    prepare(cfg)


def run(cfg: DictConfig, output_dir: str | Path) -> None:
    """Evaluate, log one line per rollout with its time, write the outputs and say where they are."""
    quiet_dependencies()
    out = Path(output_dir)
    result = evaluate(cfg, progress=log.info)
    written = write_outputs(result, out, cfg, physics=cfg.physics_figures)
    log.info(f"Wrote {len(written)} files to {out}: metrics.json, metrics.csv, {len(written) - 3} figures, report.md")
    log.info(f"Report: {out / 'report.md'} ({result.seconds:.0f} s)")
