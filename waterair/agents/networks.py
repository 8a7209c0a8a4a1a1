"""The actor and critic networks (TorchRL modules), built from their sizes and an activation name."""

from __future__ import annotations

from collections.abc import Sequence

from tensordict.nn import TensorDictModule
from torch import nn
from torchrl.modules import MLP, ValueOperator

ACTIVATIONS = {"relu": nn.ReLU, "tanh": nn.Tanh, "elu": nn.ELU}
"""Activation names accepted by ``actor.activation`` / ``critic.activation``."""


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
        output = [module for module in mlp.modules() if isinstance(module, nn.Linear)][-1]
        nn.init.zeros_(output.weight)
        nn.init.zeros_(output.bias)
    return TensorDictModule(nn.Sequential(mlp, nn.Tanh()), in_keys=["observation"], out_keys=["action"])


def make_critic(observation_size: int, action_size: int, hidden: Sequence[int], activation: str) -> ValueOperator:
    """Q(s, a): MLP on the concatenated ``observation`` and ``action``, on the CPU."""
    net = MLP(
        in_features=observation_size + action_size,
        out_features=1,
        num_cells=list(hidden),
        activation_class=ACTIVATIONS[activation],
    )
    return ValueOperator(net, in_keys=["observation", "action"])
