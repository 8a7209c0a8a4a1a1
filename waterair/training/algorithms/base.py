"""What every learning algorithm builds for the training loop (:mod:`waterair.training.loop`).

The loop owns the environment, the actor, the replay buffer, the collector, the logs and the
checkpoints; an :class:`Algorithm` owns what differs between algorithms: its config checks, its
critic, its exploration, its loss and target update, its optimisers, its gradient step and what it
learns from each collected batch (docs/training.md).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import ClassVar, Protocol

import torch
from omegaconf import DictConfig
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModule, TensorDictModuleBase
from torchrl.data import TensorDictReplayBuffer
from torchrl.modules import ValueOperator
from torchrl.objectives import LossModule, SoftUpdate

from waterair.core.validation import check_range

Update = Callable[[TensorDict, int], torch.Tensor]
"""One gradient step on a sampled batch, given the updates so far: the detached losses."""


class Counters(Protocol):
    """The loop's counters a learning step reads and advances (:class:`waterair.training.checkpoint.Progress`)."""

    frames: int
    """Frames collected, the batch being learnt from included."""
    updates: int
    """Gradient updates taken so far."""


Learn = Callable[[TensorDictBase, Counters], list[torch.Tensor]]
"""What the loop does with each collected batch, given its counters: the losses of the updates it took."""


class Algorithm(ABC):
    """A learning algorithm: the pieces it builds from the composed config ``cfg``, in the loop's order.

    The loop calls ``make_critic``, ``make_exploration``, ``make_loss`` and ``make_optimisers`` in this
    order (their networks draw from torch's generator in it), then ``make_update`` and ``make_learn``.
    """

    on_policy: ClassVar[bool]
    """Whether it learns only from the batch its own policy just collected (the buffer then holds that batch)."""
    loss_target: ClassVar[str]
    """The TorchRL loss class it instantiates, which ``agent.loss._target_`` must name."""
    gaussian_policy: ClassVar[bool] = False
    """Whether its loss builds a distribution around the actor (PPO's and SAC's Gaussian policy): a per-end actor's
    update then stays eager (:mod:`waterair.training.compiling`)."""
    logged: ClassVar[tuple[str, ...]] = ()
    """The tags of what each update returns after its (actor, critic) losses, logged as the batch's means."""

    def __init__(self, cfg: DictConfig) -> None:
        self.cfg = cfg

    @classmethod
    @abstractmethod
    def check(cls, cfg: DictConfig) -> None:
        """Check its own ``agent`` keys and the keys of other groups it reads in its own way (the keys every
        agent has are checked by :func:`waterair.training.config.validate`); one-line ``ValueError``s."""

    @abstractmethod
    def make_critic(self, env, device) -> ValueOperator:
        """The ``critic`` group's network for this algorithm, on ``device``."""

    @abstractmethod
    def make_exploration(self, actor: TensorDictModule, env, device) -> tuple[TensorDictModuleBase, torch.nn.Module]:
        """The policy that collects, and the module that holds its noise (logged, and saved in checkpoints)."""

    @abstractmethod
    def make_loss(self, actor, exploration, critic, env) -> tuple[LossModule, SoftUpdate | None]:
        """``agent.loss`` with its value estimator, and its target update (None without target networks)."""

    @abstractmethod
    def make_optimisers(self, loss: LossModule) -> tuple[torch.optim.Optimizer, torch.optim.Optimizer]:
        """The actor's and the critic's optimisers, over the loss's own copies of their parameters."""

    @abstractmethod
    def make_update(self, loss, target_update, optim_actor, optim_critic) -> Update:
        """One gradient step on a sampled batch (compiled with ``compile_update``): the detached losses,
        (actor, critic), then an entry for each of :attr:`logged`."""

    @abstractmethod
    def make_learn(self, loss, update: Update, buffer: TensorDictReplayBuffer, noise: torch.nn.Module) -> Learn:
        """What the loop does with each collected batch: ``learn(batch, progress)`` → the update losses."""


def check_learned_noise(cfg: DictConfig) -> None:
    """For an algorithm that learns its Gaussian policy's scale from ``noise.sigma_init``: the ``noise`` group must be
    a constant Gaussian (nothing anneals a learned scale)."""
    if cfg.noise.name != "gaussian" or cfg.noise.sigma_end != cfg.noise.sigma_init:
        raise ValueError(
            f"agent={cfg.agent.name} learns its action noise, starting at noise.sigma_init; noise={cfg.noise.name} "
            f"with sigma_end = {cfg.noise.sigma_end} is not allowed (use noise=gaussian with sigma_end = sigma_init)"
        )
    check_range("noise.sigma_init", cfg.noise.sigma_init, 0.0, 10.0, low_open=True)


def updates_per_batch(cfg: DictConfig) -> int:
    """``collector.updates_per_frame`` × ``collector.frames_per_batch`` gradient updates, at least one."""
    return max(1, round(cfg.collector.frames_per_batch * cfg.collector.updates_per_frame))


def adam(cfg: DictConfig, actor_params: TensorDictBase, critic_params: TensorDictBase):
    """Adam for the actor at ``actor.lr`` and for the critic(s) at ``critic.lr``, over the loss's parameters.

    Fused (one kernel over all of an optimiser's parameters) when the update runs eagerly (``compile_update``
    false): an eager DDPG update's backward and steps 1.25 ms instead of 1.75; a compiled update is faster with
    the plain one, whose step inductor fuses into its graph (2.6 ms against 3.0: dynamo leaves the fused kernel
    out)."""
    fused = not cfg.compile_update  # as make_update reads it
    actor = torch.optim.Adam(list(actor_params.flatten_keys().values()), lr=cfg.actor.lr, fused=fused)
    critic = torch.optim.Adam(list(critic_params.flatten_keys().values()), lr=cfg.critic.lr, fused=fused)
    return actor, critic
