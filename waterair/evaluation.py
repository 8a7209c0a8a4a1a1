"""Trained policies against the baselines and the upper bound on scenarios S1-S3 (SPEC §6-§7).

``evaluate.py`` is the Hydra entry point; :func:`evaluate` does the work and returns an
:class:`Evaluation` that :func:`write_outputs` turns into ``metrics.json``, ``metrics.csv``, the
figures and ``report.md``. Every policy of a scenario runs on the same seas: each rollout re-seeds
its environment with the scenario's seed, and a scenario's points run as one batch of
``points × realisations`` links (``env.wind_values`` / ``env.offset_values``).

``python -m waterair.evaluation export RUN_DIR OUT`` writes a policy-only file (the actor's
weights, its training config and final metrics) like the one shipped in ``waterair/assets``.
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import torch
from omegaconf import DictConfig, ListConfig, OmegaConf
from tensordict.nn import TensorDictModuleBase

from waterair._validation import check_choice, check_int, check_range
from waterair.baselines import BASELINES
from waterair.env import WaterAirEnv
from waterair.env_config import EnvConfig, resolve_device
from waterair.metrics import METRICS, scenario_metrics
from waterair.training import actor_module

ASSETS = Path(__file__).parent / "assets"
SHIPPED_POLICY = ASSETS / "default_policy.pt"
"""The default policy that ``python evaluate.py`` evaluates when given no run or checkpoint."""
POLICY_FORMAT = "waterair-policy/1"
UPPER_BOUND = "upper_bound"
INTERFACE_KEYS = (
    "action_mode",
    "max_tilt_deg",
    "max_slew_deg_s",
    "observation_extras",
    "history_length",
    "max_steps",
    "dtype",
)
"""Environment keys a learned policy keeps from its own training config; the scenario sets the rest."""
TRACE_KEYS = ("gain", "gain_upper_bound", "intensity", "path_valid")


class CheckpointError(ValueError):
    """A checkpoint that cannot be evaluated; the message is one line naming the file and the reason."""


# --- what is evaluated -------------------------------------------------------------------------


@dataclass
class LearnedPolicy:
    """A trained actor, loaded from a training checkpoint or a policy-only file."""

    label: str
    path: Path
    actor_state: dict[str, torch.Tensor]
    observation_size: int
    config: DictConfig | None  # the training config found next to the file, if any
    frames: int | None = None

    def interface(self, scenario_env: Mapping) -> dict:
        """The environment keys this policy was trained with (the scenario's where no config exists)."""
        source = OmegaConf.to_container(self.config.env, resolve=True) if self.config else scenario_env
        return {key: source[key] for key in INTERFACE_KEYS if key in source}

    def actor(self, actor_cfg, observation_size: int, device: torch.device):
        """The actor network with this policy's weights, after checking that it fits the environment."""
        if observation_size != self.observation_size:
            raise CheckpointError(
                f"checkpoint {self.path}: trained with observations of size {self.observation_size}, but the "
                f"evaluation environment gives {observation_size}; set env.observation_extras / "
                f"env.history_length as in training (or keep the run's config.yaml next to the checkpoint)"
            )
        network_cfg = self.config.actor if self.config else actor_cfg
        module = actor_module(network_cfg, observation_size, 4)
        try:
            module.load_state_dict(self.actor_state)
        except RuntimeError as error:
            reason = " ".join(str(error).split())[:300]
            raise CheckpointError(
                f"checkpoint {self.path}: its weights do not fit an actor with actor.hidden = "
                f"{list(network_cfg.hidden)} ({reason})"
            ) from None
        return module.to(device).eval()


@dataclass(frozen=True)
class Scenario:
    """One evaluation scenario: points (wind m/s, offset ratio), each over the same realisations."""

    name: str
    title: str
    axis: str | None  # the swept quantity ("offset_ratio" or "wind"); None for the S1 time trace
    points: tuple[tuple[float, float], ...]
    realisations: int
    steps: int
    seed: int


@dataclass
class Evaluation:
    """Everything an evaluation measured: one row per (scenario, point, policy), and the gain traces."""

    scenarios: list[Scenario]
    policies: list[dict]  # label, kind, and for learned policies source/frames/trained env
    rows: list[dict] = field(default_factory=list)
    traces: dict[str, dict[str, dict[str, torch.Tensor]]] = field(default_factory=dict)
    """scenario → policy → ``gain`` / ``gain_upper_bound`` traces ``[R, P, T]``."""
    env: EnvConfig = field(default_factory=EnvConfig)  # the scenario physics (sea, geometry, dt, device)
    seconds: float = 0.0

    @property
    def dt(self) -> float:
        return self.env.dt

    @property
    def device(self) -> str:
        return self.env.device

    def row(self, scenario: str, policy: str, wind: float, offset: float) -> dict:
        for row in self.rows:
            if (row["scenario"], row["policy"], row["wind"], row["offset_ratio"]) == (scenario, policy, wind, offset):
                return row
        raise KeyError((scenario, policy, wind, offset))


# --- loading -----------------------------------------------------------------------------------


def load_policy(path: str | Path, label: str | None = None) -> LearnedPolicy:
    """Load a training checkpoint (``checkpoints/last.pt``) or a policy file, with ``weights_only=True``.

    Raises :class:`CheckpointError` (one line, naming the file) when the file is missing, is not a
    torch file, or holds no actor weights.
    """
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"checkpoint {path} does not exist")
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as error:  # torch raises many types for a damaged or foreign file
        reason = " ".join(str(error).split())[:200]
        kind = type(error).__name__
        raise CheckpointError(f"checkpoint {path} is not a readable torch checkpoint ({kind}: {reason})") from None
    if not isinstance(state, dict) or ("actor" not in state and "loss" not in state):
        keys = sorted(state)[:8] if isinstance(state, dict) else type(state).__name__
        raise CheckpointError(f"checkpoint {path} holds no actor weights (found {keys}); is it a waterair checkpoint?")
    if "actor" in state:
        actor_state = state["actor"]
    else:
        prefix = "actor_network_params."
        actor_state = {k[len(prefix) :]: v for k, v in state["loss"].items() if k.startswith(prefix)}
    if not actor_state or "observation_size" not in state:
        raise CheckpointError(f"checkpoint {path} holds no actor weights or no observation_size")
    config_path = find_config(path)
    config = OmegaConf.load(config_path) if config_path else None
    frames = state.get("frames")
    return LearnedPolicy(
        label=label or _default_label(path, config),
        path=path,
        actor_state=actor_state,
        observation_size=int(state["observation_size"]),
        config=config,
        frames=int(frames) if frames is not None else None,
    )


def find_config(checkpoint: Path) -> Path | None:
    """The training config of a checkpoint: ``NAME.yaml`` beside a policy file, or the run's config.yaml."""
    for candidate in (
        checkpoint.with_suffix(".yaml"),
        checkpoint.parent / "config.yaml",
        checkpoint.parent.parent / "config.yaml",
    ):
        if candidate.is_file():
            return candidate
    return None


def checkpoint_sources(cfg: DictConfig, root: Path = Path(".")) -> list[Path]:
    """Checkpoint files named by ``run`` (run directories, or ``latest``) and ``checkpoint``; else the shipped one."""
    sources = []
    for run in _as_list(cfg.run):
        run_dir = latest_run(root) if run == "latest" else Path(run)
        if not run_dir.is_dir():
            raise CheckpointError(f"run = {run!r} is not a run directory")
        sources.append(run_dir / "checkpoints" / "last.pt")
    sources += [Path(p) for p in _as_list(cfg.checkpoint)]
    return sources or [SHIPPED_POLICY]


def latest_run(root: Path = Path(".")) -> Path:
    """The run under ``outputs/train`` whose checkpoint was written last (``run=latest``)."""
    checkpoints = sorted((root / "outputs" / "train").glob("*/*/checkpoints/last.pt"), key=lambda p: p.stat().st_mtime)
    if not checkpoints:
        raise CheckpointError(f"run = 'latest': no run with checkpoints/last.pt under {root / 'outputs' / 'train'}")
    return checkpoints[-1].parent.parent


def _default_label(path: Path, config: DictConfig | None) -> str:
    agent = config.agent.name if config is not None and "agent" in config else "policy"
    if path.resolve() == SHIPPED_POLICY.resolve():
        return f"{agent} (shipped)"
    run_dir = path.parent.parent if path.parent.name == "checkpoints" else path.parent
    return f"{agent} {run_dir.name}"


def _as_list(value) -> list:
    if value is None:
        return []
    if isinstance(value, ListConfig | list | tuple):
        return [str(v) for v in value]
    return [str(value)]


# --- scenarios ---------------------------------------------------------------------------------


def scenarios_from_config(cfg: DictConfig) -> list[Scenario]:
    """S1 (time trace), S2 (offset sweep) and S3 (wind sweep) from ``cfg.scenarios``; null skips one."""
    spec, out = cfg.scenarios, []

    def common(name):
        s = spec[name]
        return (
            check_int(f"scenarios.{name}.realisations", s.realisations, 1, 1 << 20),
            check_int(f"scenarios.{name}.steps", s.steps, 1, 10**7),
            check_int(f"scenarios.{name}.seed", s.seed, 0, 2**63 - 1),
        )

    if spec.get("S1") is not None:
        wind = check_range("scenarios.S1.wind", spec.S1.wind, 0.0, 60.0, low_open=True, unit="m/s")
        offset = check_range("scenarios.S1.offset_ratio", spec.S1.offset_ratio, 0.0, 10.0)
        title = f"S1: gain over time, U10 = {wind:g} m/s, offset {offset:.0%}"
        out.append(Scenario("S1", title, None, ((wind, offset),), *common("S1")))
    if spec.get("S2") is not None:
        wind = check_range("scenarios.S2.wind", spec.S2.wind, 0.0, 60.0, low_open=True, unit="m/s")
        offsets = _grid("scenarios.S2.offset_ratios", spec.S2.offset_ratios, 0.0, 10.0, "")
        title = f"S2: horizontal offset sweep, U10 = {wind:g} m/s"
        out.append(Scenario("S2", title, "offset_ratio", tuple((wind, o) for o in offsets), *common("S2")))
    if spec.get("S3") is not None:
        offset = check_range("scenarios.S3.offset_ratio", spec.S3.offset_ratio, 0.0, 10.0)
        winds = _grid("scenarios.S3.winds", spec.S3.winds, 0.0, 60.0, "m/s", low_open=True)
        title = f"S3: wind sweep, offset {offset:.0%}"
        out.append(Scenario("S3", title, "wind", tuple((w, offset) for w in winds), *common("S3")))
    if not out:
        raise ValueError("scenarios: every scenario is null; nothing to evaluate")
    return out


def _grid(key: str, values, low: float, high: float, unit: str, low_open: bool = False) -> tuple[float, ...]:
    values = list(values) if isinstance(values, ListConfig | list | tuple) else [values]
    if not values:
        raise ValueError(f"{key} = [] must list at least one value")
    return tuple(check_range(f"{key}[{i}]", v, low, high, low_open=low_open, unit=unit) for i, v in enumerate(values))


# --- running -----------------------------------------------------------------------------------


def evaluate(cfg: DictConfig, policies: Sequence[LearnedPolicy] | None = None, progress=print) -> Evaluation:
    """Run every policy, every baseline and the upper bound on every scenario of ``cfg``.

    ``policies`` defaults to the checkpoints ``cfg`` names. All checks (config values, checkpoint
    files, observation sizes) happen before the first rollout.
    """
    clock = time.perf_counter()
    scenarios = scenarios_from_config(cfg)
    check_choice("device", cfg.device, ("auto", "cpu", "cuda"))
    check_range("bootstrap.level", cfg.bootstrap.level, 0.0, 1.0, low_open=True, high_open=True)
    check_int("bootstrap.resamples", cfg.bootstrap.resamples, 10, 10**6)
    check_int("bootstrap.seed", cfg.bootstrap.seed, 0, 2**63 - 1)
    device = resolve_device(cfg.device)
    base = EnvConfig.from_mapping({**OmegaConf.to_container(cfg.env, resolve=True), "device": str(device)})
    scenario_env = {key: getattr(base, key) for key in INTERFACE_KEYS}
    unknown = [name for name in _as_list(cfg.baselines) if name not in BASELINES]
    if unknown:
        raise ValueError(f"baselines = {unknown[0]!r} is not a baseline; choose from {', '.join(BASELINES)}")
    if policies is None:
        labels = _as_list(cfg.get("labels"))
        sources = checkpoint_sources(cfg)
        if labels and len(labels) != len(sources):
            raise ValueError(f"labels has {len(labels)} entries for {len(sources)} checkpoints")
        policies = [load_policy(p, labels[i] if labels else None) for i, p in enumerate(sources)]
    _unique_labels(policies)

    # Per learned policy: its environment interface and its actor (checked now, before any rollout)
    learned = []
    for policy in policies:
        env_config = base.replace(**policy.interface(scenario_env))
        learned.append((policy, env_config, policy.actor(cfg.actor, env_config.observation_size, device)))
    for scenario in scenarios:
        for policy, env_config, _ in [(None, base, None), *learned]:
            if scenario.steps > env_config.max_steps:
                owner = f"{policy.label}'s" if policy else "the scenario's"
                raise ValueError(
                    f"scenarios.{scenario.name}.steps = {scenario.steps} is out of range; allowed [1, "
                    f"{env_config.max_steps}] ({owner} env.max_steps: a longer rollout would restart the seas)"
                )

    result = Evaluation(
        scenarios=scenarios,
        policies=[{"label": UPPER_BOUND, "kind": "bound"}]
        + [_describe(policy, base) for policy in policies]
        + [{"label": name, "kind": "baseline"} for name in _as_list(cfg.baselines)],
        env=base,
    )
    # Scenarios with the same realisations, steps and seed run as one batch over the union of their
    # points; within it, every group of policies sharing an interface runs as replicas of one env.
    groups = _policy_groups(base, _as_list(cfg.baselines), learned, together=cfg.get("batch_policies", True))
    for batch in _batches(scenarios):
        points = list(dict.fromkeys(p for s in batch for p in s.points))
        first = batch[0]
        runs = {}
        for env_config, members in groups:
            runs.update(_rollout_group(env_config, members, points, first.realisations, first.steps, first.seed))
            names = ", ".join(label for label, _ in members)
            progress(f"{'+'.join(s.name for s in batch)}: {names} done ({time.perf_counter() - clock:.0f} s)")
        for scenario in batch:
            index = torch.tensor([points.index(p) for p in scenario.points])
            selected = {label: {k: v[:, index] for k, v in t.items()} for label, t in runs.items()}
            _collect(result, scenario, selected, cfg)
    result.seconds = time.perf_counter() - clock
    return result


def _batches(scenarios: Sequence[Scenario]) -> list[list[Scenario]]:
    batches: dict[tuple[int, int, int], list[Scenario]] = {}
    for scenario in scenarios:
        batches.setdefault((scenario.realisations, scenario.steps, scenario.seed), []).append(scenario)
    return list(batches.values())


def _policy_groups(base: EnvConfig, baselines: list[str], learned, together: bool = True) -> list[tuple]:
    """(env config, [(label, policy or baseline name)]) per distinct interface; baselines use the scenario's.

    ``together=False`` gives every policy its own group (own rollout): slower, less memory.
    """
    if not together:
        return [(base, [(name, name)]) for name in baselines] + [(c, [(p.label, a)]) for p, c, a in learned]
    groups: list[tuple[EnvConfig, list]] = []
    if baselines:
        groups.append((base, [(name, name) for name in baselines]))
    for policy, env_config, actor in learned:
        match = next((members for config, members in groups if config == env_config), None)
        if match is None:
            groups.append((env_config, match := []))
        match.append((policy.label, actor))
    return groups


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


def _rollout_group(env_config: EnvConfig, members, points, realisations: int, steps: int, seed: int) -> dict:
    """Traces ``[R, P, T]`` (CPU) per member, all on the same seas (replicas of one env, seeded)."""
    from torchrl.envs.utils import ExplorationType, set_exploration_type

    links = len(points) * realisations
    winds, offsets = zip(*points, strict=True)
    env = WaterAirEnv(
        env_config.replace(
            num_envs=links * len(members),
            replicas=len(members),
            wind_values=winds,
            offset_values=offsets,
            wind_range=None,
            offset_range=None,
        )
    )
    policies = [BASELINES[policy](env) if isinstance(policy, str) else policy for _, policy in members]
    env.set_seed(seed)
    with set_exploration_type(ExplorationType.DETERMINISTIC), torch.no_grad():
        rollout = env.rollout(steps, PolicySplit(policies, links), break_when_any_done=False)
    # row = k·links + r·P + p: policy k, realisation r, point p
    shape = (len(members), realisations, len(points), steps)
    traces = {key: rollout["next", key].cpu().reshape(shape) for key in TRACE_KEYS}
    reference = env.reference_gain.cpu().reshape(shape[:3])
    return {
        label: {**{key: value[k] for key, value in traces.items()}, "reference_gain": reference[k]}
        for k, (label, _) in enumerate(members)
    }


def _collect(result: Evaluation, scenario: Scenario, runs: dict[str, dict], cfg: DictConfig) -> None:
    """Metrics rows for every point and policy (the upper bound first), and the S1 traces."""
    first = next(iter(runs.values()))
    runs = {UPPER_BOUND: {**first, "gain": first["gain_upper_bound"]}, **runs}
    order = [p["label"] for p in result.policies]
    for index, (wind, offset) in enumerate(scenario.points):
        for label in order:
            t = runs[label]
            metrics = scenario_metrics(
                t["gain"][:, index],
                t["gain_upper_bound"][:, index],
                t["reference_gain"][:, index],
                t["path_valid"][:, index],
                level=cfg.bootstrap.level,
                resamples=cfg.bootstrap.resamples,
                seed=cfg.bootstrap.seed,
            )
            result.rows.append(
                {
                    "scenario": scenario.name,
                    "wind": wind,
                    "offset_ratio": offset,
                    "policy": label,
                    "kind": next(p["kind"] for p in result.policies if p["label"] == label),
                    **metrics,
                    "reference_gain": t["reference_gain"][:, index].double().mean().item(),
                    "realisations": scenario.realisations,
                    "steps": scenario.steps,
                    "seed": scenario.seed,
                }
            )
    result.traces[scenario.name] = {
        label: {"gain": runs[label]["gain"], "gain_upper_bound": runs[label]["gain_upper_bound"]} for label in order
    }


def _describe(policy: LearnedPolicy, base: EnvConfig) -> dict:
    trained = OmegaConf.to_container(policy.config, resolve=True) if policy.config else {}
    env = trained.get("env", {})
    keys = ("wind", "fetch", "offset_ratio", "wind_range", "offset_range")
    differs = {k: v for k, v in env.items() if k in keys and v is not None}
    return {
        "label": policy.label,
        "kind": "learned",
        "source": _shown(policy.path),
        "frames": policy.frames,
        "agent": trained.get("agent", {}).get("name"),
        "trained_on": differs,
        "observation_size": policy.observation_size,
    }


def _shown(path: Path) -> str:
    """``path`` relative to the working directory when it lies inside it (reports stay portable)."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def _unique_labels(policies: Sequence[LearnedPolicy]) -> None:
    seen: dict[str, int] = {}
    for policy in policies:
        if policy.label in BASELINES or policy.label == UPPER_BOUND:
            policy.label = f"{policy.label} (learned)"
        count = seen.get(policy.label, 0)
        seen[policy.label] = count + 1
        if count:
            policy.label = f"{policy.label} #{count + 1}"


# --- outputs -----------------------------------------------------------------------------------

SCHEMA_VERSION = 1
ROW_KEYS = (
    "scenario",
    "wind",
    "offset_ratio",
    "policy",
    "kind",
    *(f"{name}{suffix}" for name in METRICS for suffix in ("", "_lo", "_hi")),
    "reference_gain",
    "realisations",
    "steps",
    "seed",
)
"""Columns of metrics.csv and the keys of every ``rows`` entry of metrics.json (docs/results.md)."""


def write_outputs(result: Evaluation, out: Path, cfg: DictConfig, physics: bool = True) -> list[Path]:
    """metrics.json, metrics.csv, every figure and report.md in ``out``; returns the files written."""
    from waterair import plots

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = [_write_json(result, out / "metrics.json", cfg), _write_csv(result, out / "metrics.csv")]
    figures = plots.evaluation_figures(result, out)
    if physics:
        from waterair.figures import physics_figures

        figures += physics_figures(out, result.env.sea())
    written += figures
    written.append(_write_report(result, out / "report.md", figures))
    return written


def _write_json(result: Evaluation, path: Path, cfg: DictConfig) -> Path:
    data = {
        "schema_version": SCHEMA_VERSION,
        "device": result.device,
        "seconds": round(result.seconds, 2),
        "bootstrap": OmegaConf.to_container(cfg.bootstrap, resolve=True),
        "policies": result.policies,
        "scenarios": [
            {
                "name": s.name,
                "title": s.title,
                "axis": s.axis,
                "points": [{"wind": w, "offset_ratio": o} for w, o in s.points],
                "realisations": s.realisations,
                "steps": s.steps,
                "seed": s.seed,
                "dt": result.dt,
            }
            for s in result.scenarios
        ],
        "rows": [{key: row[key] for key in ROW_KEYS} for row in result.rows],
    }
    return _atomic_text(path, json.dumps(data, indent=2, allow_nan=True))


def _write_csv(result: Evaluation, path: Path) -> Path:
    temporary = path.with_name(path.name + ".tmp")
    with temporary.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=ROW_KEYS, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(result.rows)
    temporary.replace(path)
    return path


def _write_report(result: Evaluation, path: Path, figures: list[Path]) -> Path:
    lines = ["# waterair evaluation", ""]
    lines += [f"Device {result.device}, {result.seconds:.0f} s. Policies:", ""]
    for policy in result.policies:
        if policy["kind"] == "learned":
            trained = ", ".join(f"{k} = {v}" for k, v in policy["trained_on"].items()) or "config not found"
            lines.append(f"- **{policy['label']}**: `{policy['source']}`, {policy['frames']} frames ({trained})")
    lines += [
        f"- baselines: {', '.join(p['label'] for p in result.policies if p['kind'] == 'baseline')}",
        f"- `{UPPER_BOUND}`: both ends along the exact current path (SPEC §6)",
        "",
        "Ratios are mean(G) / mean(G_UB); σ²_diff = var(G_UB − G) in m⁻⁴; outage is P(G < 0.1 G_0). Brackets "
        "are 95 % bootstrap intervals over sea realisations. σ²_diff alone rewards a policy that receives "
        "nothing (then it is var(G_UB)): read it next to the ratio.",
        "",
    ]
    for scenario in result.scenarios:
        lines += [f"## {scenario.title}", ""]
        seconds = scenario.steps * result.dt
        lines += [
            f"{scenario.realisations} sea realisations × {scenario.steps} steps ({seconds:g} s), "
            f"seed {scenario.seed}; every policy on the same seas.",
            "",
        ]
        if scenario.axis is None:
            wind, offset = scenario.points[0]
            lines += [
                "| policy | mean G (m⁻²) | ratio to UB | σ²_diff (m⁻⁴) | outage | valid paths |",
                "|---|---|---|---|---|---|",
            ]
            for policy in result.policies:
                r = result.row(scenario.name, policy["label"], wind, offset)
                lines.append(
                    f"| {policy['label']} | {r['mean_gain']:.4g} [{r['mean_gain_lo']:.4g}, {r['mean_gain_hi']:.4g}] "
                    f"| {r['ratio_to_ub']:.3f} | {r['sigma2_diff']:.3g} | {r['outage']:.2%} | {r['valid_share']:.1%} |"
                )
        else:
            column = "offset" if scenario.axis == "offset_ratio" else "U10 (m/s)"
            values = [o if scenario.axis == "offset_ratio" else w for w, o in scenario.points]
            labels = [p["label"] for p in result.policies]
            lines += ["Ratio to the upper bound (σ²_diff in m⁻⁴ below it):", ""]
            lines += [f"| {column} | " + " | ".join(labels) + " |", "|---" * (len(labels) + 1) + "|"]
            for (wind, offset), value in zip(scenario.points, values, strict=True):
                cells = []
                for label in labels:
                    r = result.row(scenario.name, label, wind, offset)
                    cells.append(f"{r['ratio_to_ub']:.3f}<br>{r['sigma2_diff']:.2g}")
                shown = f"{value:.0%}" if scenario.axis == "offset_ratio" else f"{value:g}"
                lines.append(f"| {shown} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += ["## Figures", ""]
    for figure in figures:
        lines += [f"![{figure.stem}]({figure.name})", ""]
    return _atomic_text(path, "\n".join(lines))


def _atomic_text(path: Path, text: str) -> Path:
    temporary = path.with_name(path.name + ".tmp")
    temporary.write_text(text)
    temporary.replace(path)
    return path


# --- exporting a policy ------------------------------------------------------------------------


def export_policy(run_dir: str | Path, out: str | Path) -> Path:
    """Write ``OUT.pt`` (actor weights only), ``OUT.yaml`` (training config), ``OUT_metrics.json`` from a run."""
    run_dir, out = Path(run_dir), Path(out)
    source = run_dir / "checkpoints" / "last.pt"
    policy = load_policy(source)
    out.parent.mkdir(parents=True, exist_ok=True)
    state = {
        "format": POLICY_FORMAT,
        "actor": {k: v.clone() for k, v in policy.actor_state.items()},
        "observation_size": policy.observation_size,
        "frames": policy.frames,
    }
    target = out.with_suffix(".pt")
    temporary = target.with_name(target.name + ".tmp")
    torch.save(state, temporary)
    temporary.replace(target)
    shutil.copyfile(run_dir / "config.yaml", out.with_suffix(".yaml"))
    if (run_dir / "final_metrics.json").exists():
        shutil.copyfile(run_dir / "final_metrics.json", out.with_name(out.stem + "_metrics.json"))
    return target


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="waterair policy tools")
    sub = parser.add_subparsers(dest="command", required=True)
    export = sub.add_parser("export", help="write a policy-only file from a run directory")
    export.add_argument("run_dir", type=Path)
    export.add_argument("out", type=Path, help="output path without suffix, e.g. waterair/assets/default_policy")
    args = parser.parse_args(argv)
    try:
        print(export_policy(args.run_dir, args.out))
    except CheckpointError as error:
        parser.exit(1, f"error: {error}\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
