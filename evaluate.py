"""Evaluate trained policies against the baselines and the upper bound on scenarios S1-S3.

``python evaluate.py`` (the shipped policy), ``python evaluate.py run=outputs/train/DATE/TIME``,
``python evaluate.py run=[RUN_A,RUN_B] labels=[ddpg,td3]``, ``python evaluate.py checkpoint=FILE``.
Writes metrics.json, metrics.csv, the figures and report.md into the Hydra run directory
(outputs/evaluate/DATE/TIME). See docs/results.md.
"""

import sys
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig

from waterair.evaluation.report import write_outputs
from waterair.evaluation.runner import evaluate


@hydra.main(version_base="1.3", config_path="conf", config_name="evaluate")
def main(cfg: DictConfig) -> None:
    out = Path(HydraConfig.get().runtime.output_dir)
    try:
        result = evaluate(cfg)
    except ValueError as error:  # config values and checkpoints are all checked before any rollout
        sys.exit(f"error: {error}")
    for path in write_outputs(result, out, cfg, physics=cfg.physics_figures):
        print(path)
    print(f"report: {out / 'report.md'} ({result.seconds:.0f} s)")


if __name__ == "__main__":
    main()
