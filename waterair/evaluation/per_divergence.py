"""A policy per beam divergence (docs/evaluation.md, "A policy per divergence").

A policy trained at one beam divergence ω_D corrects its base for the spot that divergence leaves on the
detector; at another it applies corrections that no longer fit. Learned policies that share a label and
were trained at different divergences are therefore one policy in a report: at each divergence an
evaluation runs (S5's, or the scenario's own elsewhere) the member trained nearest it acts, on a log scale
(a tie goes to the wider beam). Policies sharing a label otherwise (the same divergence, or one without a
training config) are told apart as ``label #2``, ``label #3``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from waterair.evaluation.policies import LearnedPolicy


def trained_divergence(policy: LearnedPolicy) -> float | None:
    """The ω_D (rad) ``policy`` was trained at; None without a training config that says."""
    if policy.config is None:
        return None
    value = policy.config.get("env", {}).get("optics", {}).get("divergence")
    return None if value is None else float(value)


def name_policies(policies: Sequence[LearnedPolicy], reserved: Sequence[str]) -> None:
    """Labels that say which policies are one: a label in ``reserved`` (a baseline's) becomes ``label (learned)``;
    policies sharing a label stay one policy when each was trained at its own divergence, else get ``#n``."""
    for policy in policies:
        if policy.label in reserved:
            policy.label = f"{policy.label} (learned)"
    for members in _by_label(policies).values():
        divergences = [trained_divergence(p) for p in members]
        if None not in divergences and len(set(divergences)) == len(divergences):
            continue
        for count, policy in enumerate(members[1:], start=2):
            policy.label = f"{policy.label} #{count}"


def serving(policies: Sequence[LearnedPolicy], divergence: float) -> list[LearnedPolicy]:
    """The policies that act at ``divergence`` (rad): every lone one, and of each label's members the one
    trained nearest on a log scale (a tie: the wider)."""
    chosen = []
    for members in _by_label(policies).values():
        if len(members) == 1:
            chosen += members
            continue

        def distance(p: LearnedPolicy) -> tuple[float, float]:
            trained = trained_divergence(p) or divergence
            return abs(math.log(trained / divergence)), -trained

        chosen.append(min(members, key=distance))
    return chosen


def labelled(policies: Sequence[LearnedPolicy], label: str) -> list[LearnedPolicy]:
    """The policies that act under ``label``, narrowest trained divergence first."""
    found = _by_label(policies).get(label, [])
    return sorted(found, key=lambda p: trained_divergence(p) or 0.0)


def _by_label(policies: Sequence[LearnedPolicy]) -> dict[str, list[LearnedPolicy]]:
    grouped: dict[str, list[LearnedPolicy]] = {}
    for policy in policies:
        grouped.setdefault(policy.label, []).append(policy)
    return grouped
