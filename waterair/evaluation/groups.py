"""Which policies of an evaluation run side by side in one batch, and how each acts there.

Policies that step alike run as replicas of one environment on identical seas (:mod:`waterair.evaluation.rollouts`):
the baselines and classical controllers in the scenario's interface, the controllers and the prediction bound once
more with each sensor a learned policy was trained with, and every learned policy whose step is the group's. A
replica may observe fewer parts or frames than the group, act another way (a residual on its base, its own range)
and sense another way (its latency, noise, saturation, thresholds): it reads its own columns, and acts and senses its
own way (``env.replica_actions``, ``env.replica_sensing``), as it would alone (:data:`SHARED_STEP`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from waterair.envs.config import ACTION_KEYS, OBSERVATION_EXTRAS, SENSOR_KEYS, EnvConfig
from waterair.envs.controllers import CONTROLLERS
from waterair.envs.prediction import PredictionBound
from waterair.evaluation.rollouts import REFERENCES, JoinedPolicy, Sensed, reference_name

SENSED = (*CONTROLLERS, PredictionBound.name)
"""The references that read the sensing: the classical controllers, and the prediction bound (its receiver's delay
is the reading's latency)."""


def policy_groups(base: EnvConfig, baselines: list[str], learned, together: bool = True) -> list[tuple]:
    """(env config, [(label, member)]) per distinct step; a member is a baseline's or controller's name, a
    :class:`Sensed` controller or a learned actor (:func:`joined`).

    Baselines and controllers use the scenario's environment with every observation part they read
    (``required_extras``). Where a learned policy senses differently from the scenario (its own
    training sensor), the classical controllers and the prediction bound (:data:`SENSED`) also run with
    that sensing, labelled with it, so that each policy has its classical competitor and its bound with the
    same sensing. ``together=False`` gives every policy its own group (own rollout): slower, less memory.
    """
    reference = reading(base, baselines)
    members = [(name, name) for name in baselines]
    sensed = [name for name in baselines if name in SENSED]
    labels: list[str] = []
    for sensing in dict.fromkeys(tuple(c.sensing.items()) for _, c, _ in learned):
        if sensed and dict(sensing) != reference.sensing:
            label = sensing_label(dict(sensing))
            labels.append(label)
            if labels.count(label) > 1:  # two sensor settings that read alike
                label = f"{label} #{labels.count(label)}"
            members += [(f"{name} ({label})", Sensed(name, dict(sensing))) for name in sensed]
    if not together:
        alone = [(reference.replace(**getattr(m, "sensing", {})), [(label, m)]) for label, m in members]
        return alone + [(c, [(p.label, a)]) for p, c, a in learned]
    groups: list[tuple[EnvConfig, list]] = [(reference, members)] if members else []
    for policy, env_config, actor in learned:
        index = next((i for i, (config, _) in enumerate(groups) if same_step(config, env_config)), None)
        if index is None:
            groups.append((env_config, [(policy.label, (actor, env_config))]))
            continue
        config, group = groups[index]
        extras = (*config.observation_extras, *env_config.observation_extras)
        wider = config.replace(
            observation_extras=tuple(e for e in OBSERVATION_EXTRAS if e in extras),  # the layout's own order
            frames=max(config.frames, env_config.frames),
        )
        groups[index] = (wider, [*group, (policy.label, (actor, env_config))])
    built = [(config, [(label, joined(config, member)) for label, member in group]) for config, group in groups]
    return [(side_by_side(config, group), group) for config, group in built]


SHARED_STEP = {"observation_extras": OBSERVATION_EXTRAS, "frames": 1}
SHARED_STEP |= {key: getattr(EnvConfig(), key) for key in (*ACTION_KEYS, *SENSOR_KEYS)}  # the defaults' values
"""Interface keys in which policies may differ and still run side by side in one group, each with a value any
configuration may take: the observation's parts and frames, chosen outside the step's graph
(:func:`waterair.envs.kernel.observation_columns`, :mod:`waterair.envs.frames`), and how actions turn into tilts
and how the links sense, per replica (``env.replica_actions``, ``env.replica_sensing``). The group observes the
union of the parts; each policy reads its own, acts and senses its own way (:class:`JoinedPolicy`): what it would
have read and done alone."""


def same_step(a: EnvConfig, b: EnvConfig) -> bool:
    """Whether policies on ``a`` and ``b`` can run side by side: alike but in :data:`SHARED_STEP`'s keys."""
    return a.replace(**SHARED_STEP) == b.replace(**SHARED_STEP)


def joined(group: EnvConfig, member):
    """A group's member as it acts: a baseline's name, a :class:`Sensed` controller, an actor on its own interface,
    or a learned actor that reads its own observation out of the group's and acts and senses its own way
    (:class:`JoinedPolicy`)."""
    if not isinstance(member, tuple) or isinstance(member, Sensed):
        return member
    actor, own = member
    columns = own.columns_in(group)
    actions, sensing = ({key: getattr(own, key) for key in keys if getattr(own, key) != getattr(group, key)}
                        for keys in (ACTION_KEYS, SENSOR_KEYS))  # fmt: skip
    if columns == list(range(group.observation_size)) and not actions and not sensing:
        return actor
    return JoinedPolicy(actor, columns, actions, sensing)


def side_by_side(config: EnvConfig, members) -> EnvConfig:
    """``config`` for ``members`` side by side, a replica each (rollouts set the links): each replica acting and
    sensing its member's way where a member does otherwise (``env.replica_actions``, ``env.replica_sensing``)."""
    ways = tuple(member.actions if isinstance(member, JoinedPolicy) else {} for _, member in members)
    sensing = tuple(
        {key: value for key, value in member.sensing.items() if getattr(config, key) != value}
        if isinstance(member, JoinedPolicy | Sensed)
        else {}
        for _, member in members
    )
    return config.replace(
        num_envs=len(members),
        replicas=len(members),
        replica_actions=ways if any(ways) else None,
        replica_sensing=sensing if any(sensing) else None,
    )


def reading(config: EnvConfig, names: Iterable[str]) -> EnvConfig:
    """``config`` with the observation parts the baselines and controllers ``names`` read (``required_extras``)
    after its own: the interface they run in."""
    required = (part for name in names for part in REFERENCES[name].required_extras)
    return config.replace(observation_extras=tuple(dict.fromkeys((*config.observation_extras, *required))))


def sensing_label(sensing: Mapping) -> str:
    """A short name of a sensor setting (``EnvConfig.sensing``), e.g. ``1-step latency, noisy``."""
    parts = [f"{sensing['latency_steps']}-step latency"] if sensing["latency_steps"] else []
    noisy = sensing["intensity_noise"] or sensing["intensity_noise_floor"] or sensing["spot_noise_rad"]
    parts += ["noisy"] if noisy else []
    parts += ["saturating"] if sensing["intensity_saturation"] is not None else []
    return ", ".join(parts) or "ideal"


def actor_of(member):
    """The learned actor of a group's member, or None for a baseline or controller."""
    if reference_name(member) is not None:
        return None
    return member.policy if isinstance(member, JoinedPolicy) else member
