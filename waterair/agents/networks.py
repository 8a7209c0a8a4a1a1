"""The actor and critic networks (TorchRL modules), built from their sizes and an activation name.

The deterministic actor is what a policy file holds; an on-policy agent explores with
:func:`make_gaussian_policy` around it, and learns with a state-value critic (:func:`make_value`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import torch
from tensordict.nn import TensorDictModule, TensorDictModuleBase, TensorDictSequential
from tensordict.nn.distributions.continuous import AddStateIndependentNormalScale
from torch import nn
from torchrl.data import Bounded
from torchrl.modules import MLP, ProbabilisticActor, TanhNormal, ValueOperator

from waterair.agents.per_end import PER_END, PerEnd, per_end_columns
from waterair.agents.recurrent import CELLS, make_recurrent_actor
from waterair.envs.config import EnvConfig

ACTIVATIONS = {"relu": nn.ReLU, "tanh": nn.Tanh, "elu": nn.ELU}
"""Activation names accepted by ``actor.activation`` / ``critic.activation``."""
ACTORS = ("mlp", *CELLS, PER_END)
"""The ``actor`` group's options (:func:`actor_for`)."""


def make_actor(
    observation_size: int, action_size: int, hidden: Sequence[int], activation: str, zero_output: bool = False
) -> TensorDictModule:
    """Deterministic actor: MLP(``observation``) → tanh → ``action`` in [-1, 1], on the CPU.

    ``zero_output`` starts the output layer at zero, so that every first action is 0: with residual
    actions, the base controller's pointing (the output layer still learns from the first update).
    """
    mlp = MLP(
        in_features=observation_size,
        out_features=action_size,
        num_cells=list(hidden),
        activation_class=ACTIVATIONS[activation],
    )
    if zero_output:
        _zero_last_layer(mlp)
    return TensorDictModule(nn.Sequential(mlp, nn.Tanh()), in_keys=["observation"], out_keys=["action"])


def _zero_last_layer(mlp: nn.Module) -> None:
    output = [module for module in mlp.modules() if isinstance(module, nn.Linear)][-1]
    nn.init.zeros_(output.weight)
    nn.init.zeros_(output.bias)


def actor_for(
    network: Mapping, observation_size: int, action_size: int, observation: EnvConfig | None = None
) -> TensorDictModuleBase:
    """The actor of an ``actor`` group's option: ``mlp`` (:func:`make_actor`); ``gru``/``lstm``, a recurrent module
    of ``state_size`` × ``layers`` with that MLP on its features (:mod:`waterair.agents.recurrent`); ``per_end``, an
    agent per end (TorchRL's ``MultiAgentMLP``) on its own columns of ``observation``'s layout
    (:mod:`waterair.agents.per_end`)."""
    zero_output, name = bool(network.get("zero_output", False)), network.get("name", "mlp")  # older configs: mlp
    hidden, activation = network["hidden"], network["activation"]
    if name == PER_END:
        if observation is None:
            raise ValueError("actor=per_end needs the environment config whose observation it splits")
        columns = per_end_columns(observation.observation_layout, observation.frames, network["return_steps"])
        module = PerEnd(columns, hidden, ACTIVATIONS[activation])
        if zero_output:
            module.zero_output()
        return TensorDictModule(nn.Sequential(module, nn.Tanh()), in_keys=["observation"], out_keys=["action"])
    if name not in CELLS:
        return make_actor(observation_size, action_size, hidden, activation, zero_output)
    head = make_actor(network["state_size"], action_size, hidden, activation, zero_output)
    return make_recurrent_actor(name, observation_size, network["state_size"], network["layers"], head)


class RowBlocks(nn.Module):
    """``module`` applied to the rows of its input in blocks of ``rows``, the last padded with zeros: each row's
    output is then what it is in any other batch, on one machine. A matrix product's kernel, and so its rounding,
    depends on the row count (below about 16 rows CPU BLAS takes other paths: a row reads 1e-8 apart alone and in
    a batch); in blocks of one size every row is rounded alike, so that a scenario point evaluated alone gives
    what it gives inside a grid."""

    def __init__(self, module: nn.Module, rows: int = 64) -> None:
        super().__init__()
        self.module, self.rows = module, rows

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        flat = x.reshape(-1, x.shape[-1])
        count = flat.shape[0]
        if pad := (-count) % self.rows:
            flat = torch.cat([flat, flat.new_zeros(pad, flat.shape[1])])
        out = torch.cat([self.module(block) for block in flat.split(self.rows)])
        return out[:count].reshape(*x.shape[:-1], out.shape[-1])


def make_critic(observation_size: int, action_size: int, hidden: Sequence[int], activation: str) -> ValueOperator:
    """Q(s, a): MLP on the concatenated ``observation`` and ``action``, on the CPU."""
    net = MLP(
        in_features=observation_size + action_size,
        out_features=1,
        num_cells=list(hidden),
        activation_class=ACTIVATIONS[activation],
    )
    return ValueOperator(net, in_keys=["observation", "action"])


def make_gaussian_policy(actor: TensorDictModuleBase, action_spec: Bounded, scale: float) -> ProbabilisticActor:
    """The stochastic policy around ``actor``: action = tanh(u), u ~ N(MLP(observation), σ²).

    It shares the actor's MLP (a recurrent actor's memory too), so its deterministic action tanh(MLP(observation))
    is the actor's; σ is one learned scale per action component, independent of the state, starting at ``scale``
    (action units; :func:`learned_scale`). It writes the action's log-probability, which PPO's ratio needs.
    """
    *memory, last = actor if isinstance(actor, TensorDictSequential) else (actor,)
    mlp = last.module[0]
    size = action_spec.shape[-1]
    head = AddStateIndependentNormalScale(size, scale_mapping="exp", init_value=math.log(scale))
    module = TensorDictModule(nn.Sequential(mlp, head), in_keys=list(last.in_keys), out_keys=["loc", "scale"])
    if memory:
        module = TensorDictSequential(*memory, module)
    return ProbabilisticActor(
        module,
        spec=action_spec,
        in_keys=["loc", "scale"],
        distribution_class=TanhNormal,
        distribution_kwargs={"low": -1.0, "high": 1.0},
        return_log_prob=True,
    )


def learned_scale(policy: ProbabilisticActor) -> AddStateIndependentNormalScale:
    """The learned σ of a :func:`make_gaussian_policy` policy."""
    return next(m for m in policy.modules() if isinstance(m, AddStateIndependentNormalScale))


def make_value(observation_size: int, hidden: Sequence[int], activation: str) -> ValueOperator:
    """V(s): MLP on the ``observation`` (the state-value critic of an on-policy agent), on the CPU."""
    net = MLP(
        in_features=observation_size, out_features=1, num_cells=list(hidden), activation_class=ACTIVATIONS[activation]
    )
    return ValueOperator(net, in_keys=["observation"])
