"""Recurrent actors (``actor=gru``, ``actor=lstm``): a TorchRL recurrent module over the observations, then the
MLP head of :func:`waterair.agents.networks.make_actor` on its features (docs/training.md, "Memory").

The recurrent state travels in the TensorDict, as TorchRL's recurrent modules keep it: the module reads
``recurrent_state`` (an LSTM: ``recurrent_state_h`` and ``recurrent_state_c``) and ``is_init``, and writes the next
state to ``("next", ...)``; :func:`state_primer` declares it to the environment, which zeros it at each reset.
Collecting runs it one step at a time; PPO's loss runs it over whole sequences (``set_recurrent_mode``); the
off-policy agents replay each transition from the state it was collected with. An evaluation, on an environment
that carries no state, runs it through :class:`StepMemory`.
"""

from __future__ import annotations

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModule, TensorDictModuleBase, TensorDictSequential
from torch import nn
from torchrl.data import Unbounded
from torchrl.envs import TensorDictPrimer
from torchrl.modules import GRUModule, LSTMModule

CELLS = ("gru", "lstm")
"""The recurrent ``actor`` options."""
FEATURES = "features"
"""The recurrent module's output, the head's input."""


def state_keys(cell: str) -> tuple[str, ...]:
    """The recurrent state's keys of a ``cell``: a GRU's one, an LSTM's hidden and cell states."""
    return ("recurrent_state",) if cell == "gru" else ("recurrent_state_h", "recurrent_state_c")


def make_memory(cell: str, observation_size: int, state_size: int, layers: int) -> TensorDictModuleBase:
    """The recurrent module: ``observation`` (and its state, ``is_init``) → ``features`` of ``state_size``."""
    keys = state_keys(cell)
    module = GRUModule if cell == "gru" else LSTMModule
    return module(
        input_size=observation_size,
        hidden_size=state_size,
        num_layers=layers,
        in_keys=["observation", *keys, "is_init"],
        out_keys=[FEATURES, *(("next", key) for key in keys)],
    )


def make_recurrent_actor(
    cell: str, observation_size: int, state_size: int, layers: int, head: TensorDictModule
) -> TensorDictSequential:
    """The actor: :func:`make_memory`, then ``head`` (an MLP actor on ``state_size`` inputs) reading its features."""
    head = TensorDictModule(head.module, in_keys=[FEATURES], out_keys=["action"])
    return TensorDictSequential(make_memory(cell, observation_size, state_size, layers), head)


def is_recurrent(module: nn.Module) -> bool:
    """Whether ``module`` holds a recurrent module (its actions depend on the steps before)."""
    return any(isinstance(m, GRUModule | LSTMModule) for m in module.modules())


def state_primer(cell: str, state_size: int, layers: int) -> TensorDictPrimer:
    """The environment's transform that declares the recurrent state (zeros at every reset), as
    ``make_tensordict_primer`` of the module :func:`make_memory` builds does."""
    spec = Unbounded(shape=(layers, state_size))
    return TensorDictPrimer({key: spec for key in state_keys(cell)}, expand_specs=True)


class StepMemory(TensorDictModuleBase):
    """A recurrent ``actor`` stepped on an environment that carries no recurrent state (an evaluation's): it keeps
    the state between calls, zero at the first (``is_init``), and runs the rows in blocks of ``rows``, the last
    padded, so that a link's actions do not depend on the links beside it (as
    :class:`waterair.agents.networks.RowBlocks` does for an MLP). One instance serves one rollout from its start:
    :func:`waterair.evaluation.rollouts.rollout_policies` makes a new one for each."""

    def __init__(self, actor: TensorDictModuleBase, rows: int = 64) -> None:
        super().__init__()
        self.actor, self.rows = actor, rows
        self.keys = [key for key in actor.in_keys if key not in ("observation", "is_init")]
        self.in_keys, self.out_keys = ["observation"], ["action"]
        self.state: list[torch.Tensor] | None = None

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        observation = tensordict.get("observation")
        count = observation.shape[0]
        if pad := (-count) % self.rows:
            observation = torch.cat([observation, observation.new_zeros(pad, observation.shape[-1])])
        first = self.state is None
        state = self.state or [None] * len(self.keys)
        actions, states = [], []
        for block, rows in enumerate(observation.split(self.rows)):
            is_init = torch.full((len(rows), 1), first, device=rows.device)
            step = TensorDict({"observation": rows, "is_init": is_init}, batch_size=[len(rows)])
            for key, value in zip(self.keys, state, strict=True):
                if value is not None:
                    step.set(key, value[block * self.rows : (block + 1) * self.rows])
            out = self.actor(step)
            actions.append(out.get("action"))
            states.append([out.get(("next", key)) for key in self.keys])
        self.state = [torch.cat(parts) for parts in zip(*states, strict=True)]
        tensordict.set("action", torch.cat(actions)[:count])
        return tensordict
