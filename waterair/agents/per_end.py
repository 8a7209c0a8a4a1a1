"""Each end on its own (``actor=per_end``): the transmitter's and the drone's networks, each reading its own
terminal's parts of the observation, the parts both ends know, and the other end's parts as a return channel brings
them, ``return_steps`` steps late (docs/training.md, "Each end on its own").

Each end's network, an agent of TorchRL's ``MultiAgentMLP``, points its own end (the transmitter's two action
components, the drone's two); the critic, used only in training, reads the whole observation (and the off-policy
agents' the joint action: centralised training, decentralised acting). The other end's parts come from the
observation's older frames: with ``env.frames`` F and ``return_steps`` L, an end reads the other's frames L to
F − 1, none when L ≥ F.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import torch
from torch import nn
from torchrl.modules import MultiAgentMLP

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
    """The two ends' networks, each on its own columns of the observation (:func:`end_columns`), their actions side
    by side in the action's order: TorchRL's :class:`~torchrl.modules.MultiAgentMLP` with an agent per end,
    decentralised (an end reads only its own input) and with parameters of its own.

    Each end's columns are gathered into one row of ``[..., ends, width]``, ``width`` the wider end's count; the
    narrower end's row is padded with zeros, which its first layer never sees change. The columns and the padding's
    mask are buffers: a policy file holds them with the weights. Policy files of the earlier layout (an MLP per end
    under ``nets``) load into it unchanged in what they compute (:func:`_from_nets`)."""

    def __init__(
        self, columns: Mapping[str, Sequence[int]], hidden: Sequence[int], activation: type[nn.Module]
    ) -> None:
        super().__init__()
        if list(columns) != list(ACTIONS):
            raise ValueError(f"PerEnd needs the columns of {', '.join(ACTIONS)}, in that order; got {list(columns)}")
        width = max(len(cols) for cols in columns.values())
        index = torch.zeros(len(columns), width, dtype=torch.long)
        mask = torch.zeros(len(columns), width)
        for row, cols in enumerate(columns.values()):
            index[row, : len(cols)] = torch.tensor(list(cols), dtype=torch.long)
            mask[row, : len(cols)] = 1.0
        self.register_buffer("columns", index)
        self.register_buffer("mask", mask)
        outputs = {ACTIONS[end].stop - ACTIONS[end].start for end in columns}
        if len(outputs) != 1:
            raise ValueError(f"PerEnd needs every end to act on as many components; got {outputs}")
        self.agents = MultiAgentMLP(
            n_agent_inputs=width,
            n_agent_outputs=outputs.pop(),
            n_agents=len(columns),
            centralized=False,
            share_params=False,
            num_cells=list(hidden),
            activation_class=activation,
        )
        self.register_load_state_dict_pre_hook(_from_nets)

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        ends, width = self.columns.shape
        inputs = observation.index_select(-1, self.columns.flatten()).unflatten(-1, (ends, width)) * self.mask
        return self.agents(inputs).flatten(-2)

    def zero_output(self) -> None:
        """Start every end's output layer at 0 (its first actions are the residual base's)."""
        last = max(self.agents.params.keys(), key=int)
        with torch.no_grad():
            for tensor in self.agents.params[last].values():
                tensor.zero_()


def _from_nets(module: PerEnd, state: dict, prefix: str, *args) -> None:
    """Rewrite the earlier layout's entries in ``state`` (``nets.tx.0.weight``…, ``tx_columns``) in this one's:
    each layer's two ends stacked, the first layer's weights padded with zero columns."""
    ends = list(ACTIONS)
    if f"{prefix}{ends[0]}_columns" not in state:
        return
    width = module.columns.shape[1]
    columns = [state.pop(f"{prefix}{end}_columns") for end in ends]
    state[f"{prefix}columns"] = torch.stack([nn.functional.pad(c, (0, width - len(c))) for c in columns])
    state[f"{prefix}mask"] = torch.stack([nn.functional.pad(torch.ones(len(c)), (0, width - len(c))) for c in columns])
    first = min(module.agents.params.keys(), key=int)
    for key in list(state):
        if not key.startswith(f"{prefix}nets.{ends[0]}."):
            continue
        layer = key[len(f"{prefix}nets.{ends[0]}.") :]
        tensors = [state.pop(f"{prefix}nets.{end}.{layer}") for end in ends]
        if layer == f"{first}.weight":
            tensors = [nn.functional.pad(t, (0, width - t.shape[1])) for t in tensors]
        state[f"{prefix}agents.params.{layer}"] = torch.stack(tensors)


def per_end_columns(layout: Mapping[str, slice], frames: int, return_steps: int) -> dict[str, list[int]]:
    """Both ends' columns, the transmitter's first (:data:`ACTIONS`' order)."""
    return {end: end_columns(layout, frames, end, return_steps) for end in ACTIONS}
