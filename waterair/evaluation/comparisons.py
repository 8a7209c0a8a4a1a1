"""Each learned policy against its classical base, paired on the same seas (docs/evaluation.md, "Comparisons").

A learned policy's base is the baseline or classical controller its residual actions correct (``env.residual_base``),
sensing as the policy does where the controller senses: the competitor it has to beat. At every point both run on
the same seas, and :func:`~waterair.evaluation.metrics.paired_comparison` resamples those seas together for both.
"""

from __future__ import annotations

import math

from waterair.envs.controllers import CONTROLLERS
from waterair.evaluation.metrics import COMPARED, paired_comparison, verdict
from waterair.evaluation.rollouts import Sensed, reference_name
from waterair.evaluation.scenarios import SETTING_COLUMNS

TRACES = ("gain", "gain_upper_bound", "reference_gain", "path_valid")
"""What a comparison reads of each policy's traces ``[R, P, T]``."""
WHERE = ("scenario", "wind", "offset_ratio", "offset_azimuth_deg", "divergence", *SETTING_COLUMNS)
"""What names a point of an evaluation: its scenario, its coordinates, the beam divergence (rad) and S6's or S7's
setting of the ends (:data:`~waterair.evaluation.scenarios.SETTING_COLUMNS`)."""
COMPARISON_KEYS = (
    *WHERE,
    "policy",
    "base",
    *(f"{name}_{kind}{suffix}" for name in COMPARED for kind in ("diff", "ratio") for suffix in ("", "_lo", "_hi")),
    "rate_held",
    "base_rate_held",
    "rate_held_verdict",
)
"""The keys of every ``comparisons`` entry of metrics.json."""
HOLDS_NOTHING = 1.0e3
"""bit/s: a rate held in 99 % of steps below this is no link (no OOK receiver runs slower); where both policies'
held rates are below it their ratio is undefined, and the verdict says ``neither holds``."""


def base_labels(groups, learned) -> dict[str, str]:
    """Each learned policy's label → its base's label among the evaluation's ``groups`` (``[(config, [(label,
    member)])]``); ``learned``: ``(policy, env config, actor)``. A policy whose base is not evaluated has none."""
    found: dict[tuple, str] = {}
    for config, members in groups:
        for label, member in members:
            if (name := reference_name(member)) is not None:
                sensing = member.sensing if isinstance(member, Sensed) else config.sensing
                found.setdefault((name, tuple(sorted(sensing.items()))), label)
                found.setdefault((name, None), label)  # the first: in the scenario's sensing
    bases: dict[str, str] = {}
    for policy, env_config, _ in learned:
        name = env_config.residual_base
        sensed = found.get((name, tuple(sorted(env_config.sensing.items()))))
        base = sensed if name in CONTROLLERS else found.get((name, None))  # flat-sea Snell senses nothing
        if base is not None:
            bases.setdefault(policy.label, base)
    return bases


def comparison_rows(
    policies: list[dict], runs: dict, index: int, where: dict, held: dict[str, float], link, bootstrap
) -> list[dict]:
    """One row per learned policy of ``policies`` (the evaluation's entries) with a ``base``: at point ``index`` of
    ``runs`` (label → traces), ``where`` (scenario, the point's coordinates, divergence), both policies' rates held
    in 99 % of steps (``held``: label → bit/s, the point's rows') and the paired comparison. ``rate_held_verdict``
    says what the held rates' ratio interval allows (:func:`verdict`), or ``neither holds`` where both held rates
    are under :data:`HOLDS_NOTHING` (their ratio is then NaN, its interval too)."""
    rows = []
    settings = {"link": link, "level": bootstrap.level, "resamples": bootstrap.resamples, "seed": bootstrap.seed}
    for policy in policies:
        if policy["kind"] != "learned" or policy.get("base") is None:
            continue
        pair = [tuple(runs[label][key][:, index] for key in TRACES) for label in (policy["label"], policy["base"])]
        compared = paired_comparison(*pair, **settings)
        rates = {"rate_held": held[policy["label"]], "base_rate_held": held[policy["base"]]}
        if max(rates.values()) < HOLDS_NOTHING:
            compared |= dict.fromkeys(("rate_held_ratio", "rate_held_ratio_lo", "rate_held_ratio_hi"), math.nan)
            judged = "neither holds"
        else:
            judged = verdict(compared["rate_held_ratio_lo"], compared["rate_held_ratio_hi"], even=1.0)
        row = {**where, "policy": policy["label"], "base": policy["base"], **compared, **rates}
        rows.append(row | {"rate_held_verdict": judged})
    return rows
