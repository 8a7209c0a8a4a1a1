"""DDPG: a deterministic actor learnt through a Q(s, a) critic, with target networks (docs/training.md).

TorchRL's ``DDPGLoss`` with a TD(0) estimator at ``agent.gamma`` and a ``SoftUpdate`` of the target
networks at rate ``agent.tau``; exploration, update and replay are :class:`OffPolicy`'s.
"""

from __future__ import annotations

from hydra.utils import instantiate
from omegaconf import DictConfig
from torchrl.objectives import SoftUpdate

from waterair.training.algorithms.base import adam
from waterair.training.algorithms.off_policy import OffPolicy


class DDPG(OffPolicy):
    """Deep deterministic policy gradient: ``agent.loss`` is a ``DDPGLoss``."""

    loss_target = "torchrl.objectives.DDPGLoss"
    value_loss = "loss_value"

    @classmethod
    def check(cls, cfg: DictConfig) -> None:
        super().check(cfg)
        agent = cfg.agent
        if agent.policy_weights == "average" and not agent.loss.delay_actor:
            raise ValueError(
                "agent.policy_weights = 'average' needs the target actor it averages into; set "
                "agent.loss.delay_actor=true or agent.policy_weights=last"
            )

    def make_loss(self, actor, exploration, critic, env):
        """The loss of the deterministic ``actor`` (not the noisy ``exploration``) and its target update."""
        loss = instantiate(self.cfg.agent.loss)(actor, critic)
        loss.make_value_estimator(gamma=self.cfg.agent.gamma)
        return loss, SoftUpdate(loss, tau=self.cfg.agent.tau)

    def make_optimisers(self, loss):
        return adam(self.cfg, loss.actor_network_params, loss.value_network_params)
