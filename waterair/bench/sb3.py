"""Stable-Baselines3 DDPG on our Gymnasium view, matched to a training config: the one reference
pipeline the training and time-to-quality suites compare with.

Stable-Baselines3 is not a dependency: :func:`sb3_ddpg` returns None when it does not import.
"""

from __future__ import annotations

from fractions import Fraction

import torch
from omegaconf import DictConfig, OmegaConf
from tensordict.nn import TensorDictModuleBase

from waterair.envs.rewards import Reward
from waterair.training.builders import env_config


def sb3_ddpg(cfg: DictConfig, seed: int = 0):
    """A Stable-Baselines3 DDPG model on one link of ``cfg``'s environment (eager step), with
    ``cfg``'s learning rate, replay capacity, batch, τ, discount, Gaussian noise σ, hidden layers
    and updates per frame (as a fraction: n updates every m steps), learning from its first full batch;
    None without Stable-Baselines3."""
    try:
        from stable_baselines3 import DDPG
        from stable_baselines3.common.noise import NormalActionNoise
    except ImportError:
        return None
    import numpy as np

    from waterair.envs.gym import WaterAirGymEnv

    ratio = Fraction(cfg.collector.updates_per_frame).limit_denominator(64)  # 0.15625: 5 updates every 32 steps
    reward = Reward.from_mapping(OmegaConf.to_container(cfg.reward, resolve=True))
    env = WaterAirGymEnv(env_config(cfg, compile_kernel=False), reward=reward, seed=seed)
    return DDPG(
        "MlpPolicy",
        env,
        learning_rate=cfg.critic.lr,
        buffer_size=cfg.buffer.capacity,
        learning_starts=cfg.buffer.batch_size,
        batch_size=cfg.buffer.batch_size,
        tau=cfg.agent.tau,
        gamma=cfg.agent.gamma,
        train_freq=(ratio.denominator, "step"),
        gradient_steps=ratio.numerator,
        action_noise=NormalActionNoise(np.zeros(4), cfg.noise.sigma_init * np.ones(4)),
        policy_kwargs={"net_arch": list(cfg.actor.hidden)},
        device="cpu",
        seed=seed,
    )


class SB3Actor(TensorDictModuleBase):
    """A Stable-Baselines3 deterministic actor as a TensorDict policy (``observation`` → ``action``)."""

    in_keys = ["observation"]
    out_keys = ["action"]

    def __init__(self, model):
        super().__init__()
        self.model = model

    def forward(self, tensordict):
        with torch.no_grad():
            action = self.model.actor(tensordict.get("observation").float())
        return tensordict.set("action", action.clamp(-1.0, 1.0))
