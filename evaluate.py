"""Evaluate trained policies against the baselines and the upper bound on scenarios S1-S3.

``python evaluate.py`` (the shipped policies), ``python evaluate.py run=outputs/train/DATE/TIME``,
``python evaluate.py run=[RUN_A,RUN_B] labels=[ddpg,td3]``, ``python evaluate.py checkpoint=FILE``.
Writes metrics.json, metrics.csv, the figures and report.md into the Hydra run directory
(outputs/evaluate/DATE/TIME). See docs/evaluation.md. The whole command line, checkpoints included,
is checked before Hydra creates that directory.
"""

import gc
import sys

if __name__ == "__main__":
    gc.disable()  # until the imports are done (waterair.core.process.set_up_process)

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig

from waterair.cli import evaluation
from waterair.cli.preflight import preflight
from waterair.core.process import set_up_process


@hydra.main(version_base="1.3", config_path="conf", config_name="evaluate")
def main(cfg: DictConfig) -> None:
    evaluation.run(cfg, HydraConfig.get().runtime.output_dir)


if __name__ == "__main__":
    set_up_process()
    preflight("evaluate", sys.argv[1:], evaluation.check)
    main()
