"""Builders of the training pieces, one per config group: ``make_X(cfg, ...)`` returns X.

The environment (``env``, ``reward``), networks (``actor``, ``critic``), exploration (``noise``),
loss and target update (``agent``), optimisers, replay buffer (``buffer``), collector
(``collector``) and the learning step. DDPG and TD3 learn off-policy from a replay of every
transition; PPO (``agent=ppo``) learns on-policy from each collected batch.
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
from torchrl.data.replay_buffers.samplers import SamplerWithoutReplacement
from torchrl.envs import Compose, InitTracker, RewardSum, TransformedEnv
from torchrl.modules import AdditiveGaussianModule, OrnsteinUhlenbeckProcessModule, ValueOperator
from torchrl.objectives import SoftUpdate, ValueEstimators

from waterair.agents.networks import make_actor as build_actor
from waterair.agents.networks import make_critic as build_critic
from waterair.agents.networks import make_gaussian_policy, make_value
from waterair.envs.config import EnvConfig
from waterair.envs.env import WaterAirEnv
from waterair.envs.link import link_budget
from waterair.envs.rewards import Reward
from waterair.physics.link import LinkBudget

TRANSITION_KEYS = (
    "observation",
    "action",
    ("next", "observation"),
    ("next", "reward"),
    ("next", "done"),
    ("next", "terminated"),
)
"""What the replay buffer stores: the losses read nothing else (the env's gains stay out)."""
ON_POLICY = ("ppo",)
"""Agents that learn only from the batch their own policy just collected."""


def env_config(cfg: DictConfig, **overrides) -> EnvConfig:
    """The validated environment config of the ``env`` group, with ``overrides`` applied."""
    return EnvConfig.from_mapping({**OmegaConf.to_container(cfg.env, resolve=True), **overrides})


def make_link(cfg: DictConfig, config: EnvConfig | None = None) -> LinkBudget:
    """The link budget of the ``link`` group on the channel of ``config`` (default: the ``env`` group's)."""
    values = OmegaConf.to_container(cfg.link, resolve=True) if "link" in cfg else None
    return link_budget(values, config or env_config(cfg))


def make_reward(cfg: DictConfig, config: EnvConfig | None = None) -> Reward:
    """The reward of the ``reward`` group (``snr`` reads the link budget)."""
    return Reward.from_mapping(OmegaConf.to_container(cfg.reward, resolve=True), link=make_link(cfg, config))


def make_env(cfg: DictConfig) -> TransformedEnv:
    """The batched environment with episode-reward and init tracking (the OU noise needs is_init)."""
    config = env_config(cfg)
    reward = make_reward(cfg, config)
    return TransformedEnv(WaterAirEnv(config, reward=reward), Compose(InitTracker(), RewardSum()))


def make_actor(cfg: DictConfig, env, device) -> TensorDictModule:
    """Deterministic actor of the ``actor`` group: MLP(observation) → tanh → action in [-1, 1]."""
    sizes = env.observation_spec["observation"].shape[-1], env.action_spec.shape[-1]
    return build_actor(*sizes, cfg.actor.hidden, cfg.actor.activation, cfg.actor.zero_output).to(device)


def make_critic(cfg: DictConfig, env, device) -> ValueOperator:
    """The ``critic`` group's network: Q(s, a), or V(s) for an on-policy agent."""
    sizes = env.observation_spec["observation"].shape[-1], env.action_spec.shape[-1]
    if cfg.agent.name in ON_POLICY:
        return make_value(sizes[0], cfg.critic.hidden, cfg.critic.activation).to(device)
    return build_critic(*sizes, cfg.critic.hidden, cfg.critic.activation).to(device)


def make_loss(cfg: DictConfig, actor, exploration, critic, env):
    """``agent.loss`` and its target update (None for PPO, which keeps no target networks).

    DDPG and TD3 learn the deterministic ``actor`` with a TD(0) estimator at ``agent.gamma``; PPO
    learns its stochastic ``exploration`` policy with generalised advantage estimation at
    ``agent.gamma`` and ``agent.lmbda``.
    """
    if cfg.agent.name in ON_POLICY:
        loss = instantiate(cfg.agent.loss)(exploration, critic)
        loss.make_value_estimator(ValueEstimators.GAE, gamma=cfg.agent.gamma, lmbda=cfg.agent.lmbda)
        return loss, None
    extra = {"action_spec": env.action_spec_unbatched} if cfg.agent.name == "td3" else {}
    loss = instantiate(cfg.agent.loss)(actor, critic, **extra)
    loss.make_value_estimator(gamma=cfg.agent.gamma)
    return loss, SoftUpdate(loss, tau=cfg.agent.tau)


def make_exploration(cfg: DictConfig, actor, env, device) -> tuple[TensorDictModuleBase, torch.nn.Module]:
    """The exploration policy and the module that holds its noise.

    DDPG and TD3: the actor, then annealed Gaussian or Ornstein-Uhlenbeck noise (the noise module,
    stepped once per collected env step to anneal it). PPO: the Gaussian policy around the actor,
    whose noise is a learned scale starting at ``noise.sigma_init`` (the noise module is that scale).
    Noise acts only under ``ExplorationType.RANDOM``: evaluation runs the bare actor.
    """
    steps = max(1, cfg.noise.annealing_frames // cfg.env.num_envs)
    spec = env.action_spec_unbatched.to(device)
    if cfg.agent.name in ON_POLICY:
        policy = make_gaussian_policy(actor, spec, cfg.noise.sigma_init).to(device)
        return policy, policy.module[0].module[1]  # the learned scale
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
    """Adam for the actor (PPO: with its noise scale) and for the critic(s), at ``actor.lr`` and ``critic.lr``."""
    actor_params = list(loss.actor_network_params.flatten_keys().values())
    critic_params = {"td3": "qvalue_network_params", "ppo": "critic_network_params"}.get(
        cfg.agent.name, "value_network_params"
    )
    critic_params = list(getattr(loss, critic_params).flatten_keys().values())
    return torch.optim.Adam(actor_params, lr=cfg.actor.lr), torch.optim.Adam(critic_params, lr=cfg.critic.lr)


def make_buffer(cfg: DictConfig, run_dir: Path, device) -> TensorDictReplayBuffer:
    """Uniform replay over flattened transitions; in memory or memory-mapped on disk.

    On-policy (PPO): the last collected batch alone, sampled in whole minibatches without
    replacement; the rows a pass cannot fill a minibatch with wait for the next pass's shuffle, so
    every pass starts on a fresh permutation.
    """
    on_policy = cfg.agent.name in ON_POLICY
    capacity = cfg.collector.frames_per_batch if on_policy else cfg.buffer.capacity
    if cfg.buffer.name == "memmap":
        scratch = Path(cfg.buffer.scratch_dir) if cfg.buffer.scratch_dir else run_dir / "buffer"
        storage = LazyMemmapStorage(capacity, scratch_dir=str(scratch), existsok=True)
    else:
        storage = LazyTensorStorage(capacity, device=device)
    sampler = SamplerWithoutReplacement(drop_last=True) if on_policy else None
    return TensorDictReplayBuffer(storage=storage, sampler=sampler, batch_size=cfg.buffer.batch_size)


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

    PPO's step sums the clipped objective and the critic loss and clips the gradient norm at
    ``agent.max_grad_norm``. The step returns the (actor, critic) losses as a detached ``[2]`` tensor,
    PPO's with the approximate KL divergence from the collecting policy as a third entry.
    """
    if cfg.agent.name in ON_POLICY:
        params = [p for group in (optim_actor, optim_critic) for g in group.param_groups for p in g["params"]]

        def update(batch: TensorDict, count: int) -> torch.Tensor:
            losses = loss(batch)
            optim_actor.zero_grad(set_to_none=True)
            optim_critic.zero_grad(set_to_none=True)
            (losses["loss_objective"] + losses["loss_critic"]).backward()
            torch.nn.utils.clip_grad_norm_(params, cfg.agent.max_grad_norm)
            optim_actor.step()
            optim_critic.step()
            kl = losses["kl_approx"].mean()  # how far this minibatch's policy moved from the collecting one
            return torch.stack((losses["loss_objective"], losses["loss_critic"], kl)).detach()

        return torch.compile(update) if cfg.compile_update else update

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


def make_learn(cfg: DictConfig, loss, update, buffer: TensorDictReplayBuffer, noise):
    """What the loop does with each collected batch: ``learn(batch, progress)`` → the update losses.

    ``progress`` counts frames (this batch included) and updates. Each batch gets
    ``collector.updates_per_frame`` × its frames updates, none before
    ``collector.init_random_frames`` (uniform random actions). Off-policy: anneal the noise, store
    the batch's transitions, then sample each update from the whole replay. On-policy (PPO): the
    batch alone, in passes of ``frames_per_batch // batch_size`` minibatches (that many updates
    rounded to whole passes), its advantages recomputed before each pass, and no further pass once a
    pass has moved the policy by more than ``agent.target_kl`` (mean approximate KL from the policy
    that collected the batch; null: every pass).
    """
    per_batch = max(1, round(cfg.collector.frames_per_batch * cfg.collector.updates_per_frame))
    steps_per_batch = cfg.collector.frames_per_batch // cfg.env.num_envs
    random_frames, batch_size = cfg.collector.init_random_frames, cfg.buffer.batch_size

    if cfg.agent.name in ON_POLICY:
        keys = loss.tensor_keys
        stored = ("observation", "action", keys.sample_log_prob, keys.advantage, keys.value_target)
        per_pass = cfg.collector.frames_per_batch // batch_size
        passes = max(1, round(per_batch / per_pass))
        target_kl = cfg.agent.target_kl

        def learn_on_policy(batch: TensorDict, progress) -> list[torch.Tensor]:
            if progress.frames - batch.numel() < random_frames:  # random actions have no log-probability
                return []
            losses: list[torch.Tensor] = []
            for index in range(passes):
                if index and target_kl is not None:  # one host synchronisation per pass
                    if torch.stack(losses[-per_pass:])[:, 2].mean().item() > target_kl:
                        break
                with torch.no_grad():
                    loss.value_estimator(batch)
                buffer.extend(batch.select(*stored).reshape(-1))  # the storage holds one batch
                for _ in range(per_pass):
                    losses.append(update(buffer.sample(), progress.updates))
                    progress.updates += 1
            return losses

        return learn_on_policy

    def learn_off_policy(batch: TensorDict, progress) -> list[torch.Tensor]:
        noise.step(steps_per_batch)
        buffer.extend(batch.select(*TRANSITION_KEYS).reshape(-1))
        if progress.frames < random_frames or len(buffer) < batch_size:
            return []
        losses = []
        for _ in range(per_batch):
            losses.append(update(buffer.sample(), progress.updates))
            progress.updates += 1
        return losses

    return learn_off_policy
