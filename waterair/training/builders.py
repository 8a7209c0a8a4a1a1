"""Builders of the training pieces every algorithm shares, one per config group: ``make_X(cfg, ...)`` returns X.

The environment (``env``, ``reward``, ``link``), the actor (``actor``), the replay buffer (``buffer``)
and the collector (``collector``). What differs between algorithms (critic, exploration, loss,
optimisers, update and learning step) is built by :mod:`waterair.training.algorithms`.
"""

from __future__ import annotations

from pathlib import Path

from omegaconf import DictConfig, OmegaConf
from tensordict.nn import TensorDictModuleBase
from torchrl.collectors import Collector
from torchrl.data import LazyMemmapStorage, LazyTensorStorage, TensorDictReplayBuffer
from torchrl.data.replay_buffers.samplers import SamplerWithoutReplacement
from torchrl.envs import Compose, InitTracker, RewardSum, TransformedEnv

from waterair.agents.networks import actor_for
from waterair.agents.recurrent import CELLS, state_primer
from waterair.envs.config import EnvConfig
from waterair.envs.env import WaterAirEnv
from waterair.envs.link import link_budget
from waterair.envs.rewards import Reward
from waterair.physics.link import LinkBudget


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
    """The batched environment with episode-reward and init tracking (the OU noise and a recurrent actor need
    is_init), and a recurrent actor's state declared (zero at each reset)."""
    config = env_config(cfg)
    reward = make_reward(cfg, config)
    transforms = [InitTracker(), RewardSum()]
    if cfg.actor.name in CELLS:
        transforms.append(state_primer(cfg.actor.name, cfg.actor.state_size, cfg.actor.layers))
    return TransformedEnv(WaterAirEnv(config, reward=reward), Compose(*transforms))


def make_actor(cfg: DictConfig, env, device) -> TensorDictModuleBase:
    """Deterministic actor of the ``actor`` group: [a recurrent module →] MLP (per end, ``per_end``) → tanh → action
    in [-1, 1]."""
    sizes = env.observation_spec["observation"].shape[-1], env.action_spec.shape[-1]
    return actor_for(cfg.actor, *sizes, env.base_env.config).to(device)


def memory_storage(buffer: DictConfig, capacity: int, run_dir: Path, device):
    """``buffer=memory``: the transitions in memory, on the device."""
    return LazyTensorStorage(capacity, device=device)


def memmap_storage(buffer: DictConfig, capacity: int, run_dir: Path, device):
    """``buffer=memmap``: the transitions in memory-mapped files (``buffer.scratch_dir``, else the run's
    ``buffer/``)."""
    scratch = Path(buffer.scratch_dir) if buffer.scratch_dir else run_dir / "buffer"
    return LazyMemmapStorage(capacity, scratch_dir=str(scratch), existsok=True)


STORAGES = {"memory": memory_storage, "memmap": memmap_storage}
"""The ``buffer`` group's options by name: each builds the replay storage from the group, the capacity, the run's
folder and the device."""


def make_buffer(cfg: DictConfig, run_dir: Path, device, on_policy: bool) -> TensorDictReplayBuffer:
    """Uniform replay over flattened transitions; in memory or memory-mapped on disk.

    ``on_policy`` (the algorithm's trait): the last collected batch alone, sampled in whole minibatches
    without replacement; the rows a pass cannot fill a minibatch with wait for the next pass's shuffle,
    so every pass starts on a fresh permutation. Each ``sample`` is a whole pass's minibatches, which the
    learning step splits (the same rows as one call per minibatch). Off-policy: uniform with replacement, each
    ``sample`` of the size it names (a collected batch's updates draw theirs in one call).
    """
    capacity = cfg.collector.frames_per_batch if on_policy else cfg.buffer.capacity
    storage = STORAGES[cfg.buffer.name](cfg.buffer, capacity, run_dir, device)
    sampler = SamplerWithoutReplacement(drop_last=True) if on_policy else None
    per_pass = capacity // cfg.buffer.batch_size * cfg.buffer.batch_size if on_policy else None
    return TensorDictReplayBuffer(storage=storage, sampler=sampler, batch_size=per_pass)


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
