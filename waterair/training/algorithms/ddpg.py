"""DDPG: a deterministic actor learnt through a Q(s, a) critic, with target networks (docs/training.md).

TorchRL's ``DDPGLoss`` with a TD(0) estimator at ``agent.gamma`` and a ``SoftUpdate`` of the target
networks at rate ``agent.tau``; loss, exploration, update and replay are :class:`OffPolicy`'s.
"""

from __future__ import annotations

from omegaconf import DictConfig

from waterair.training.algorithms.off_policy import OffPolicy


class DDPG(OffPolicy):
    """Deep deterministic policy gradient: ``agent.loss`` is a ``DDPGLoss``."""

    loss_target = "torchrl.objectives.DDPGLoss"
    value_loss = "loss_value"
    value_params = "value_network_params"

    @classmethod
    def check(cls, cfg: DictConfig) -> None:
        super().check(cfg)
        agent = cfg.agent
        if agent.policy_weights == "average" and not agent.loss.delay_actor:
            raise ValueError(
                "agent.policy_weights = 'average' needs the target actor it averages into; set "
                "agent.loss.delay_actor=true or agent.policy_weights=last"
            )
