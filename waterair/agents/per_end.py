"""Each end on its own (``actor=per_end``): the transmitter's and the drone's networks, each reading its own
terminal's parts of the observation, the parts both ends know, and the other end's parts as a return channel brings
them, ``return_steps`` steps late (docs/training.md, "Each end on its own").

Each network points its own end (the transmitter's two action components, the drone's two); the critic, used only in
training, reads the whole observation (centralised training, decentralised acting). The other end's parts come from
the observation's older frames: with ``env.frames`` F and ``return_steps`` L, an end reads the other's frames L to
F − 1, none when L ≥ F.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import torch
from torch import nn
from torchrl.modules import MLP

PER_END = "per_end"
"""The ``actor`` option's name."""
ENDS = {
    "tx": ("tx_pointing", "beacon", "beacon_valid"),
    "rx": ("rx_pointing", "intensity", "spot", "spot_valid", "history"),
}
"""The observation's parts each terminal senses itself: the vehicle's pointing and its beacon detector; the drone's
pointing, photodiode, quadrant spot and intensity history (docs/environment.md, "Observation")."""
SHARED = ("time", "geometry", "divergence")
"""The parts both ends know without a reading: the clock, the planned geometry and the beam's divergence."""
ACTIONS = {"tx": slice(0, 2), "rx": slice(2, 4)}
"""Each end's action components."""


def end_columns(layout: Mapping[str, slice], frames: int, end: str, return_steps: int) -> list[int]:
    """The observation's columns ``end``'s network reads (frames newest first, each of the layout's width)."""
    unknown = set(layout) - {*ENDS["tx"], *ENDS["rx"], *SHARED}
    if unknown:
        raise ValueError(
            f"actor=per_end cannot say which end observes {', '.join(sorted(unknown))}; drop it from "
            f"env.observation_extras"
        )
    other = "rx" if end == "tx" else "tx"
    width = max(part.stop for part in layout.values())
    return [
        frame * width + column
        for frame in range(frames)
        for name, part in layout.items()
        if name in ENDS[end] or name in SHARED or (name in ENDS[other] and frame >= return_steps)
        for column in range(part.start, part.stop)
    ]


class PerEnd(nn.Module):
    """The two ends' MLPs on their own columns of the observation (:func:`end_columns`), their actions side by side
    in the action's order. The columns are buffers: a policy file holds them with the weights."""

    def __init__(
        self, columns: Mapping[str, Sequence[int]], hidden: Sequence[int], activation: type[nn.Module]
    ) -> None:
        super().__init__()
        self.nets = nn.ModuleDict()
        for end, cols in columns.items():
            self.register_buffer(f"{end}_columns", torch.tensor(list(cols), dtype=torch.long))
            width = ACTIONS[end].stop - ACTIONS[end].start
            self.nets[end] = MLP(
                in_features=len(cols), out_features=width, num_cells=list(hidden), activation_class=activation
            )

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        return torch.cat(
            [net(observation.index_select(-1, getattr(self, f"{end}_columns"))) for end, net in self.nets.items()],
            dim=-1,
        )


def per_end_columns(layout: Mapping[str, slice], frames: int, return_steps: int) -> dict[str, list[int]]:
    """Both ends' columns, the transmitter's first (:data:`ACTIONS`' order)."""
    return {end: end_columns(layout, frames, end, return_steps) for end in ACTIONS}
