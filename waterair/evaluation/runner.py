"""Runs policies, baselines and the upper bound on the scenarios, every policy on the same seas.

:func:`evaluate` does the work of ``evaluate.py`` and returns an :class:`Evaluation` (rows of
metrics and the gain traces) that :mod:`waterair.evaluation.report` writes out. Each rollout seeds
its environment with the scenario's seed, a scenario's points run as one batch of
``points × realisations`` links (``env.wind_values`` / ``env.offset_values``), and the policies
whose step is the same run side by side as replicas of one environment with identical seas
(:mod:`waterair.evaluation.groups`). :func:`compare_policies` is the same measurement for one point, as training's
closing evaluation uses it.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import torch
from omegaconf import DictConfig, OmegaConf

from waterair.core.compiling import CHOICES as COMPILE_CHOICES
from waterair.core.devices import resolve_device
from waterair.core.threads import AUTO
from waterair.core.validation import check_choice, check_int, check_range
from waterair.envs.config import EnvConfig
from waterair.envs.link import link_budget
from waterair.envs.stepper import varying_environments
from waterair.evaluation.comparisons import base_labels, comparison_rows
from waterair.evaluation.compiling import compiled_group, note_compiled
from waterair.evaluation.divergence import at_divergence, outage_against_power, scenario_link
from waterair.evaluation.groups import actor_of, policy_groups, side_by_side
from waterair.evaluation.metrics import phase_metrics, scenario_metrics
from waterair.evaluation.per_divergence import labelled, name_policies, serving, trained_divergence
from waterair.evaluation.policies import (
    INTERFACE_KEYS,
    LearnedPolicy,
    as_list,
    checkpoint_sources,
    load_policy,
    trained_on,
)
from waterair.evaluation.rollouts import REFERENCES, one_bound, reference_name, rollout_policies
from waterair.evaluation.scenarios import SETTING_COLUMNS, Scenario, Setting, scenarios_from_config
from waterair.evaluation.workers import Batch, choose_workers, run_batches
from waterair.physics.link import LinkBudget

UPPER_BOUND = "upper_bound"
SENSING = ("trained", "scenario")
"""``sensing``: each learned policy with the sensor it was trained with, or every policy with the scenario's."""


@dataclass(frozen=True)
class Bootstrap:
    """Confidence intervals: a seeded percentile bootstrap over sea realisations."""

    level: float = 0.95
    resamples: int = 2000
    seed: int = 0

    def __post_init__(self) -> None:
        check_range("bootstrap.level", self.level, 0.0, 1.0, low_open=True, high_open=True)
        check_int("bootstrap.resamples", self.resamples, 10, 10**6)
        check_int("bootstrap.seed", self.seed, 0, 2**63 - 1)


@dataclass
class Evaluation:
    """Everything an evaluation measured: one row per (scenario, point, policy), and the gain traces."""

    scenarios: list[Scenario]
    policies: list[dict]  # label, kind, and for learned policies source/frames/trained env
    rows: list[dict] = field(default_factory=list)
    traces: dict[str, dict[str, dict[str, torch.Tensor]]] = field(default_factory=dict)
    """scenario → policy → ``gain`` / ``gain_upper_bound`` traces ``[R, P, T]``."""
    env: EnvConfig = field(default_factory=EnvConfig)  # the scenario physics (sea, geometry, dt, device)
    link: LinkBudget = field(default_factory=LinkBudget)  # what turns each step's gain into BER, outage, rate
    links: dict[tuple[str, float], LinkBudget] = field(default_factory=dict)
    """(scenario, divergence) → its link budget where it is not ``link`` (S5)."""
    power_rows: list[dict] = field(default_factory=list)  # S5's outage against transmit power
    comparisons: list[dict] = field(default_factory=list)  # each learned policy against its base, per point
    seconds: float = 0.0

    @property
    def dt(self) -> float:
        return self.env.dt

    @property
    def device(self) -> str:
        return self.env.device

    def row(self, scenario: str, policy: str, point: tuple[float, float, float], divergence: float | None = None):
        """The row of ``policy`` at ``point`` (wind, offset ratio, azimuth) of ``scenario`` (at ``divergence``, rad)."""
        for row in self.rows:
            if row["scenario"] == scenario and row["policy"] == policy and _point(row) == tuple(point):
                if divergence is None or row["divergence"] == divergence:
                    return row
        raise KeyError((scenario, policy, point, divergence))

    def scenario(self, name: str) -> Scenario:
        """The scenario named ``name``."""
        return next(scenario for scenario in self.scenarios if scenario.name == name)

    def link_of(self, scenario: str, divergence: float | None = None) -> LinkBudget:
        """The link budget ``scenario``'s rows were measured with (at ``divergence``)."""
        return self.links.get((scenario, divergence or self.env.optics.divergence), self.link)


def compare_policies(
    env_config: EnvConfig,
    policies: Mapping[str, object],
    scenario: Scenario,
    bootstrap: Bootstrap = Bootstrap(),
    link: LinkBudget | None = None,
    beside: Sequence[tuple[EnvConfig, Mapping[str, object]]] = (),
) -> dict[str, dict[str, float]]:
    """Metrics of ``policies`` (label → actor or baseline name) on the first point of ``scenario``, same seas.

    ``beside``: more ``(env config, policies)`` groups (another interface) on the same seas, measured alike.
    The upper bound is included as ``upper_bound``, one for all (:func:`one_bound`); the link metrics are of
    ``link`` (default: the default budget on ``env_config``'s channel).
    """
    link = link or link_budget(None, env_config)
    runs = {}
    for config, members in ((env_config, policies), *beside):
        with varying_environments():  # evaluate.py's graphs: a later evaluation loads its policy's from the cache
            runs |= rollout_policies(
                config, list(members.items()), scenario.points[:1], scenario.realisations, scenario.steps, scenario.seed
            )
        note_compiled(config)
    return {label: _point_metrics(t, 0, bootstrap, link, env_config.dt) for label, t in _bounded(runs).items()}


@dataclass
class EvaluationPlan:
    """Everything :func:`evaluate` checks before its first rollout, ready to run."""

    scenarios: list[Scenario]
    bootstrap: Bootstrap
    env: EnvConfig  # the scenario physics (sea, geometry, dt, device) and the baselines' interface
    link: LinkBudget
    baselines: list[str]
    policies: list[LearnedPolicy]
    learned: list[tuple]  # (policy, its env config, its actor on the device)
    batch_policies: bool
    groups: list[tuple] = field(default_factory=list)  # (env config, [(label, policy or baseline name)])
    links: dict[tuple[str, float], LinkBudget] = field(default_factory=dict)  # S5's, per divergence
    workers: int = 1  # processes running the batches (``workers``, :mod:`waterair.evaluation.workers`)
    threads: int = 1  # torch threads in each of them, where there are several
    processes: str = "1 process"  # a line saying how many of each and why
    compile_auto: bool = False  # env.compile_kernel: auto (S6's and S7's settings then run eager)


SCENARIO_SETS = {
    "wind": "scenarios.S1.wind, scenarios.S3.winds, scenarios.S5.winds",
    "offset": "scenarios.S1.offset_ratio, scenarios.S2.offset_ratios, scenarios.S5.offset_ratios",
    "offset_azimuth": "scenarios.S4.azimuths_deg",
}
"""The operating point's keys the scenarios' points replace, and the keys that set them instead (``env.wind_direction``
and ``env.divergence`` stay the scenarios': they keep the sea's direction and, but for S5, the optics' divergence)."""


def prepare(cfg: DictConfig, policies: Sequence[LearnedPolicy] | None = None) -> EvaluationPlan:
    """Check every config value, checkpoint file and observation size of ``cfg``; raise one-line errors.

    ``policies`` defaults to the checkpoints ``cfg`` names.
    """
    scenarios = scenarios_from_config(cfg)
    bootstrap = Bootstrap(**OmegaConf.to_container(cfg.bootstrap, resolve=True))
    resolve_device(cfg.device)
    values = OmegaConf.to_container(cfg.env, resolve=True)
    compile_kernel = str(values.get("compile_kernel", "auto")).lower()
    check_choice("env.compile_kernel", compile_kernel, COMPILE_CHOICES)
    base = EnvConfig.from_mapping({**values, "compile_kernel": compile_kernel == "true"})
    for name, scenario_key in SCENARIO_SETS.items():  # a key the scenarios would replace is not silently dropped
        if getattr(base, name) is not None:
            raise ValueError(f"env.{name} = {getattr(base, name):g} is not where evaluate.py takes its points; each "
                             f"scenario sets its own: {scenario_key} (docs/evaluation.md)")  # fmt: skip
    device = resolve_device(base.device, "env.device")
    base = base.replace(device=str(device))  # reports name the device that ran, not "auto"
    link_values = OmegaConf.to_container(cfg.link, resolve=True)
    link = link_budget(link_values, base)
    links = {(s.name, d): scenario_link(link_values, s, base, d) for s in scenarios for d in s.divergences}
    scenario_env = {key: getattr(base, key) for key in INTERFACE_KEYS}
    baselines = as_list(cfg.baselines)
    unknown = [name for name in baselines if name not in REFERENCES]
    if unknown:
        raise ValueError(f"baselines = {unknown[0]!r} is not a baseline; choose from {', '.join(REFERENCES)}")
    if policies is None:
        labels = as_list(cfg.get("labels"))
        sources = checkpoint_sources(cfg)
        if labels and len(labels) != len(sources):
            raise ValueError(f"labels has {len(labels)} entries for {len(sources)} checkpoints")
        policies = [load_policy(p, labels[i] if labels else None) for i, p in enumerate(sources)]
    name_policies(policies, (*REFERENCES, UPPER_BOUND))
    sensing = cfg.get("sensing", "trained")
    check_choice("sensing", sensing, SENSING)
    learned = []
    for policy in policies:
        env_config = base.replace(**policy.interface(scenario_env, sensing=sensing == "trained"))
        learned.append((policy, env_config, policy.actor(cfg.actor, env_config.observation_size).to(device)))
    for scenario in scenarios:
        for policy, env_config, _ in [(None, base, None), *learned]:
            for setting in scenario.settings or (None,):  # a setting's env is checked here too, before any rollout
                config = setting.applied(env_config) if setting else env_config
                steps = setting.steps if setting else scenario.steps
                if steps > config.max_steps:
                    owner = f"{policy.label}'s" if policy else "the scenario's"
                    raise ValueError(
                        f"scenarios.{scenario.name}.steps = {steps} is out of range; allowed [1, "
                        f"{config.max_steps}] ({owner} env.max_steps: a longer rollout would restart the seas)"
                    )
    together = bool(cfg.get("batch_policies", True))
    groups = policy_groups(base, baselines, learned, together)
    batches = len(_batches_at_divergences(scenarios))
    workers, threads, processes = choose_workers(cfg.get("workers", AUTO), batches, base.device)
    if compile_kernel == "auto":  # each group compiles when its frames repay its graphs (evaluation/compiling.py)
        per_policy = sum(len(s.points) * s.realisations * s.steps * max(1, len(s.divergences))
                         for s in scenarios if not s.settings)  # fmt: skip
        groups = [(compiled_group(config, len(members) * per_policy, workers)[0], members)
                  for config, members in groups]  # fmt: skip
    return EvaluationPlan(
        scenarios, bootstrap, base, link, baselines, list(policies), learned, together, groups, links,
        workers, threads, processes, compile_kernel == "auto",
    )  # fmt: skip


def evaluate(cfg: DictConfig, policies: Sequence[LearnedPolicy] | None = None, progress=print) -> Evaluation:
    """Run every policy, every baseline and the upper bound on every scenario of ``cfg``.

    Everything is checked (:func:`prepare`) before the first rollout. ``progress`` receives one
    line per finished rollout, with its own duration.
    """
    clock = time.perf_counter()
    plan = prepare(cfg, policies)
    result = Evaluation(
        scenarios=plan.scenarios,
        policies=[{"label": UPPER_BOUND, "kind": "bound"}]
        + [
            _describe(labelled(plan.policies, label), plan.env)
            for label in dict.fromkeys(p.label for p in plan.policies)
        ]
        + [
            {"label": label, "kind": "baseline", "baseline": reference_name(member)}
            for _, members in plan.groups
            for label, member in members
            if reference_name(member)
        ],
        env=plan.env,
        link=plan.link,
        links=plan.links,
    )
    bases = base_labels(plan.groups, plan.learned)
    for entry in result.policies:
        if entry["kind"] == "learned" and entry["label"] in bases:
            entry["base"] = bases[entry["label"]]
    progress(f"Evaluating in {plan.processes}")
    _run(plan, result, progress)
    result.seconds = time.perf_counter() - clock
    return result


def _run(plan: EvaluationPlan, result: Evaluation, progress) -> None:
    """Every scenario batch at each of its divergences, every policy group on it, into ``result``."""
    # Scenarios with the same realisations, steps and seed run as one batch over the union of their
    # points; within it, every group of policies sharing an interface runs as replicas of one env.
    # S6's and S7's settings each run as a batch of their own, eager where the compile is auto (a step each).
    batches, collected = [], []
    for scenarios, divergence, setting in _batches_at_divergences(plan.scenarios):
        points = list(dict.fromkeys(p for s in scenarios for p in s.points))
        first = scenarios[0]
        steps = setting.steps if setting else first.steps
        at = f" at {divergence * 1e3:g} mrad" if divergence is not None else ""
        names = "+".join(s.name for s in scenarios) + (f" {setting.name(plan.env)}" if setting else "")
        what = f"{names}{at} ({len(points)} points × {first.realisations} seas × {steps} steps)"
        groups = [
            (at_divergence(env_config, divergence), members)
            for env_config, members in _acting(plan, divergence or plan.env.optics.divergence)
        ]
        if setting is not None:  # eager where the compile is auto: a step of its own
            groups = [(setting.applied(config, eager=plan.compile_auto), members) for config, members in groups]
        batches.append(Batch(what, groups, points, first.realisations, steps, first.seed))
        collected.append((scenarios, points, divergence, setting))
    for runs, (scenarios, points, divergence, setting) in zip(
        run_batches(batches, plan.workers, plan.threads, progress), collected, strict=True
    ):
        for scenario in scenarios:
            index = torch.tensor([points.index(p) for p in scenario.points])
            selected = {label: {k: v[:, index] for k, v in t.items()} for label, t in runs.items()}
            _collect(result, scenario, selected, plan.bootstrap, (divergence, setting))


def _acting(plan: EvaluationPlan, divergence: float) -> list[tuple]:
    """``plan.groups`` with only the learned policies that act at ``divergence`` (a policy per divergence)."""
    acting = {id(p) for p in serving(plan.policies, divergence)}
    actors = {id(actor) for policy, _, actor in plan.learned if id(policy) in acting}
    groups = []
    for env_config, group in plan.groups:
        kept = [(label, member) for label, member in group if reference_name(member) or id(actor_of(member)) in actors]
        if kept:
            groups.append((side_by_side(env_config, kept), kept))
    return groups


def _batches_at_divergences(scenarios: Sequence[Scenario]) -> list[tuple[list[Scenario], float | None, Setting | None]]:
    """Each batch of :func:`_batches` at each of its divergences (S5: every point at each; else None, the env's)
    and each of its settings (S6, S7; else None)."""
    return [(batch, divergence, setting) for batch in _batches(scenarios)
            for divergence in batch[0].divergences or (None,) for setting in batch[0].settings or (None,)]  # fmt: skip


def _batches(scenarios: Sequence[Scenario]) -> list[list[Scenario]]:
    batches: dict[tuple, list[Scenario]] = {}
    for s in scenarios:
        batches.setdefault((s.realisations, s.steps, s.seed, s.divergences, s.settings), []).append(s)
    return list(batches.values())


def _collect(result: Evaluation, scenario: Scenario, runs: dict[str, dict], bootstrap: Bootstrap, at: tuple) -> None:
    """Metrics rows for every point and policy (the upper bound first) ``at`` a divergence and a setting (None:
    the env's), and the traces.

    S5 keeps the traces at its power sweep's divergence only, and measures that sweep from them; S6 and S7 keep none.
    """
    divergence, setting = at
    runs = _bounded(runs)
    kinds = {p["label"]: p["kind"] for p in result.policies}
    divergence = result.env.optics.divergence if divergence is None else divergence
    link = result.link_of(scenario.name, divergence)
    columns = setting.columns(result.env) if setting else dict.fromkeys(SETTING_COLUMNS)
    dt = columns["dt"] or result.dt
    for index, (wind, offset, azimuth) in enumerate(scenario.points):
        for label in kinds:
            t = runs[label]
            result.rows.append(
                {
                    "scenario": scenario.name,
                    "wind": wind,
                    "offset_ratio": offset,
                    "offset_azimuth_deg": azimuth,
                    "divergence": divergence,
                    **columns,
                    "policy": label,
                    "kind": kinds[label],
                    **_point_metrics(t, index, bootstrap, link, dt),
                    "reference_gain": t["reference_gain"][:, index].double().mean().item(),
                    "realisations": scenario.realisations,
                    "steps": scenario.steps,
                    "seed": scenario.seed,
                }
            )
        where = {"scenario": scenario.name, "wind": wind, "offset_ratio": offset, "offset_azimuth_deg": azimuth}
        where |= {"divergence": divergence, **columns}
        held = {row["policy"]: row["rate_held"] for row in result.rows[-len(kinds) :]}
        result.comparisons += comparison_rows(result.policies, runs, index, where, held, link, bootstrap)
    sweep = scenario.power_sweep
    if scenario.divergences and (sweep is None or not math.isclose(sweep.divergence, divergence)):
        return  # S5 but at its power sweep's divergence; S6, S7
    result.traces[scenario.name] = {
        label: {"gain": runs[label]["gain"], "gain_upper_bound": runs[label]["gain_upper_bound"]} for label in kinds
    }
    if sweep is not None:
        result.power_rows += outage_against_power(scenario, {label: runs[label] for label in kinds}, link, bootstrap)


def _bounded(runs: dict[str, dict]) -> dict[str, dict]:
    """``runs`` under one bound (:func:`one_bound`), the bound first as a policy of its own whose gain is the bound."""
    runs = one_bound(runs)
    first = next(iter(runs.values()))
    return {UPPER_BOUND: {**first, "gain": first["gain_upper_bound"]}, **runs}


def _point_metrics(
    traces: dict[str, torch.Tensor], index: int, bootstrap: Bootstrap, link: LinkBudget, dt: float
) -> dict:
    """Every metric of point ``index`` of one policy's traces ``[R, P, T]`` (steps of ``dt`` s), the link's of
    ``link``: over all steps, and of the acquisition and the tracking apart (:func:`phase_metrics`)."""
    point = tuple(traces[key][:, index] for key in ("gain", "gain_upper_bound", "reference_gain", "path_valid"))
    settings = {"link": link, "level": bootstrap.level, "resamples": bootstrap.resamples, "seed": bootstrap.seed}
    return {**scenario_metrics(*point, **settings), **phase_metrics(*point, dt, **settings)}


def _describe(policies: Sequence[LearnedPolicy], base: EnvConfig) -> dict:
    """The report's entry of one label: the policy acting at ``base``'s divergence, and each member's
    divergence, file and frames where there are several (a policy per divergence)."""
    policy = serving(policies, base.optics.divergence)[0]
    trained = OmegaConf.to_container(policy.config, resolve=True) if policy.config else {}
    entry = {
        "label": policy.label,
        "kind": "learned",
        "source": _shown(policy.path),
        "frames": policy.file.frames,
        "agent": trained.get("agent", {}).get("name"),
        "trained_on": trained_on(trained.get("env", {})),
        "observation_size": policy.file.observation_size,
    }
    if len(policies) > 1:
        entry["per_divergence"] = [
            {"divergence": trained_divergence(p), "source": _shown(p.path), "frames": p.file.frames} for p in policies
        ]
    return entry


def _shown(path: Path) -> str:
    """``path`` relative to the working directory when it lies inside it (reports stay portable)."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def _point(row: dict) -> tuple[float, float, float]:
    return row["wind"], row["offset_ratio"], row["offset_azimuth_deg"]
