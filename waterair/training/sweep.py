"""The Hydra callback that summarises a sweep: ``summary.csv`` at its root, one row per job."""

from __future__ import annotations

import json
from pathlib import Path

from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf

from waterair.core.files import atomic_write_csv


class SweepSummary(Callback):
    """At the end of a multirun, write ``summary.csv`` (job, overrides, final metrics) at the sweep root."""

    def on_multirun_end(self, config: DictConfig, **kwargs) -> None:
        root = Path(config.hydra.sweep.dir)
        rows = []
        for metrics_path in sorted(root.glob("*/final_metrics.json"), key=lambda p: int(p.parent.name)):
            overrides_path = metrics_path.parent / ".hydra" / "overrides.yaml"
            overrides = OmegaConf.load(overrides_path) if overrides_path.exists() else []
            rows.append(
                {
                    "job": metrics_path.parent.name,
                    "overrides": " ".join(overrides),
                    **json.loads(metrics_path.read_text()),
                }
            )
        if rows:
            atomic_write_csv(root / "summary.csv", list(dict.fromkeys(key for row in rows for key in row)), rows)
