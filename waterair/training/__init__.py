"""Training of the beam-alignment agent from Hydra configs: the loop, its builders, checkpoints, logs, sweeps."""

from waterair.training.config import validate
from waterair.training.loop import train

__all__ = ["train", "validate"]
