"""Train a beam-alignment agent: ``python train.py [group=option] [key=value ...]``.

Examples: ``python train.py env.wind=8 agent=td3``, ``python train.py resume=outputs/train/DATE/TIME``,
``python train.py -m env.wind=8,12 agent.gamma=0.2,0.9 hydra/launcher=joblib``. See docs/training.md.
"""

import sys
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf

from waterair.training import train, validate


@hydra.main(version_base="1.3", config_path="conf", config_name="config")
def main(cfg: DictConfig) -> float:
    if cfg.resume:
        # The run's own resolved config is authoritative; Hydra's .hydra/ there is rewritten per call.
        saved = Path(cfg.resume) / "config.yaml"
        if not saved.exists():
            sys.exit(f"error: resume = {cfg.resume!r} has no config.yaml; it is not a waterair run directory")
        resume = cfg.resume
        cfg = OmegaConf.load(saved)
        cfg.resume = resume
        run_dir = Path(resume)
    else:
        run_dir = Path(HydraConfig.get().runtime.output_dir)
    try:
        validate(cfg)
    except ValueError as error:
        sys.exit(f"error: {error}")
    metrics = train(cfg, run_dir)
    return metrics["agent/mean_gain"]


if __name__ == "__main__":
    main()
