"""DDPG: a deterministic actor learnt through a Q(s, a) critic, with target networks (docs/training.md).

TorchRL's ``DDPGLoss`` with a TD(0) estimator at ``agent.gamma`` and a ``SoftUpdate`` of the target
networks at rate ``agent.tau``; loss, exploration, update and replay are :class:`OffPolicy`'s.
"""

from __future__ import annotations

from collections.abc import Callable

import torch
from omegaconf import DictConfig
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torchrl.objectives.utils import distance_loss
from torchrl.objectives.value import TD0Estimator

from waterair.training.algorithms.off_policy import OffPolicy


class RewardTarget(TD0Estimator):
    """TD(0) at discount 0: the target r + 0 · (1 − terminated) · Q'(s', μ'(s')) is the reward, so the target
    networks' value of the next state is not computed (two forward passes of every update: the eager loss 1.4 ms
    instead of 2.1); the same target, the same gradients."""

    def value_estimate(self, tensordict, target_params=None, next_value=None, **kwargs):
        if next_value is None:
            next_value = torch.zeros_like(tensordict.get(("next", self.tensor_keys.reward)))
        return super().value_estimate(tensordict, target_params, next_value, **kwargs)


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

    def make_loss(self, actor, exploration, critic, env):
        """:class:`OffPolicy`'s, with :class:`RewardTarget` for TorchRL's TD(0) estimator at discount 0 (wired
        to the loss's keys as the loss wires its own)."""
        loss, target_update = super().make_loss(actor, exploration, critic, env)
        if self.cfg.agent.gamma == 0:
            keys = loss.tensor_keys
            estimator = RewardTarget.for_loss(loss, gamma=0.0, value_network=loss.actor_critic)
            estimator.set_keys(
                value=keys.state_action_value, reward=keys.reward, done=keys.done, terminated=keys.terminated
            )
            # as TorchRL's own make_value_estimator stores it: its ``value_estimator`` setter never runs for a
            # module, which nn.Module's __setattr__ registers as a submodule of that name instead
            loss._value_estimator = estimator
        return loss, target_update

    def loss_terms(self, loss) -> Callable[[TensorDict], tuple[torch.Tensor, torch.Tensor]]:
        """:class:`OffPolicy`'s, or, for an eager update at discount 0, :func:`direct_losses`: the same losses
        without TorchRL's per-call machinery."""
        direct = None if self.cfg.compile_update else direct_losses(loss)
        return direct or super().loss_terms(loss)


def direct_losses(loss) -> Callable[[TensorDict], tuple[torch.Tensor, torch.Tensor]] | None:
    """``DDPGLoss``'s actor and value losses computed on its networks' own modules and parameters, or None where
    that would not be the same loss: unless the actor and the critic are plain ``TensorDictModule`` s (one output
    each), the target is the reward (:class:`RewardTarget`) and the losses are means.

    TorchRL's loss swaps each network's parameters into it for every call (its functional copies are the same
    tensors), copies and detaches the batch, and writes every output through a TensorDict: eager, about a third of
    an update's time at batch 64 (docs/benchmarks.md, "Training", has the update against bare PyTorch). Here the
    critic's value loss is ``distance_loss(Q(s, a), r)`` and the actor's −Q(s, μ(s)) with the critic's parameters
    out of the graph, as TorchRL's detached copies keep them; the priority TorchRL writes back into the batch for a
    prioritised replay is left out (the replay is uniform). Compiled updates keep TorchRL's loss, which compiles
    to the same."""
    actor, critic = loss.actor_network, loss.value_network
    plain = all(type(m).forward is TensorDictModule.forward and len(m.out_keys) == 1 for m in (actor, critic))
    if not (plain and isinstance(loss.value_estimator, RewardTarget) and loss.reduction == "mean"):
        return None
    action_key, reward_key = actor.out_keys[0], ("next", loss.tensor_keys.reward)
    critic_params = list(loss.value_network_params.values(True, True))  # the critic module's own tensors

    def terms(batch: TensorDict) -> tuple[torch.Tensor, torch.Tensor]:
        value = critic.module(*(batch.get(key) for key in critic.in_keys))
        value_loss = distance_loss(value, batch.get(reward_key), loss_function=loss.loss_function).mean()
        action = actor.module(*(batch.get(key) for key in actor.in_keys))
        for parameter in critic_params:
            parameter.requires_grad_(False)
        try:
            chosen = critic.module(*(action if key == action_key else batch.get(key) for key in critic.in_keys))
        finally:
            for parameter in critic_params:
                parameter.requires_grad_(True)
        return -chosen.mean(), value_loss

    return terms
