"""Resuming a run: which run, what the command line may change, and whether anything is left to do.

``train.py resume=RUN_DIR`` continues ``RUN_DIR`` with the config it was started with. The command
line may raise ``total_frames`` (the run then collects up to the new count), switch the progress
bar and set ``threads`` (the speed on this machine, not the experiment); any other key that
differs from the run's is refused, naming it, so that a resumed run is never silently a different
experiment. A run that already has its frames is left as it is.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from hydra.core.override_parser.overrides_parser import OverridesParser
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from waterair.agents.checkpoint import load_state
from waterair.training.checkpoint import CHECKPOINT
from waterair.training.config import CONF_DIR, validate

FREE_KEYS = ("resume", "total_frames", "logger.progress_bar", "threads")
"""Keys a resume command may set (the bar only changes what the console shows, ``threads`` the speed on this
machine); ``hydra.*`` is free too."""


@dataclass
class ResumePlan:
    """The run to continue, its config (``total_frames`` possibly raised) and the frames it has."""

    run_dir: Path
    config: DictConfig
    frames_done: int

    @property
    def finished(self) -> bool:
        return self.frames_done >= self.config.total_frames


def plan_resume(cfg: DictConfig, overrides: list[str]) -> ResumePlan:
    """Check ``resume=`` and the other ``overrides`` against the run; raise one-line ``ValueError``s."""
    run_dir = Path(cfg.resume)
    if not run_dir.is_dir():
        raise ValueError(f"resume = {cfg.resume!r} does not exist; give a run directory (outputs/train/DATE/TIME)")
    if not (run_dir / "config.yaml").is_file():
        raise ValueError(f"resume = {cfg.resume!r} is not a waterair run directory (it has no config.yaml)")
    saved = OmegaConf.load(run_dir / "config.yaml")
    if not isinstance(OmegaConf.select(saved, "env.channel"), DictConfig):  # a name, or none: before the group
        raise ValueError(
            f"resume: {run_dir} was written by an earlier release; python -m waterair.cli.migrate {run_dir} "
            "rewrites its config in this version's keys, then resume it"
        )
    checkpoint = run_dir / CHECKPOINT
    frames_done = int(load_state(checkpoint)["frames"]) if checkpoint.exists() else 0
    for override in OverridesParser.create().parse_overrides(overrides):
        if override.key_or_group.split(".")[0].split("/")[0] in ("hydra", *FREE_KEYS):
            continue
        for key in _keys_set_by(override):
            new, old = _plain(OmegaConf.select(cfg, key)), _plain(OmegaConf.select(saved, key))
            if new != old:
                raise ValueError(
                    f"resume: {override.input_line} changes {key} (the run has {old!r}); a resumed run keeps its "
                    f"config, only total_frames may grow"
                )
    given = {o.split("=")[0].lstrip("+") for o in overrides}
    free = {"resume": str(run_dir)}
    if "total_frames" in given:
        if cfg.total_frames < saved.total_frames:
            raise ValueError(
                f"total_frames = {cfg.total_frames} is out of range on resume; allowed [{saved.total_frames}, inf) "
                f"(the run's own total; a resumed run can only grow)"
            )
        free["total_frames"] = cfg.total_frames
    if "logger.progress_bar" in given:
        free["logger"] = {"progress_bar": cfg.logger.progress_bar}
    if "threads" in given:
        free["threads"] = cfg.threads
    config = OmegaConf.merge(saved, free)
    try:
        validate(config)
    except OmegaConfBaseException as error:  # a key this version reads is missing: an older run
        raise ValueError(f"resume: {run_dir / 'config.yaml'} is not a config this version can run ({error})") from None
    return ResumePlan(run_dir=run_dir, config=config, frames_done=frames_done)


def _keys_set_by(override) -> list[str]:
    """The config keys an override sets: itself, or every key its group option file sets (at its ``@package``)."""
    if "/" not in override.key_or_group:
        return [override.key_or_group]
    path = CONF_DIR / override.key_or_group / f"{override.value()}.yaml"
    header = re.match(r"# @package (\S+)", path.read_text())
    package = header.group(1) if header else override.key_or_group.replace("/", ".")
    prefix = "" if package == "_global_" else f"{package}."
    return [f"{prefix}{key}" for key in OmegaConf.load(path) if key != "defaults"]


def _plain(value):
    return OmegaConf.to_container(value, resolve=True) if isinstance(value, DictConfig) else value
