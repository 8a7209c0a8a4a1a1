"""The learned policies an evaluation compares: which files, what they are called, how they act.

A policy file or training checkpoint is read by :func:`waterair.agents.checkpoint.read_policy`;
here it gets a label and the training config found beside it, which says the environment
interface it expects (:data:`INTERFACE_KEYS`) and its network shape.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from omegaconf import DictConfig, ListConfig, OmegaConf

from waterair.agents.checkpoint import CheckpointError, PolicyFile, read_policy
from waterair.agents.per_end import PER_END
from waterair.envs.config import SENSOR_KEYS, EnvConfig
from waterair.envs.operating_point import FIXED

ASSETS = Path(__file__).resolve().parents[1] / "assets"
INTERFACE_KEYS = (
    "action_mode",
    "max_tilt_deg",
    "max_slew_deg_s",
    "residual_deg",
    "residual_beams",
    "residual_base",
    "observation_extras",
    "history_length",
    "frames",
    "max_steps",
    "dtype",
)
"""Environment keys a learned policy keeps from its own training config; the scenario sets the rest."""
TRAINED_ON = {f"{name}_range": home for name, home in FIXED.items()}
"""What the report says a learned policy was trained on: each per-link draw's range, else its one value."""
SHIPPED = {
    "default": (),
    "intensity": ("env/observation=intensity", "env/motion=static", "env/actuator=ideal", "env.offset_range=[0.0,0.5]"),
    "paper": ("+experiment=paper",),
}
"""The shipped policies in :data:`ASSETS` (``NAME.pt``, ``NAME.yaml``, ``NAME_metrics.json``), which
``python evaluate.py`` evaluates when given no run or checkpoint, and the ``train.py`` overrides
each was trained with (on defaults otherwise: ``default`` on the link at sea, its ends moving and slewing;
``intensity`` on the same sea and channel with both ends still, pointing where commanded, as before motion and
actuators, and offsets drawn to 50 %, as before the default's 70 %; ``paper`` on the paper's physics;
docs/results.md). ``default`` serves every beam divergence (it observes its link's); policies trained at one
divergence each may still share a label and act as one (:mod:`waterair.evaluation.per_divergence`)."""


def shipped_policy(name: str) -> Path:
    """The file of the shipped policy ``name`` (one of :data:`SHIPPED`)."""
    return ASSETS / f"{name}.pt"


@dataclass
class LearnedPolicy:
    """A trained actor with its label and the training config found next to its file (if any)."""

    label: str
    file: PolicyFile
    config: DictConfig | None

    @property
    def path(self) -> Path:
        return self.file.path

    def interface(self, scenario_env: Mapping, sensing: bool = True) -> dict:
        """The environment keys this policy was trained with (the scenario's where no config exists),
        with its training sensor (:data:`SENSOR_KEYS`) when ``sensing``."""
        source = OmegaConf.to_container(self.config.env, resolve=True) if self.config else scenario_env
        keys = INTERFACE_KEYS + (SENSOR_KEYS if sensing else ())
        return {key: source[key] for key in keys if key in source}

    def actor(self, actor_cfg: DictConfig, observation_size: int):
        """The actor network (CPU, eval mode): its training config's shape, else ``actor_cfg``'s."""
        network = self.config.actor if self.config else actor_cfg
        observation = None
        if network.get("name") == PER_END:  # the layout it splits: its training config's (a size alone cannot say)
            if self.config is None:
                raise CheckpointError(
                    f"checkpoint {self.path}: actor=per_end needs the config.yaml it was trained with"
                )
            env = OmegaConf.to_container(self.config.env, resolve=True)
            observation = EnvConfig.from_mapping({**env, "compile_kernel": False})  # a saved run's may read auto
        return self.file.actor(network, observation_size, observation)


def load_policy(path: str | Path, label: str | None = None) -> LearnedPolicy:
    """Read a policy file or training checkpoint and its config; raises :class:`CheckpointError`."""
    file = read_policy(path)
    config_path = find_config(file.path)
    config = OmegaConf.load(config_path) if config_path else None
    return LearnedPolicy(label=label or _default_label(file.path, config), file=file, config=config)


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
    """Checkpoint files named by ``run`` (run directories, or ``latest``) and ``checkpoint``; else the shipped ones."""
    sources = []
    for run in as_list(cfg.run):
        run_dir = latest_run(root) if run == "latest" else Path(run)
        if not run_dir.is_dir():
            raise CheckpointError(f"run = {run!r} is not a run directory")
        sources.append(run_dir / "checkpoints" / "last.pt")
    sources += [Path(p) for p in as_list(cfg.checkpoint)]
    return sources or [shipped_policy(name) for name in SHIPPED]


def latest_run(root: Path = Path(".")) -> Path:
    """The run under ``outputs/train`` whose checkpoint was written last (``run=latest``)."""
    checkpoints = sorted((root / "outputs" / "train").glob("*/*/checkpoints/last.pt"), key=lambda p: p.stat().st_mtime)
    if not checkpoints:
        raise CheckpointError(f"run = 'latest': no run with checkpoints/last.pt under {root / 'outputs' / 'train'}")
    return checkpoints[-1].parent.parent


def as_list(value) -> list[str]:
    """A config value that may be null, one item or a list, as a list of strings."""
    if value is None:
        return []
    if isinstance(value, ListConfig | list | tuple):
        return [str(v) for v in value]
    return [str(value)]


def _default_label(path: Path, config: DictConfig | None) -> str:
    agent = config.agent.name if config is not None and "agent" in config else "policy"
    if path.resolve().parent == ASSETS and path.stem in SHIPPED:
        return f"{agent} {path.stem}"
    run_dir = path.parent.parent if path.parent.name == "checkpoints" else path.parent
    return f"{agent} {run_dir.name}"


def trained_on(env: Mapping) -> dict:
    """``{key: value}`` of :data:`TRAINED_ON` in a training config's ``env`` section: the range where one is set
    (e.g. ``wind_range``), else the value it replaces (``sea.wind``); keys the config lacks are left out."""
    said = {}
    for draw, (group, key) in TRAINED_ON.items():
        if env.get(draw) is not None:
            said[draw] = env[draw]
        elif env.get(group, {}).get(key) is not None:
            said[f"{group}.{key}"] = env[group][key]
    return said
