"""S5, link rate against beam divergence (docs/evaluation.md, "S5"): each divergence's environment and link
budget, each policy's best divergence and what a learned policy gains there, and outage against transmit power.

A narrower beam puts more intensity on its axis (J_0/P_t = 2/(π ω_D'²), docs/model.md §9), which reaches
the receiver only if the pointing holds it there; the channel gain G is normalised by J_0, so
the received power P_r = T_f P_t (J_0/P_t) G A_det is what the divergences are compared on.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import torch

from waterair.envs.config import EnvConfig
from waterair.evaluation.metrics import scenario_metrics
from waterair.evaluation.scenarios import Scenario
from waterair.physics.link import LinkBudget

BASELINES_COMPARED = ("flat_snell", "aoa_tracker")
"""What a learned policy's best rate is compared with: flat-sea Snell and the quadrant tracker."""


def at_divergence(env: EnvConfig, divergence: float | None) -> EnvConfig:
    """``env`` with the beam divergence ω_D = ``divergence`` (rad); None keeps its own."""
    if divergence is None or divergence == env.optics.divergence:
        return env
    return env.replace(optics={"divergence": divergence})


def scenario_link(values: Mapping, scenario: Scenario, env: EnvConfig, divergence: float | None) -> LinkBudget:
    """The link budget of ``scenario`` at ``divergence``: the ``link`` group ``values`` with the scenario's own
    keys replaced, on ``env``'s optics at that divergence. An error in a key the scenario sets names
    ``scenarios.<name>.link.<key>``, any other ``link.<key>``."""
    own = dict(scenario.link)
    optics = env.optics if divergence is None else dataclasses.replace(env.optics, divergence=divergence)
    try:
        return LinkBudget.from_mapping({**values, **own}, optics=optics)
    except ValueError as error:
        message = str(error)
        if any(message.startswith(f"link.{key} ") for key in own):
            message = f"scenarios.{scenario.name}.{message}"
        raise ValueError(message) from None


def best_divergences(rows: list[dict], scenario: Scenario) -> list[dict]:
    """For every (wind, offset, policy) of ``scenario``: the divergence whose mean rate is highest.

    Each entry holds ``wind``, ``offset_ratio``, ``policy``, ``divergence`` (rad), and there ``rate``,
    ``rate_held``, ``rate_held_999``, ``received_power_dbm`` and ``outage``. A tie (every divergence at the
    receiver's top rate) goes to the widest beam, the one that forgives pointing most.
    """
    best: dict[tuple, dict] = {}
    for row in rows:
        if row["scenario"] != scenario.name:
            continue
        key = (row["wind"], row["offset_ratio"], row["policy"])
        held = best.get(key)
        better = held is None or (row["rate"], row["divergence"]) > (held["rate"], held["divergence"])
        if better:
            best[key] = row
    keys = ("rate", "rate_held", "rate_held_999", "received_power_dbm", "outage", "divergence")
    return [{"wind": w, "offset_ratio": o, "policy": p, **{k: row[k] for k in keys}} for (w, o, p), row in best.items()]


def learned_gains(best: list[dict], policies: list[dict]) -> list[dict]:
    """What each learned policy gains at its best divergence over flat-sea Snell and the quadrant tracker at theirs.

    ``policies`` are an evaluation's (label, kind, and for a baseline its name): every run of a baseline in
    :data:`BASELINES_COMPARED` is compared, the ones with a learned policy's own sensing among them. One entry
    per (wind, offset, learned policy, baseline label): ``db`` the difference of mean received power (dB),
    ``rate`` of mean rate (bit/s), ``rate_held`` of the rate held 99 % of the time (bit/s).
    """
    learned = [p["label"] for p in policies if p["kind"] == "learned"]
    compared = [p["label"] for p in policies if p.get("baseline") in BASELINES_COMPARED]
    index = {(b["wind"], b["offset_ratio"], b["policy"]): b for b in best}
    out = []
    for (wind, offset, policy), mine in index.items():
        if policy not in learned:
            continue
        for label in compared:
            other = index.get((wind, offset, label))
            if other is None:
                continue
            out.append(
                {
                    "wind": wind,
                    "offset_ratio": offset,
                    "policy": policy,
                    "baseline": label,
                    "db": mine["received_power_dbm"] - other["received_power_dbm"],
                    "rate": mine["rate"] - other["rate"],
                    "rate_held": mine["rate_held"] - other["rate_held"],
                }
            )
    return out


def outage_against_power(
    scenario: Scenario, traces: Mapping[str, Mapping[str, torch.Tensor]], link: LinkBudget, bootstrap
) -> list[dict]:
    """Outage (BER above the FEC limit) at every transmit power of ``scenario.power_sweep``, per policy and offset.

    ``traces`` (policy → ``gain``, ``gain_upper_bound``, ``reference_gain``, ``path_valid``, ``[R, P, T]``) are
    the scenario's rollouts at the sweep's divergence, ``link`` its budget there; only the power changes, so
    no rollout is repeated. Each entry: ``policy``, ``offset_ratio``, ``power_w``, ``outage`` with ``_lo`` /
    ``_hi`` bounds, and ``no_light`` (the share of steps with no light at all: the floor no power lifts).
    """
    sweep = scenario.power_sweep
    if sweep is None:
        return []
    out = []
    for index, (wind, offset, _) in enumerate(scenario.points):
        if wind != sweep.wind:
            continue
        for policy, t in traces.items():
            gain = t["gain"][:, index]
            no_light = (gain <= 0).double().mean().item()
            for power in sweep.powers:
                metrics = scenario_metrics(
                    gain,
                    t["gain_upper_bound"][:, index],
                    t["reference_gain"][:, index],
                    t["path_valid"][:, index],
                    link=dataclasses.replace(link, power_w=power),
                    level=bootstrap.level,
                    resamples=bootstrap.resamples,
                    seed=bootstrap.seed,
                )
                out.append(
                    {
                        "policy": policy,
                        "offset_ratio": offset,
                        "power_w": power,
                        **{k: metrics[k] for k in ("outage", "outage_lo", "outage_hi")},
                        "no_light": no_light,
                    }
                )
    return out
