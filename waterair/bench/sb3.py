"""Stable-Baselines3 DDPG and PPO on our Gymnasium view, matched to a training config: the reference
pipelines the training and time-to-quality suites compare with.

Stable-Baselines3 is not a dependency (the ``bench`` extra, which ``make bench`` installs): :func:`sb3_ddpg` and
:func:`sb3_ppo` return None when it does not import, and :data:`MISSING` says so before a suite starts.
"""

from __future__ import annotations

import importlib.util
from fractions import Fraction

import torch
from omegaconf import DictConfig, OmegaConf
from tensordict.nn import TensorDictModuleBase

from waterair.envs.rewards import Reward
from waterair.training.builders import env_config

MISSING = (
    "Stable-Baselines3 is not installed: the suite leaves out its rows "
    "(pip install -e '.[bench]', or make bench, installs it)"
)
"""The line a suite that compares with Stable-Baselines3 prints first when it is missing (:func:`installed`)."""


def installed() -> bool:
    """Whether Stable-Baselines3 imports."""
    return importlib.util.find_spec("stable_baselines3") is not None


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

    ratio = Fraction(cfg.collector.updates_per_frame).limit_denominator(64)  # 0.15625: 5 updates every 32 steps
    model = DDPG(
        "MlpPolicy",
        _gym_env(cfg, seed),
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
    return _logging_nowhere(model)


def sb3_ppo(cfg: DictConfig, seed: int = 0):
    """A Stable-Baselines3 PPO model on one link of ``cfg``'s environment (eager step), matched to ``agent=ppo``:
    a rollout of ``collector.frames_per_batch`` steps, passes over it as ``collector.updates_per_frame`` gives in
    minibatches of ``buffer.batch_size``, ``actor.lr``, discount, GAE's λ, clip range, advantage normalisation,
    critic coefficient, gradient-norm clip, target KL, no entropy bonus, the actor's and critic's hidden layers,
    and a learned state-independent log-σ starting at ln ``noise.sigma_init``; None without Stable-Baselines3."""
    try:
        from stable_baselines3 import PPO
    except ImportError:
        return None
    import math

    frames, batch = cfg.collector.frames_per_batch, cfg.buffer.batch_size
    loss = cfg.agent.loss
    model = PPO(
        "MlpPolicy",
        _gym_env(cfg, seed),
        learning_rate=cfg.actor.lr,
        n_steps=frames,
        batch_size=batch,
        n_epochs=max(1, round(cfg.collector.updates_per_frame * batch)),  # 0.15625 × 64 = 10 passes
        gamma=cfg.agent.gamma,
        gae_lambda=cfg.agent.lmbda,
        clip_range=loss.clip_epsilon,
        normalize_advantage=loss.normalize_advantage,
        ent_coef=0.0,
        vf_coef=loss.critic_coeff,
        max_grad_norm=cfg.agent.max_grad_norm,
        target_kl=cfg.agent.target_kl,
        policy_kwargs={
            "net_arch": {"pi": list(cfg.actor.hidden), "vf": list(cfg.critic.hidden)},
            "log_std_init": math.log(cfg.noise.sigma_init),
        },
        device="cpu",
        seed=seed,
    )
    return _logging_nowhere(model)


def _logging_nowhere(model):
    """``model`` with a logger that writes nothing: without one of its own, each ``learn`` of Stable-Baselines3's
    makes a folder ``SB3-<date and time>`` in the temporary directory (a time-to-quality run learns hundreds of
    times)."""
    from stable_baselines3.common.logger import Logger

    model.set_logger(Logger(folder=None, output_formats=[]))
    return model


def _gym_env(cfg: DictConfig, seed: int):
    """One link of ``cfg``'s environment, eager, as a Gymnasium env with ``cfg``'s reward."""
    from waterair.envs.gym import WaterAirGymEnv

    reward = Reward.from_mapping(OmegaConf.to_container(cfg.reward, resolve=True))
    return WaterAirGymEnv(env_config(cfg, compile_kernel=False), reward=reward, seed=seed)


class SB3Actor(TensorDictModuleBase):
    """A Stable-Baselines3 model's deterministic action (DDPG's actor, PPO's mean) as a TensorDict policy
    (``observation`` → ``action``), clipped to the action bounds as Stable-Baselines3 clips it."""

    in_keys = ["observation"]
    out_keys = ["action"]

    def __init__(self, model):
        super().__init__()
        self.model = model

    def forward(self, tensordict):
        with torch.no_grad():
            action = self.model.policy._predict(tensordict.get("observation").float(), deterministic=True)
        return tensordict.set("action", action.clamp(-1.0, 1.0))
