"""The training checkpoint: a policy file (``waterair.agents.checkpoint``) plus the learner's state.

``checkpoints/last.pt`` holds the policy entries (format tag, actor weights, observation size,
frames) that evaluation reads, and everything a resumed run needs: counters, the loss module
(networks and target networks), exploration noise, optimisers and random-number states. It is
written atomically; the replay buffer, when kept, is dumped next to it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import torch

from waterair.agents.checkpoint import load_state, policy_state, save_policy

CHECKPOINT = "checkpoints/last.pt"
"""Where a run's checkpoint lives, relative to the run directory."""
BUFFER_DIR = "checkpoints/buffer"


@dataclass
class Progress:
    """Counters saved in every checkpoint."""

    frames: int = 0
    updates: int = 0
    episodes: int = 0


@dataclass
class Learner:
    """Everything a checkpoint saves and restores, besides the counters."""

    actor: torch.nn.Module
    loss: torch.nn.Module
    noise: torch.nn.Module
    optim_actor: torch.optim.Optimizer
    optim_critic: torch.optim.Optimizer
    env_generator: torch.Generator
    buffer: object
    observation_size: int


def save_checkpoint(run_dir: Path, progress: Progress, learner: Learner, keep_buffer: bool) -> Path:
    """Write ``checkpoints/last.pt`` atomically (and dump the replay buffer first when kept)."""
    if keep_buffer:
        learner.buffer.dumps(str(Path(run_dir) / BUFFER_DIR))
    state = {
        **policy_state(learner.actor, learner.observation_size, progress.frames),
        "updates": progress.updates,
        "episodes": progress.episodes,
        "loss": learner.loss.state_dict(),
        "exploration": learner.noise.state_dict(),
        "optim_actor": learner.optim_actor.state_dict(),
        "optim_critic": learner.optim_critic.state_dict(),
        "torch_rng": torch.get_rng_state(),
        "env_rng": learner.env_generator.get_state(),
    }
    return save_policy(Path(run_dir) / CHECKPOINT, state)


def load_checkpoint(run_dir: Path, learner: Learner, keep_buffer: bool) -> Progress:
    """Restore everything :func:`save_checkpoint` wrote; ``torch.load(weights_only=True)`` only."""
    state = load_state(Path(run_dir) / CHECKPOINT)
    learner.loss.load_state_dict(state["loss"])
    learner.noise.load_state_dict(state["exploration"])
    learner.optim_actor.load_state_dict(state["optim_actor"])
    learner.optim_critic.load_state_dict(state["optim_critic"])
    torch.set_rng_state(state["torch_rng"])
    learner.env_generator.set_state(state["env_rng"])
    buffer_dir = Path(run_dir) / BUFFER_DIR
    if keep_buffer and buffer_dir.exists():
        learner.buffer.loads(str(buffer_dir))
    return Progress(state["frames"], state["updates"], state["episodes"])
