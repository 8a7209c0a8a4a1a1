"""Builders of the training pieces, one per config group: ``make_X(cfg, ...)`` returns X.

The environment (``env``, ``reward``), networks (``actor``, ``critic``), loss and target update
(``agent``), exploration (``noise``), optimisers, replay buffer (``buffer``), collector
(``collector``) and the update step.
"""

from __future__ import annotations

from pathlib import Path

import torch
from hydra.utils import instantiate
from omegaconf import DictConfig, OmegaConf
from tensordict import TensorDict
from tensordict.nn import TensorDictModule, TensorDictModuleBase, TensorDictSequential
from torchrl.collectors import Collector
from torchrl.data import LazyMemmapStorage, LazyTensorStorage, TensorDictReplayBuffer
from torchrl.envs import Compose, InitTracker, RewardSum, TransformedEnv
from torchrl.modules import AdditiveGaussianModule, OrnsteinUhlenbeckProcessModule, ValueOperator
from torchrl.objectives import SoftUpdate

from waterair.agents.networks import make_actor as build_actor
from waterair.agents.networks import make_critic as build_critic
from waterair.envs.config import EnvConfig
from waterair.envs.env import WaterAirEnv
from waterair.envs.rewards import Reward

TRANSITION_KEYS = (
    "observation",
    "action",
    ("next", "observation"),
    ("next", "reward"),
    ("next", "done"),
    ("next", "terminated"),
)
"""What the replay buffer stores: the losses read nothing else (the env's gains stay out)."""


def env_config(cfg: DictConfig, **overrides) -> EnvConfig:
    """The validated environment config of the ``env`` group, with ``overrides`` applied."""
    return EnvConfig.from_mapping({**OmegaConf.to_container(cfg.env, resolve=True), **overrides})


def make_env(cfg: DictConfig) -> TransformedEnv:
    """The batched environment with episode-reward and init tracking (the OU noise needs is_init)."""
    reward = Reward.from_mapping(OmegaConf.to_container(cfg.reward, resolve=True))
    return TransformedEnv(WaterAirEnv(env_config(cfg), reward=reward), Compose(InitTracker(), RewardSum()))


def make_actor(cfg: DictConfig, env, device) -> TensorDictModule:
    """Deterministic actor of the ``actor`` group: MLP(observation) → tanh → action in [-1, 1]."""
    sizes = env.observation_spec["observation"].shape[-1], env.action_spec.shape[-1]
    return build_actor(*sizes, cfg.actor.hidden, cfg.actor.activation, cfg.actor.zero_output).to(device)


def make_critic(cfg: DictConfig, env, device) -> ValueOperator:
    """Q(s, a) of the ``critic`` group."""
    sizes = env.observation_spec["observation"].shape[-1], env.action_spec.shape[-1]
    return build_critic(*sizes, cfg.critic.hidden, cfg.critic.activation).to(device)


def make_loss(cfg: DictConfig, actor, critic, env):
    """``agent.loss`` (DDPGLoss or TD3Loss) with a TD(0) value estimator at ``agent.gamma``, and its soft update."""
    extra = {"action_spec": env.action_spec_unbatched} if cfg.agent.name == "td3" else {}
    loss = instantiate(cfg.agent.loss)(actor, critic, **extra)
    loss.make_value_estimator(gamma=cfg.agent.gamma)
    return loss, SoftUpdate(loss, tau=cfg.agent.tau)


def make_exploration(cfg: DictConfig, actor, env, device) -> tuple[TensorDictSequential, TensorDictModuleBase]:
    """The exploration policy (actor, then annealed Gaussian or Ornstein-Uhlenbeck noise) and its noise module.

    The noise acts only under ``ExplorationType.RANDOM``: evaluation runs the bare actor. Step the
    noise module once per collected env step to anneal it.
    """
    steps = max(1, cfg.noise.annealing_frames // cfg.env.num_envs)
    spec = env.action_spec_unbatched.to(device)
    if cfg.noise.name == "ou":
        noise = OrnsteinUhlenbeckProcessModule(
            spec=spec,
            eps_init=1.0,
            eps_end=cfg.noise.sigma_end / max(cfg.noise.sigma_init, 1e-12),
            annealing_num_steps=steps,
            theta=cfg.noise.theta,
            sigma=cfg.noise.sigma_init,
            device=device,
        )
    else:
        noise = AdditiveGaussianModule(
            spec=spec,
            sigma_init=float(cfg.noise.sigma_init),
            sigma_end=float(cfg.noise.sigma_end),
            annealing_num_steps=steps,
            device=device,
        )
    return TensorDictSequential(actor, noise), noise


def make_optimisers(cfg: DictConfig, loss):
    """Adam for the actor and for the critic(s), at ``actor.lr`` and ``critic.lr``."""
    actor_params = list(loss.actor_network_params.flatten_keys().values())
    critic_params = loss.qvalue_network_params if cfg.agent.name == "td3" else loss.value_network_params
    critic_params = list(critic_params.flatten_keys().values())
    return torch.optim.Adam(actor_params, lr=cfg.actor.lr), torch.optim.Adam(critic_params, lr=cfg.critic.lr)


def make_buffer(cfg: DictConfig, run_dir: Path, device) -> TensorDictReplayBuffer:
    """Uniform replay over flattened transitions; in memory or memory-mapped on disk."""
    if cfg.buffer.name == "memmap":
        scratch = Path(cfg.buffer.scratch_dir) if cfg.buffer.scratch_dir else run_dir / "buffer"
        storage = LazyMemmapStorage(cfg.buffer.capacity, scratch_dir=str(scratch), existsok=True)
    else:
        storage = LazyTensorStorage(cfg.buffer.capacity, device=device)
    return TensorDictReplayBuffer(storage=storage, batch_size=cfg.buffer.batch_size)


def make_collector(cfg: DictConfig, env, policy, frames_done: int) -> Collector:
    """TorchRL Collector for exactly the frames still to go (all of them unless resuming)."""
    remaining = cfg.total_frames - frames_done
    if remaining <= 0 or remaining % cfg.collector.frames_per_batch:
        raise ValueError(
            f"total_frames = {cfg.total_frames} leaves {remaining} frames after {frames_done}; that must be a "
            f"positive multiple of collector.frames_per_batch = {cfg.collector.frames_per_batch}"
        )
    random_frames = max(0, cfg.collector.init_random_frames - frames_done)
    return Collector(
        env,
        policy,
        frames_per_batch=cfg.collector.frames_per_batch,
        total_frames=remaining,
        init_random_frames=random_frames,
        auto_register_policy_transforms=False,
    )


def make_update(cfg: DictConfig, loss, target_update, optim_actor, optim_critic):
    """One gradient step on a sampled batch; the actor steps every ``agent.policy_delay`` updates (TD3).

    The step returns the (actor, critic) losses as a detached ``[2]`` tensor.
    """
    value_key = "loss_qvalue" if cfg.agent.name == "td3" else "loss_value"
    policy_delay = cfg.agent.policy_delay if cfg.agent.name == "td3" else 1

    def update(batch: TensorDict, count: int) -> torch.Tensor:
        losses = loss(batch)
        # Only the loss_* entries: the other outputs (pred_value, ...) still require grad.
        update_actor = count % policy_delay == 0
        total = losses[value_key] + (losses["loss_actor"] if update_actor else 0.0)
        optim_actor.zero_grad(set_to_none=True)
        optim_critic.zero_grad(set_to_none=True)
        total.backward()
        optim_critic.step()
        if update_actor:
            optim_actor.step()
        target_update.step()
        # Detached, not .item(): no host synchronisation (and no graph break) per update; the loop
        # turns a whole batch of these into numbers once.
        return torch.stack((losses["loss_actor"], losses[value_key])).detach()

    return torch.compile(update) if cfg.compile_update else update
