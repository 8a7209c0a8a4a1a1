"""PPO: on-policy clipped policy optimisation of a Gaussian policy around the actor (docs/training.md).

The exploration is tanh(u), u ~ N(MLP(s), σ²), sharing the actor's MLP, with σ learned per action
component from ``noise.sigma_init``; the critic is V(s). TorchRL's ``ClipPPOLoss`` with generalised
advantage estimation at ``agent.gamma`` and ``agent.lmbda``, no target networks. Each collected batch
is learnt from alone, in whole passes of minibatches, its advantages recomputed before each pass.
"""

from __future__ import annotations

import torch
from hydra.utils import instantiate
from omegaconf import DictConfig
from tensordict import TensorDict, TensorDictBase
from torchrl.data import TensorDictReplayBuffer
from torchrl.modules import ValueOperator, set_recurrent_mode
from torchrl.objectives import ValueEstimators

from waterair.agents.networks import learned_scale, make_gaussian_policy, make_value
from waterair.agents.recurrent import is_recurrent
from waterair.core.validation import check_choice, check_int, check_range
from waterair.training.algorithms.base import (
    Algorithm,
    Counters,
    Learn,
    Update,
    adam,
    check_learned_noise,
    updates_per_batch,
)

CRITIC_LOSSES = ("l1", "l2", "smooth_l1")
"""``ClipPPOLoss``'s ``loss_critic_type`` values."""


class PPO(Algorithm):
    """Proximal policy optimisation: ``agent.loss`` is a ``ClipPPOLoss``."""

    on_policy = True
    loss_target = "torchrl.objectives.ClipPPOLoss"
    gaussian_policy = True
    logged = ("loss/kl",)

    @classmethod
    def check(cls, cfg: DictConfig) -> None:
        """PPO's own keys, and the keys of other groups it reads in its own way."""
        agent = cfg.agent
        check_range("agent.lmbda", agent.lmbda, 0.0, 1.0)
        check_range("agent.max_grad_norm", agent.max_grad_norm, 0.0, 1e6, low_open=True)
        if agent.target_kl is not None:
            check_range("agent.target_kl", agent.target_kl, 0.0, 10.0, low_open=True)
        check_range("agent.loss.clip_epsilon", agent.loss.clip_epsilon, 0.0, 1.0, low_open=True)
        check_range("agent.loss.critic_coeff", agent.loss.critic_coeff, 0.0, 1e6, low_open=True)
        check_choice("agent.loss.loss_critic_type", agent.loss.loss_critic_type, CRITIC_LOSSES)
        for flag in ("entropy_bonus", "normalize_advantage"):
            if not isinstance(agent.loss[flag], bool):
                raise ValueError(f"agent.loss.{flag} = {agent.loss[flag]!r} must be true or false")
        if agent.policy_weights != "last":
            raise ValueError(
                "agent.policy_weights = 'average' is not allowed with agent=ppo (no target actor); use last"
            )
        check_learned_noise(cfg)
        check_int("buffer.batch_size", cfg.buffer.batch_size, 1, cfg.collector.frames_per_batch)
        if cfg.checkpoint.keep_buffer:
            raise ValueError(
                "checkpoint.keep_buffer = true is not allowed with agent=ppo, which replays nothing: a resumed run "
                "collects its next batch afresh"
            )

    def make_critic(self, env, device) -> ValueOperator:
        """V(s) of the ``critic`` group."""
        size = env.observation_spec["observation"].shape[-1]
        return make_value(size, self.cfg.critic.hidden, self.cfg.critic.activation).to(device)

    def make_exploration(self, actor, env, device):
        """The Gaussian policy around ``actor``; its noise module is the learned scale, starting at
        ``noise.sigma_init``. Noise acts only under ``ExplorationType.RANDOM``: evaluation runs the bare actor."""
        spec = env.action_spec_unbatched.to(device)
        policy = make_gaussian_policy(actor, spec, self.cfg.noise.sigma_init).to(device)
        return policy, learned_scale(policy)

    def make_loss(self, actor, exploration, critic, env):
        """The loss of the stochastic ``exploration`` policy; no target update."""
        loss = instantiate(self.cfg.agent.loss)(exploration, critic)
        loss.make_value_estimator(ValueEstimators.GAE, gamma=self.cfg.agent.gamma, lmbda=self.cfg.agent.lmbda)
        return loss, None

    def make_optimisers(self, loss):
        """The actor's optimiser steps its learned noise scale too."""
        return adam(self.cfg, loss.actor_network_params, loss.critic_network_params)

    def make_update(self, loss, target_update, optim_actor, optim_critic) -> Update:
        """One backward of the clipped objective plus the critic loss, the gradient norm clipped at
        ``agent.max_grad_norm``; returns (actor, critic, approximate KL from the collecting policy), detached."""
        params = [p for group in (optim_actor, optim_critic) for g in group.param_groups for p in g["params"]]
        max_grad_norm = self.cfg.agent.max_grad_norm

        def update(batch: TensorDict, count: int) -> torch.Tensor:
            with set_recurrent_mode(True):  # a recurrent actor over a minibatch's sequences; an MLP alike
                losses = loss(batch)
            optim_actor.zero_grad(set_to_none=True)
            optim_critic.zero_grad(set_to_none=True)
            (losses["loss_objective"] + losses["loss_critic"]).backward()
            torch.nn.utils.clip_grad_norm_(params, max_grad_norm)
            optim_actor.step()
            optim_critic.step()
            kl = losses["kl_approx"].mean()  # how far this minibatch's policy moved from the collecting one
            return torch.stack((losses["loss_objective"], losses["loss_critic"], kl)).detach()

        return torch.compile(update) if self.cfg.compile_update else update

    def make_learn(self, loss, update: Update, buffer: TensorDictReplayBuffer, noise) -> Learn:
        """Passes over the batch alone, ``frames_per_batch // batch_size`` minibatches each, as many as
        ``collector.updates_per_frame`` × its frames updates rounded to whole passes; its advantages recomputed
        before each pass, and no further pass once a pass has moved the policy by more than ``agent.target_kl``
        (mean approximate KL from the policy that collected the batch; null: every pass). None on the frames
        of ``collector.init_random_frames``, whose random actions have no log-probability.

        A recurrent actor learns from whole sequences: each minibatch is ``buffer.batch_size`` // the batch's steps
        links (at least one), every step of each, run from the state each link's first step was collected with
        (:meth:`minibatches`)."""
        cfg = self.cfg
        keys = loss.tensor_keys
        stored = ("observation", "action", keys.sample_log_prob, keys.advantage, keys.value_target)
        batch_size = cfg.buffer.batch_size
        per_pass = cfg.collector.frames_per_batch // batch_size
        sequences = is_recurrent(loss.actor_network)
        if sequences:
            steps = cfg.collector.frames_per_batch // cfg.env.num_envs
            per_pass = cfg.env.num_envs // max(1, batch_size // steps)
        passes = max(1, round(updates_per_batch(cfg) / per_pass))
        random_frames, target_kl = cfg.collector.init_random_frames, cfg.agent.target_kl
        memory = [key for key in loss.actor_network.in_keys if key != "observation"]

        def learn(batch: TensorDictBase, progress: Counters) -> list[torch.Tensor]:
            if progress.frames - batch.numel() < random_frames:
                return []
            losses: list[torch.Tensor] = []
            for index in range(passes):
                if index and target_kl is not None:  # one host synchronisation per pass
                    if torch.stack(losses[-per_pass:])[:, 2].mean().item() > target_kl:
                        break
                with torch.no_grad():
                    loss.value_estimator(batch)
                if sequences:
                    minibatches = self.minibatches(batch.select(*stored, *memory), per_pass)
                else:
                    buffer.extend(batch.select(*stored).reshape(-1))  # the storage holds one batch
                    minibatches = buffer.sample().split(batch_size)  # a pass: one permutation's minibatches
                for minibatch in minibatches:
                    losses.append(update(minibatch, progress.updates))
                    progress.updates += 1
            return losses

        return learn

    @staticmethod
    def minibatches(batch: TensorDictBase, count: int) -> list[TensorDictBase]:
        """A pass over a recurrent actor's batch ``[links, steps]``: ``count`` minibatches of whole links, in an order
        drawn from torch's generator; the links a pass cannot fill a minibatch with wait for the next pass."""
        links = batch.shape[0]
        size = links // count
        order = torch.randperm(links, device=batch.device)[: size * count]
        return list(batch[order].split(size))
