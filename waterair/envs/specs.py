"""What the environment's TensorDicts hold, one link's worth: the TorchRL specs (docs/environment.md).

Derived from the observation's size and the float dtype, never typed twice: the entries of
:class:`Specs.observation` are the keys every step writes (:class:`waterair.envs.state.Measurement`, the
observation, the geometry and the tilts).
"""

from __future__ import annotations

from typing import NamedTuple

import torch
from torchrl.data import Bounded, Categorical, Composite, Unbounded


class Specs(NamedTuple):
    """The unbatched specs of one link: ``observation`` (every key a step writes beside the reward and the
    flags), ``action`` ``[4]`` in [-1, 1], ``reward`` ``[1]`` and ``done`` (done, terminated, truncated)."""

    observation: Composite
    action: Bounded
    reward: Unbounded
    done: Composite


def make_specs(observation_size: int, dtype: torch.dtype) -> Specs:
    """The specs of an environment whose observation has ``observation_size`` entries of ``dtype``."""

    def vector(size: int) -> Unbounded:
        return Unbounded(shape=(size,), dtype=dtype)

    scalar = Unbounded(shape=(), dtype=dtype)
    observation = Composite(
        observation=vector(observation_size),
        gain=scalar.clone(),
        gain_upper_bound=scalar.clone(),
        intensity=scalar.clone(),
        path_valid=Categorical(2, shape=(), dtype=torch.bool),
        alpha_d=scalar.clone(),
        alpha_a=scalar.clone(),
        departure=vector(3),
        arrival=vector(3),
        tx_position=vector(3),
        rx_position=vector(3),
        flat_point=vector(3),
        divergence=Unbounded(shape=(), dtype=torch.float64),
        tilt=vector(4),
        pointed=vector(4),
        base_tilt=vector(4),
    )
    flag = Categorical(2, shape=(1,), dtype=torch.bool)
    return Specs(
        observation=observation,
        action=Bounded(low=-1.0, high=1.0, shape=(4,), dtype=dtype),
        reward=Unbounded(shape=(1,), dtype=dtype),
        done=Composite(done=flag.clone(), terminated=flag.clone(), truncated=flag.clone()),
    )
