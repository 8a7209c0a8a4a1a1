"""The learning algorithms, one per module, and the one registry that maps ``agent.name`` to each.

Each is an :class:`~waterair.training.algorithms.base.Algorithm`: its config checks, critic,
exploration, loss, optimisers, gradient step and learning step, with its traits (``on_policy``,
``loss_target``) as class attributes that the loop reads instead of the agent's name. The option
files ``conf/agent/<name>.yaml`` configure them (docs/training.md).
"""

from waterair.training.algorithms.base import Algorithm
from waterair.training.algorithms.ddpg import DDPG
from waterair.training.algorithms.ppo import PPO
from waterair.training.algorithms.sac import SAC
from waterair.training.algorithms.td3 import TD3

ALGORITHMS: dict[str, type[Algorithm]] = {"ppo": PPO, "ddpg": DDPG, "td3": TD3, "sac": SAC}
"""``agent.name`` → the algorithm it trains."""

__all__ = ["ALGORITHMS", "Algorithm", "create"]


def create(cfg) -> Algorithm:
    """The algorithm ``cfg.agent.name`` names, built on the composed (and validated) config ``cfg``."""
    return ALGORITHMS[cfg.agent.name](cfg)
