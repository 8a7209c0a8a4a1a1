"""Greedy rollouts of several policies side by side on the same seas: what every evaluation measures."""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import torch
from tensordict.nn import TensorDictModuleBase
from torchrl.envs.utils import ExplorationType, set_exploration_type

from waterair.agents.recurrent import StepMemory, is_recurrent
from waterair.envs.baselines import BASELINES
from waterair.envs.config import EnvConfig
from waterair.envs.controllers import CONTROLLERS
from waterair.envs.env import WaterAirEnv
from waterair.envs.prediction import PredictionBound

REFERENCES = {**BASELINES, PredictionBound.name: PredictionBound, **CONTROLLERS}
"""Everything ``baselines`` may name: the model-based baselines, the prediction bound and the classical
controllers."""
TRACE_KEYS = ("gain", "gain_upper_bound", "intensity", "path_valid")


def one_bound(runs: dict[str, dict[str, torch.Tensor]]) -> dict[str, dict[str, torch.Tensor]]:
    """``runs`` (label → traces ``[R, P, T]`` of the same seas) with one G_UB per step for all: the most any replica
    found, its search or a pointing that received more than the search (docs/model.md §4.5). Every ratio then shares
    its denominator, and no row depends on which policy ran first."""
    bound = torch.stack([t["gain_upper_bound"] for t in runs.values()]).amax(0)
    valid = torch.stack([t["path_valid"] for t in runs.values()]).any(0)
    return {label: {**t, "gain_upper_bound": bound, "path_valid": valid} for label, t in runs.items()}


class PolicySplit(TensorDictModuleBase):
    """K policies side by side: policy k acts on rows ``[k·size, (k+1)·size)`` of the batch."""

    out_keys = ["action"]

    def __init__(self, policies: Sequence[TensorDictModuleBase], size: int):
        super().__init__()
        self.policies = torch.nn.ModuleList(policies)
        self.size = size
        self.in_keys = list(dict.fromkeys(key for p in policies for key in p.in_keys))

    def forward(self, tensordict):
        actions = [
            policy(tensordict[k * self.size : (k + 1) * self.size].select(*policy.in_keys))["action"]
            for k, policy in enumerate(self.policies)
        ]
        tensordict.set("action", torch.cat(actions, dim=0))
        return tensordict


class JoinedPolicy(TensorDictModuleBase):
    """A learned ``policy`` acting in a group of policies whose step is its own but whose observation has more
    parts or frames and whose replicas may act and sense otherwise: it reads its own ``columns`` of the
    observation (:meth:`EnvConfig.columns_in`) and its replica acts as ``actions`` and senses as ``sensing`` say
    (``env.replica_actions``, ``env.replica_sensing``), which is what its own environment would have given and
    done."""

    def __init__(self, policy: TensorDictModuleBase, columns: Sequence[int], actions: dict, sensing: dict):
        super().__init__()
        self.policy, self.actions, self.sensing = policy, actions, sensing
        self.in_keys, self.out_keys = list(policy.in_keys), list(policy.out_keys)
        self.register_buffer("columns", torch.tensor(list(columns), dtype=torch.long))

    def forward(self, tensordict):
        view = tensordict.copy()  # the caller's observation stays whole
        view.set("observation", view.get("observation").index_select(-1, self.columns.to(view.device)))
        return self.policy(view)


class Sensed(NamedTuple):
    """A baseline or classical controller, by ``name``, in a replica that senses as ``sensing`` says (some of the
    sensing keys, ``env.replica_sensing``): the controllers with a learned policy's sensor beside those with the
    scenario's."""

    name: str
    sensing: dict


def reference_name(member) -> str | None:
    """The baseline or controller a group's member is (a name, or :class:`Sensed`), or None for a learned one."""
    return member if isinstance(member, str) else member.name if isinstance(member, Sensed) else None


KINEMATIC = ("tracking", "prediction_bound")
"""The kinematic references: they point where they command, whatever the ends' actuators (``env.actuated``)."""


def kinematic(config: EnvConfig, members) -> tuple | None:
    """``config``'s ways of acting per replica (``env.replica_actions``), a kinematic reference's not actuated where
    the ends have actuators or move (it points in the world, through neither the actuators nor an attitude)."""
    bypassed = config.actuator.moves or config.motion.moves
    if not bypassed or not any(reference_name(m) in KINEMATIC for _, m in members):
        return config.replica_actions
    ways = [dict(way) for way in config.replica_actions or [()] * len(members)]
    return tuple({**way, "actuated": False} if reference_name(m) in KINEMATIC else way
                 for way, (_, m) in zip(ways, members, strict=True))  # fmt: skip


def rollout_policies(env_config: EnvConfig, members, points, realisations: int, steps: int, seed: int) -> dict:
    """Traces ``[R, P, T]`` (CPU) per member ``(label, policy or baseline name)``, all on the same seas.

    The members run as replicas of one environment seeded with ``seed``, greedily (no exploration
    noise), over ``points`` (wind m/s, offset ratio, azimuth deg) × ``realisations`` links for
    ``steps`` steps (one episode: a recurrent policy's state starts at zero). The members read common sensor
    noise too (a link's, :mod:`waterair.envs.noise`), so that each scores the same alone and beside others.
    """
    links = len(points) * realisations
    winds, offsets, azimuths = zip(*points, strict=True)
    env = WaterAirEnv(
        env_config.replace(
            num_envs=links * len(members),
            replicas=len(members),
            replica_actions=kinematic(env_config, members),
            wind_values=winds,
            offset_values=offsets,
            offset_azimuth_values=azimuths,
            wind_direction_values=None,  # points fix the drone; the wind blows from env.sea.wind_direction_deg
            wind_range=None,
            offset_range=None,
            offset_azimuth_range=None,
            wind_direction_range=None,
            divergence_range=None,  # every link at the scenario's ω_D (optics.divergence), the link budget's
            divergence_values=None,
        )
    )
    configs = env.config.replica_configs()  # each replica's own sensing, for the controllers that read it
    policies = [
        REFERENCES[name].for_rollout(env, configs[k], steps)
        if (name := reference_name(policy))
        else StepMemory(policy)  # a recurrent policy's state, from zero at the rollout's start
        if is_recurrent(policy)
        else policy
        for k, (_, policy) in enumerate(members)
    ]
    env.set_seed(seed)
    with set_exploration_type(ExplorationType.DETERMINISTIC), torch.no_grad():
        rollout = env.rollout(steps, PolicySplit(policies, links), break_when_any_done=False)
    # row = k·links + r·P + p: policy k, realisation r, point p
    shape = (len(members), realisations, len(points), steps)
    traces = {key: rollout["next", key].cpu().reshape(shape) for key in TRACE_KEYS}
    reference = env.state.reference_gain.cpu().reshape(shape[:3])
    return {
        label: {**{key: value[k] for key, value in traces.items()}, "reference_gain": reference[k]}
        for k, (label, _) in enumerate(members)
    }
