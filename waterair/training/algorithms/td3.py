"""TD3: DDPG with twin critics, target policy smoothing and delayed actor updates (docs/training.md).

TorchRL's ``TD3Loss`` (its target actions smoothed by ``agent.loss.policy_noise`` clipped at
``agent.loss.noise_clip``) with a TD(0) estimator at ``agent.gamma`` and a ``SoftUpdate`` at rate
``agent.tau``; the actor steps every ``agent.policy_delay`` updates. Exploration, update and replay
are :class:`OffPolicy`'s.
"""

from __future__ import annotations

from omegaconf import DictConfig

from waterair.core.validation import check_int, check_range
from waterair.training.algorithms.off_policy import OffPolicy


class TD3(OffPolicy):
    """Twin delayed DDPG: ``agent.loss`` is a ``TD3Loss``."""

    loss_target = "torchrl.objectives.TD3Loss"
    value_loss = "loss_qvalue"
    value_params = "qvalue_network_params"

    @classmethod
    def check(cls, cfg: DictConfig) -> None:
        super().check(cfg)
        agent = cfg.agent
        check_int("agent.policy_delay", agent.policy_delay, 1, 1000)
        check_range("agent.loss.policy_noise", agent.loss.policy_noise, 0.0, 10.0)
        check_range("agent.loss.noise_clip", agent.loss.noise_clip, 0.0, 10.0)

    @property
    def policy_delay(self) -> int:
        return self.cfg.agent.policy_delay

    def loss_options(self, env) -> dict:
        """Its smoothed target actions stay in the action spec."""
        return {"action_spec": env.action_spec_unbatched}
