"""SAC: a stochastic actor learnt through twin Q(s, a) critics with a learned entropy temperature (docs/training.md).

The policy is tanh(u), u ~ N(MLP(s), σ²), the actor's MLP with one learned scale per action component (as
PPO's, starting at ``noise.sigma_init``); its deterministic action tanh(MLP(s)) is the actor a policy file
holds. TorchRL's ``SACLoss`` (its second version: twin critics, no state-value network) with a TD(0)
estimator at ``agent.gamma`` and a ``SoftUpdate`` of the target critics at rate ``agent.tau``. The temperature
α is learned toward the target entropy ``agent.loss.target_entropy`` (``auto``: −1 per action component) at
``agent.alpha_lr``, by the actor's optimiser. Replay and the update schedule are :class:`OffPolicy`'s.
"""

from __future__ import annotations

from collections.abc import Callable
from types import MethodType

import torch
from omegaconf import DictConfig
from tensordict import TensorDict

from waterair.agents.networks import make_gaussian_policy
from waterair.core.validation import check_choice, check_range
from waterair.training.algorithms.base import check_learned_noise
from waterair.training.algorithms.off_policy import OffPolicy

SAC_LOSSES = ("l1", "l2", "smooth_l1")
"""``SACLoss``'s ``loss_function`` values."""


class SAC(OffPolicy):
    """Soft actor-critic: ``agent.loss`` is a ``SACLoss``."""

    loss_target = "torchrl.objectives.SACLoss"
    gaussian_policy = True
    value_loss = "loss_qvalue"
    value_params = "qvalue_network_params"
    logged = ("loss/alpha", "train/alpha", "train/entropy")
    annealed_noise = False

    @classmethod
    def check(cls, cfg: DictConfig) -> None:
        super().check(cfg)
        agent, loss = cfg.agent, cfg.agent.loss
        check_range("agent.alpha_lr", agent.alpha_lr, 0.0, 1.0)
        check_range("agent.loss.alpha_init", loss.alpha_init, 0.0, 1e3, low_open=True)
        check_choice("agent.loss.loss_function", loss.loss_function, SAC_LOSSES)
        if loss.target_entropy != "auto":
            check_range("agent.loss.target_entropy", loss.target_entropy, -100.0, 100.0)
        if agent.policy_weights != "last" or loss.delay_actor:
            raise ValueError(
                "agent=sac saves the actor it learns (agent.policy_weights = last, agent.loss.delay_actor = false): "
                f"got agent.policy_weights = {agent.policy_weights!r}, agent.loss.delay_actor = {loss.delay_actor}"
            )
        check_learned_noise(cfg)

    def make_exploration(self, actor, env, device):
        """The Gaussian policy around ``actor`` (:func:`make_gaussian_policy`); its noise module is the learned
        scale. Noise acts only under ``ExplorationType.RANDOM``: evaluation runs the bare actor."""
        policy = make_gaussian_policy(actor, env.action_spec_unbatched.to(device), self.cfg.noise.sigma_init)
        policy = policy.to(device)
        return policy, policy.module[0].module[1]

    def make_loss(self, actor, exploration, critic, env):
        """:class:`OffPolicy`'s loss of the stochastic ``exploration`` policy (SAC's actor is the distribution); at
        discount 0 its critics' target is the reward alone (:func:`myopic_target`)."""
        loss, target_update = super().make_loss(exploration, exploration, critic, env)
        if self.cfg.agent.gamma == 0:
            loss._compute_target_v2 = MethodType(myopic_target, loss)
        return loss, target_update

    def loss_options(self, env) -> dict:
        """Its ``auto`` target entropy counts the action spec's components."""
        return {"action_spec": env.action_spec_unbatched}

    def make_optimisers(self, loss):
        """Adam for the actor (its learned scale included) with the temperature as a group of its own at
        ``agent.alpha_lr``, and for the twin critics."""
        optim_actor, optim_critic = super().make_optimisers(loss)
        optim_actor.add_param_group({"params": [loss.log_alpha], "lr": self.cfg.agent.alpha_lr})
        return optim_actor, optim_critic

    def loss_terms(self, loss) -> Callable[[TensorDict], tuple[torch.Tensor, ...]]:
        """The actor's and the critics' losses, then the temperature's (stepped with the actor's, by its optimiser),
        α and the policy's entropy (−log-probability of its actions)."""

        def terms(batch: TensorDict) -> tuple[torch.Tensor, ...]:
            losses = loss(batch)
            return (losses["loss_actor"], losses["loss_qvalue"], losses["loss_alpha"], losses["alpha"],
                    losses["entropy"])  # fmt: skip

        return terms


def myopic_target(loss, tensordict: TensorDict) -> torch.Tensor:
    """The critics' TD(0) target at discount 0, ``[B]``: r + 0 · V(s') is r, so the next state's actions and the
    target critics' values, which ``SACLoss`` computes whatever the discount (half the update's forward work),
    are skipped. Bound to a loss in place of its ``_compute_target_v2``; the same numbers (a test)."""
    return tensordict.get(("next", loss.tensor_keys.reward)).squeeze(-1)
