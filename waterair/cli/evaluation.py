"""What ``evaluate.py`` does around :func:`waterair.evaluation.runner.evaluate`: checks, progress, outputs."""

from __future__ import annotations

import logging
from pathlib import Path

from omegaconf import DictConfig, ListConfig

from waterair.cli.console import quiet_dependencies
from waterair.core.threads import AUTO, choose_threads, torch_threads
from waterair.evaluation.report import write_outputs
from waterair.evaluation.runner import evaluate, prepare

log = logging.getLogger("waterair.evaluate")


def check(cfg: DictConfig, overrides: list[str]) -> None:
    """Every config value and checkpoint, checked before anything is written (one-line errors)."""
    prepare(cfg)


def run(cfg: DictConfig, output_dir: str | Path) -> None:
    """Evaluate, log one line per rollout with its time, write the outputs and say where they are.

    torch's threads follow train.py's ``threads: auto`` (:func:`waterair.core.threads.choose_threads`;
    ``OMP_NUM_THREADS`` sets them); ``workers`` runs the batches in processes of their own
    (:mod:`waterair.evaluation.workers`).
    """
    quiet_dependencies()
    out = Path(output_dir)
    with torch_threads(choose_threads(AUTO)[0]):  # the batches' processes say theirs (``workers``)
        result = evaluate(cfg, progress=log.info)
    written = write_outputs(result, out, cfg, physics=cfg.physics_figures)
    figures = sum(path.suffix == ".png" for path in written)
    tables = ", ".join(path.name for path in written if path.suffix == ".csv")
    log.info(f"Wrote {len(written)} files to {out}: metrics.json, {tables}, {figures} figures, report.md")
    skipped = [name for name, scenario in cfg.scenarios.items() if scenario is None]
    if skipped:  # make train's first look (+study=first_run): say how to see the rest
        given = " ".join(f"{key}={_argument(cfg[key])}" for key in ("run", "checkpoint") if cfg.get(key) is not None)
        log.info(f"Not run: {', '.join(skipped)}; the whole study: .venv/bin/python evaluate.py {given}".rstrip())
    log.info(f"Report: {out / 'report.md'} ({result.seconds:.0f} s)")


def _argument(value) -> str:
    """A ``run=``/``checkpoint=`` value as the command line takes it: a path, or ``[A,B]``."""
    return f"[{','.join(str(item) for item in value)}]" if isinstance(value, ListConfig | list) else str(value)
