"""The training checkpoint: a policy file (``waterair.agents.checkpoint``) plus the learner's state.

``checkpoints/last.pt`` holds the policy entries (format tag, the greedy policy's weights,
observation size, frames) that evaluation reads, and everything a resumed run needs: counters,
the loss module (networks and target networks), exploration noise, optimisers and random-number
states. It is written atomically; the replay buffer, when kept, is dumped next to it first.
"""

from __future__ import annotations

import copy
import shutil
from dataclasses import dataclass
from pathlib import Path

import torch

from waterair.agents.checkpoint import load_state, policy_state, save_policy

CHECKPOINT = "checkpoints/last.pt"
"""Where a run's checkpoint lives, relative to the run directory."""
BUFFER_PREFIX = "buffer-"
"""Replay-buffer dumps are ``checkpoints/buffer-<frames>`` folders."""


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
    sensor_generator: torch.Generator
    buffer: object
    observation_size: int
    average: bool = False  # the greedy policy is the actor's Polyak average (its target network)
    env_episodes: torch.Tensor | None = None  # each link's resets so far (keyed draws: a part of their keys)

    def policy(self) -> torch.nn.Module:
        """The greedy policy the run saves and evaluates (``agent.policy_weights``): the actor's last
        iterate, or a snapshot of its Polyak average, the loss's target actor (rate ``agent.tau``)."""
        if not self.average:
            return self.actor
        policy = copy.deepcopy(self.actor)
        policy.load_state_dict(dict(self.loss.target_actor_network_params.flatten_keys(".").items()))
        return policy


def save_checkpoint(run_dir: Path, progress: Progress, learner: Learner, keep_buffer: bool) -> Path:
    """Write ``checkpoints/last.pt`` atomically; with ``keep_buffer`` dump the replay buffer first.

    The buffer goes to ``checkpoints/buffer-<frames>`` (dumped under a temporary name, then renamed),
    and the checkpoint records which dump and how many transitions it holds. Older dumps are
    removed only after the new checkpoint is in place, so a run killed at any moment leaves a
    checkpoint whose own dump is intact.
    """
    run_dir = Path(run_dir)
    state = {
        **policy_state(learner.policy(), learner.observation_size, progress.frames),
        "updates": progress.updates,
        "episodes": progress.episodes,
        "loss": learner.loss.state_dict(),
        "exploration": learner.noise.state_dict(),
        "optim_actor": learner.optim_actor.state_dict(),
        "optim_critic": learner.optim_critic.state_dict(),
        "torch_rng": torch.get_rng_state(),
        "env_rng": learner.env_generator.get_state(),
        "sensor_rng": learner.sensor_generator.get_state(),
        **({} if learner.env_episodes is None else {"env_episodes": learner.env_episodes.clone()}),
    }
    if keep_buffer:
        state["buffer"] = {"dir": _dump_buffer(run_dir, learner.buffer, progress.frames), "size": len(learner.buffer)}
    path = save_policy(run_dir / CHECKPOINT, state)
    keep = state.get("buffer", {}).get("dir")
    for old in [*(run_dir / "checkpoints").glob(f"{BUFFER_PREFIX}*"), *(run_dir / "checkpoints").glob(".*.tmp")]:
        if old.name != keep:
            shutil.rmtree(old)
    return path


def load_checkpoint(run_dir: Path, learner: Learner, keep_buffer: bool) -> Progress:
    """Restore everything :func:`save_checkpoint` wrote; ``torch.load(weights_only=True)`` only.

    With ``keep_buffer`` the replay buffer is restored from the dump the checkpoint names, and its
    size is checked against the checkpoint; a missing or inconsistent dump is a one-line error.
    """
    run_dir = Path(run_dir)
    state = load_state(run_dir / CHECKPOINT)
    learner.loss.load_state_dict(state["loss"])
    learner.noise.load_state_dict(state["exploration"])
    learner.optim_actor.load_state_dict(state["optim_actor"])
    learner.optim_critic.load_state_dict(state["optim_critic"])
    torch.set_rng_state(state["torch_rng"])
    learner.env_generator.set_state(state["env_rng"])
    learner.sensor_generator.set_state(state["sensor_rng"])
    if learner.env_episodes is not None and "env_episodes" in state:  # a run saved before the key: none
        learner.env_episodes.copy_(state["env_episodes"])
    if keep_buffer and "buffer" in state:
        dump = run_dir / "checkpoints" / state["buffer"]["dir"]
        if not dump.is_dir():
            raise ValueError(f"checkpoint {run_dir / CHECKPOINT} names the replay buffer {dump}, which is missing")
        learner.buffer.loads(str(dump))
        if len(learner.buffer) != state["buffer"]["size"]:
            raise ValueError(
                f"replay buffer {dump} holds {len(learner.buffer)} transitions; its checkpoint says "
                f"{state['buffer']['size']}"
            )
    return Progress(state["frames"], state["updates"], state["episodes"])


def _dump_buffer(run_dir: Path, buffer, frames: int) -> str:
    """Dump ``buffer`` to ``checkpoints/buffer-<frames>`` via a temporary folder; return the folder's name."""
    name = f"{BUFFER_PREFIX}{frames}"
    final, temporary = run_dir / "checkpoints" / name, run_dir / "checkpoints" / f".{name}.tmp"
    for stale in (final, temporary):
        if stale.exists():
            shutil.rmtree(stale)
    buffer.dumps(str(temporary))
    temporary.rename(final)
    return name
