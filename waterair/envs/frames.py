"""Frame stacking inside the environment: the last k observation frames side by side, newest first.

The same temporal context as TorchRL's ``CatFrames``, kept by the environment so that every consumer
of the observation sees it: the collector, the replay buffer, evaluation's replica batches and the
Gymnasium view. The newest frame comes first, so ``EnvConfig.observation_layout`` still names where
each part of the present frame sits; a reset fills every slot of its rows with the new frame.
"""

from __future__ import annotations

import torch


class FrameStack:
    """A ring of the last ``frames`` observation frames of B links, ``[B, frames, size]``."""

    def __init__(self, batch: int, frames: int, size: int, dtype: torch.dtype, device: torch.device):
        self.frames = torch.zeros(batch, frames, size, dtype=dtype, device=device)

    def reset(self, rows: torch.Tensor, frame: torch.Tensor) -> torch.Tensor:
        """Fill every slot of ``rows`` with their rows of ``frame`` ``[B, size]``; the stack ``[B, frames · size]``.

        Out of place: the stacks handed out earlier stay as they were (a collector's last ``next``
        observation of a finished episode must not turn into the new episode's first).
        """
        self.frames = self.frames.clone()
        self.frames[rows] = frame[rows].unsqueeze(1).expand(-1, self.frames.shape[1], -1)
        return self.frames.flatten(1)

    def push(self, frame: torch.Tensor) -> torch.Tensor:
        """Add the newest ``frame`` ``[B, size]`` of every link; the stack ``[B, frames · size]``."""
        self.frames = torch.cat((frame.unsqueeze(1), self.frames[:, :-1]), dim=1)
        return self.frames.flatten(1)
