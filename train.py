"""Train a beam-alignment agent: ``python train.py [group=option] [key=value ...]``.

Examples: ``python train.py env.wind=12 reward.a=5``, ``python train.py resume=outputs/train/DATE/TIME``,
``python train.py -m agent.gamma=0,0.9 reward.a=5,10 env.wind=4,12,20 hydra/launcher=joblib``. See docs/training.md.
The whole command line is checked before Hydra creates the run directory.
"""

import gc
import sys

if __name__ == "__main__":
    gc.disable()  # until the imports are done (waterair.core.process.set_up_process)

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig

from waterair.cli import training
from waterair.cli.preflight import preflight
from waterair.core.process import set_up_process


@hydra.main(version_base="1.3", config_path="conf", config_name="config")
def main(cfg: DictConfig) -> float:
    hydra_config = HydraConfig.get()
    in_sweep = hydra_config.mode == RunMode.MULTIRUN
    events = training.sweep_events_dir(hydra_config) if in_sweep else None  # each job's run named by its overrides
    return training.run(cfg, list(hydra_config.overrides.task), hydra_config.runtime.output_dir, in_sweep, events)


if __name__ == "__main__":
    set_up_process()
    preflight("config", sys.argv[1:], training.check)
    main()
