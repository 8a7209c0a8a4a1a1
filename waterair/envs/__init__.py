"""The reinforcement-learning environment over the physics layer.

:class:`~waterair.envs.env.WaterAirEnv` (a batched TorchRL ``EnvBase``) with its validated
:class:`~waterair.envs.config.EnvConfig`, the rewards, the baseline policies and, in
:mod:`waterair.envs.gym` (extra ``gym``), Gymnasium views. The RL interface is described in
docs/environment.md.
"""

from waterair.envs.baselines import BASELINES
from waterair.envs.config import EnvConfig
from waterair.envs.env import WaterAirEnv
from waterair.envs.rewards import Reward

__all__ = ["BASELINES", "EnvConfig", "Reward", "WaterAirEnv"]
