"""Model-based alignment baselines as TensorDict policies (docs/environment.md, baselines).

Each policy reads what the environment writes into the tensordict (``tx_position``, ``rx_position``, the
calm-sea point ``flat_point`` and, for tracking, the last path's ``departure``/``arrival``) and writes
``action``, so it runs through exactly the same ``env.rollout`` as a learned agent. The upper
bound is not a policy: the environment reports ``gain_upper_bound`` every step.
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase

from waterair.envs.config import EnvConfig
from waterair.envs.env import WaterAirEnv
from waterair.physics.optics import unit_vector


class PointingPolicy(TensorDictModuleBase):
    """Base class: subclasses say where each end should point; this turns it into an action."""

    in_keys = ["tx_position", "rx_position", "flat_point", "divergence", "observation", "tilt", "pointed", "base_tilt"]
    out_keys = ["action"]
    name = "pointing"
    required_extras: tuple[str, ...] = ()
    """Observation parts (``env.observation_extras``) the policy reads besides the paper's eight."""

    def __init__(self, env: WaterAirEnv, config: EnvConfig | None = None):
        super().__init__()
        self.env = env
        self.config = config or env.config
        """The configuration of the replica it acts in (``EnvConfig.replica_configs``): its sensing."""

    @classmethod
    def for_rollout(cls, env: WaterAirEnv, config: EnvConfig, steps: int) -> PointingPolicy:
        """The policy acting in ``env`` as ``config`` (its replica's) says, for a rollout of ``steps`` from a reset:
        what the evaluation builds; a policy that prepares for the rollout's length overrides it."""
        return cls(env, config=config)

    def directions(self, tensordict: TensorDictBase) -> tuple[torch.Tensor, torch.Tensor]:
        """Unit transmitter (up) and receiver (down) pointing, each ``[B, 3]``."""
        raise NotImplementedError

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        tx_dir, rx_dir = self.directions(tensordict)
        # The present (commanded) tilts come with each row, so the policy acts correctly on a slice
        # of the batch, and in delta mode also when the sensors' pointing telemetry is late; in
        # residual mode each row's base controller tilts come with it too.
        base = tensordict.get("base_tilt", None)
        divergence = tensordict.get("divergence", None)
        action = self.env.action_for_pointing(tx_dir, rx_dir, tensordict.get("tilt"), base, divergence)
        tensordict.set("action", action)
        return tensordict


class NoAlignment(PointingPolicy):
    """Transmitter straight up, receiver straight down."""

    name = "no_alignment"

    def directions(self, tensordict):
        up = torch.zeros_like(tensordict.get("tx_position"))
        up[:, 2] = 1.0
        return up, -up


class StraightFacing(PointingPolicy):
    """Each end points at the other along the straight line, ignoring refraction (paper)."""

    name = "straight_facing"

    def directions(self, tensordict):
        line = unit_vector(tensordict.get("rx_position") - tensordict.get("tx_position"))
        return line, -line


class FlatSeaSnell(PointingPolicy):
    """Both ends along the refracted path of a calm sea: the mean refraction, no surface knowledge."""

    name = "flat_snell"

    def directions(self, tensordict):
        tx, rx = tensordict.get("tx_position"), tensordict.get("rx_position")
        point = tensordict.get("flat_point")  # the environment's, solved once a link at its reset
        return unit_vector(point - tx), unit_vector(point - rx)


class PreviousPathTracking(PointingPolicy):
    """Both ends along the path of the previous step (perfect sensing, one step of delay).

    A strong model-based competitor: it knows the exact path, 50 ms late. Falls back to the
    flat-sea path where the previous path was invalid.
    """

    in_keys = [*PointingPolicy.in_keys, "departure", "arrival", "path_valid"]
    name = "tracking"

    def directions(self, tensordict):
        flat_tx, flat_rx = FlatSeaSnell.directions(self, tensordict)
        valid = tensordict.get("path_valid").unsqueeze(-1)
        return (
            torch.where(valid, tensordict.get("departure"), flat_tx),
            torch.where(valid, -tensordict.get("arrival"), flat_rx),
        )


BASELINES = {cls.name: cls for cls in (NoAlignment, StraightFacing, FlatSeaSnell, PreviousPathTracking)}
"""Baseline policy classes by name."""
