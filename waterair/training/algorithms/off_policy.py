"""What DDPG and TD3 share: a Q(s, a) critic, a noisy deterministic actor, target networks and replay.

The exploration is the actor plus annealed Gaussian or Ornstein-Uhlenbeck noise; every collected
transition goes to the replay buffer, and each update samples from all of it (docs/training.md).
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Callable
from typing import ClassVar

import torch
from hydra.utils import instantiate
from omegaconf import DictConfig
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModule, TensorDictSequential
from torchrl.modules import AdditiveGaussianModule, OrnsteinUhlenbeckProcessModule, ValueOperator
from torchrl.objectives import LossModule, SoftUpdate

from waterair.agents.networks import make_critic
from waterair.core.validation import check_range
from waterair.training.algorithms.base import Algorithm, Counters, Learn, Update, adam, updates_per_batch

TRANSITION_KEYS = (
    "observation",
    "action",
    ("next", "observation"),
    ("next", "reward"),
    ("next", "done"),
    ("next", "terminated"),
)
"""What the replay buffer stores: the losses read nothing else (the env's gains stay out); a recurrent actor's state
and ``is_init`` besides, at both steps (:func:`memory_keys`)."""


def memory_keys(actor: TensorDictModule) -> tuple:
    """What a recurrent ``actor`` reads besides the observation (its state and ``is_init``), at a transition's step and
    its next: replayed, each transition's actions are computed from the state it was collected with, its target's
    from the state the collecting actor passed on (TorchRL's recurrent modules step by step; no gradient flows
    back through earlier steps). None for an MLP."""
    keys = [key for key in actor.in_keys if key != "observation"]
    return (*keys, *(("next", key) for key in keys))


class PolyakUpdate(SoftUpdate):
    """TorchRL's ``SoftUpdate``, θ' ← θ' + τ (θ − θ') for every target parameter, as one foreach ``lerp_`` over the
    loss's tensors listed once: the same arithmetic as its per-parameter loop, without walking the loss's parameter
    tensordicts at every update (0.43 ms of an eager update's 5.3, now 0.05: ``bench training``'s breakdown).
    Loading a state dict into the loss copies into these tensors; the loss must not be moved to another device
    after."""

    def __init__(self, loss: LossModule, *, tau: float) -> None:
        super().__init__(loss, tau=tau)
        self._lists: tuple[list[torch.Tensor], list[torch.Tensor]] = [], []
        for key, source in self._sources.items(include_nested=True, leaves_only=True):
            first, *rest = key if isinstance(key, tuple) else (key,)
            self._lists[0].append(self._targets.get((f"target_{first}", *rest)).data)
            self._lists[1].append(source.data)

    @torch.no_grad()
    def step(self) -> None:
        torch._foreach_lerp_(*self._lists, 1.0 - self.eps)


class OffPolicy(Algorithm):
    """An actor-critic with target networks that learns from a replay of every transition."""

    on_policy = False
    value_loss: ClassVar[str]
    """The loss entry of the critic(s)."""
    annealed_noise: ClassVar[bool] = True
    """Whether its exploration noise is the ``noise`` group's annealed module (else a learned part of the policy)."""

    @property
    @abstractmethod
    def value_params(self) -> str:
        """The loss's attribute that holds the critic(s)' parameters (a class attribute of each algorithm)."""

    @classmethod
    def check(cls, cfg: DictConfig) -> None:
        check_range("agent.tau", cfg.agent.tau, 0.0, 1.0, low_open=True)

    @property
    def policy_delay(self) -> int:
        """Critic updates per actor update."""
        return 1

    def make_critic(self, env, device) -> ValueOperator:
        """Q(s, a) of the ``critic`` group."""
        sizes = env.observation_spec["observation"].shape[-1], env.action_spec.shape[-1]
        return make_critic(*sizes, self.cfg.critic.hidden, self.cfg.critic.activation).to(device)

    def make_exploration(self, actor: TensorDictModule, env, device):
        """The actor, then annealed Gaussian or Ornstein-Uhlenbeck noise of the ``noise`` group.

        The noise module anneals over ``noise.annealing_frames`` when stepped once per collected env
        step. Noise acts only under ``ExplorationType.RANDOM``: evaluation runs the bare actor.
        """
        cfg = self.cfg
        steps = max(1, cfg.noise.annealing_frames // cfg.env.num_envs)
        noise = EXPLORATION_NOISES[cfg.noise.name](cfg.noise, env.action_spec_unbatched.to(device), steps, device)
        return TensorDictSequential(actor, noise), noise

    def make_loss(self, actor, exploration, critic, env):
        """The loss of the deterministic ``actor`` (not the noisy ``exploration``) with a TD(0) estimator at
        ``agent.gamma``, and the soft update of its target networks at rate ``agent.tau`` (:class:`PolyakUpdate`)."""
        loss = instantiate(self.cfg.agent.loss)(actor, critic, **self.loss_options(env))
        loss.make_value_estimator(gamma=self.cfg.agent.gamma)
        return loss, PolyakUpdate(loss, tau=self.cfg.agent.tau)

    def loss_options(self, env) -> dict:
        """Further arguments of ``agent.loss``, from the environment: none."""
        return {}

    def make_optimisers(self, loss):
        return adam(self.cfg, loss.actor_network_params, getattr(loss, self.value_params))

    def loss_terms(self, loss) -> Callable[[TensorDict], tuple[torch.Tensor, ...]]:
        """The (actor, critic) losses of a batch, then one entry for each of :attr:`logged` (those that require
        grad step with the actor): the loss module's own (its other outputs, pred_value and the like, still require
        grad and are left out)."""
        value_key = self.value_loss

        def terms(batch: TensorDict) -> tuple[torch.Tensor, torch.Tensor]:
            losses = loss(batch)
            return losses["loss_actor"], losses[value_key]

        return terms

    def make_update(self, loss, target_update, optim_actor, optim_critic) -> Update:
        """One backward of the critic's and (every ``policy_delay`` updates) the actor's loss (:meth:`loss_terms`),
        with the logged terms that require grad, both optimisers' steps, then the soft target update; returns the
        (actor, critic) losses and the logged terms as a detached tensor."""
        terms, policy_delay = self.loss_terms(loss), self.policy_delay

        def update(batch: TensorDict, count: int) -> torch.Tensor:
            actor_loss, value_loss, *logged = terms(batch)
            update_actor = count % policy_delay == 0
            stepped = sum((term for term in logged if term.requires_grad), actor_loss)
            total = value_loss + (stepped if update_actor else 0.0)
            optim_actor.zero_grad(set_to_none=True)
            optim_critic.zero_grad(set_to_none=True)
            total.backward()
            optim_critic.step()
            if update_actor:
                optim_actor.step()
            target_update.step()
            # Detached, not .item(): no host synchronisation (and no graph break) per update; the loop
            # turns a whole batch of these into numbers once.
            return torch.stack((actor_loss, value_loss, *logged)).detach()

        return torch.compile(update) if self.cfg.compile_update else update

    def make_learn(self, loss, update: Update, buffer, noise) -> Learn:
        """Anneal the noise (:attr:`annealed_noise`), store the batch's transitions, then take
        ``collector.updates_per_frame`` × its frames updates, each on a sample of the whole replay; none before
        ``collector.init_random_frames`` (uniform random actions) or while the replay holds less than one sample.
        The replay does not change between a batch's updates, so their samples (uniform, with replacement) are
        drawn in one call and split: the same distribution as one call each, without 0.3 ms of sampling per eager
        update."""
        per_batch = updates_per_batch(self.cfg)
        steps_per_batch = self.cfg.collector.frames_per_batch // self.cfg.env.num_envs
        random_frames, batch_size = self.cfg.collector.init_random_frames, self.cfg.buffer.batch_size
        annealed, stored = self.annealed_noise, (*TRANSITION_KEYS, *memory_keys(loss.actor_network))

        def learn(batch: TensorDictBase, progress: Counters) -> list[torch.Tensor]:
            if annealed:
                noise.step(steps_per_batch)
            buffer.extend(batch.select(*stored).reshape(-1))
            if progress.frames < random_frames or len(buffer) < batch_size:
                return []
            losses = []
            for sample in buffer.sample(batch_size * per_batch).split(batch_size):
                losses.append(update(sample, progress.updates))
                progress.updates += 1
            return losses

        return learn


def ou_noise(noise: DictConfig, spec, steps: int, device) -> torch.nn.Module:
    """``noise=ou``: Ornstein-Uhlenbeck noise of scale ``sigma_init`` annealed to ``sigma_end`` over ``steps``."""
    return OrnsteinUhlenbeckProcessModule(
        spec=spec,
        eps_init=1.0,
        eps_end=noise.sigma_end / max(noise.sigma_init, 1e-12),
        annealing_num_steps=steps,
        theta=noise.theta,
        sigma=noise.sigma_init,
        device=device,
    )


def gaussian_noise(noise: DictConfig, spec, steps: int, device) -> torch.nn.Module:
    """``noise=gaussian``: additive Gaussian noise annealed from ``sigma_init`` to ``sigma_end`` over ``steps``."""
    return AdditiveGaussianModule(
        spec=spec,
        sigma_init=float(noise.sigma_init),
        sigma_end=float(noise.sigma_end),
        annealing_num_steps=steps,
        device=device,
    )


EXPLORATION_NOISES = {"gaussian": gaussian_noise, "ou": ou_noise}
"""The ``noise`` group's options by name: each builds the exploration module from the group, the action spec,
the annealing steps (collected env steps) and the device."""
