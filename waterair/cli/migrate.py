"""Rewrite an earlier release's run config in this version's keys: ``python -m waterair.cli.migrate RUN [RUN ...]``.

RUN is a run directory (its ``config.yaml``) or a config file (a policy's ``NAME.yaml`` beside ``NAME.pt``).
Each file is rewritten in place, atomically, its original kept beside it as ``config.yaml.orig``; a config
already in this version's keys is left untouched. Afterwards ``resume=RUN`` and ``evaluate.py run=RUN`` work
as for any run. What changes, all in the ``env`` group (docs/environment.md, "Renamed keys"):

* the physics keys the first releases kept flat move into their groups (``env.wind`` → ``env.sea.wind``,
  ``env.offset_ratio`` → ``env.geometry.offset_ratio``, ``env.aperture_diameter`` →
  ``env.optics.aperture_diameter``); a flat sea key the run's sea does not have is dropped, as those
  releases ignored it (their configs list both seas' keys);
* the channel, a name beside flat settings until it became a group, becomes the group
  (``env.channel: full`` with ``env.lattice_nodes: 9`` → ``env.channel: {name: full, nodes: 9, span: 4.5}``),
  keeping only the chosen channel's own settings;
* a config that names no channel or no sea ran the defaults of its release: the paper's one path and
  JONSWAP sea, until the measured-slope sea and the full channel became the defaults; they are written out.
"""

from __future__ import annotations

import argparse
import dataclasses
import shutil
import sys
from collections.abc import Mapping
from pathlib import Path

from omegaconf import OmegaConf

from waterair.core.files import atomic_write_text
from waterair.envs.groups import RENAMED
from waterair.envs.operating_point import FIXED
from waterair.physics.channel import CHANNELS, SinglePathChannel
from waterair.physics.sea import SPECTRA

BEFORE_THE_OCEAN = {"channel": SinglePathChannel.name, "spectrum": "jonswap"}
"""The channel and sea of a saved config that names neither: the defaults until the measured-slope sea and the
full channel became them."""


def migrated_env(values: Mapping) -> dict:
    """An ``env`` group of any release in this version's keys (see the module's docstring)."""
    out = dict(values)
    channel = out.pop("channel", BEFORE_THE_OCEAN["channel"])
    sea = out.get("sea")
    if "spectrum" not in out and not (isinstance(sea, Mapping) and "spectrum" in sea):
        out["spectrum"] = BEFORE_THE_OCEAN["spectrum"]
    grouped = isinstance(channel, Mapping)  # this version's layout, where env.wind is the operating point's key
    flat = {key: out.pop(key) for key in list(out) if key in RENAMED and not (grouped and key in FIXED)}
    for key, value in flat.items():
        group, name = RENAMED[key].split(".")
        if group != "channel":
            out[group] = {**(out.get(group) or {}), name: value}
    if isinstance(out.get("sea"), Mapping):
        own = {"spectrum", *(field.name for field in dataclasses.fields(SPECTRA[out["sea"]["spectrum"]]))}
        out["sea"] = {key: value for key, value in out["sea"].items() if key in own}
    if grouped:
        out["channel"] = dict(channel)
    else:
        own = {field.name for field in dataclasses.fields(CHANNELS[channel])}
        settings = {
            RENAMED[key].split(".")[1]: value for key, value in flat.items() if RENAMED[key].startswith("channel.")
        }
        out["channel"] = {"name": channel, **{key: value for key, value in settings.items() if key in own}}
    return dict(sorted(out.items(), key=lambda item: _place(item[0], list(values))))


def _place(key: str, original: list[str]) -> int:
    """Where ``key`` of the rewritten group goes: where it, or the first old key moved into it, was."""
    places = [index for index, old in enumerate(original) if old == key or RENAMED.get(old, "").startswith(f"{key}.")]
    return min(places, default=len(original))


def migrate(path: str | Path) -> Path | None:
    """Rewrite the config of ``path`` (a run directory or a config file) in this version's keys; returns the
    file rewritten, or None where it was already current. Raises ``ValueError`` naming what is missing."""
    path = Path(path)
    config_path = path / "config.yaml" if path.is_dir() else path
    if not config_path.is_file():
        raise ValueError(f"{path} is neither a run directory with a config.yaml nor a config file")
    config = OmegaConf.to_container(OmegaConf.load(config_path), resolve=False)
    if not isinstance(config, dict) or not isinstance(config.get("env"), Mapping):
        raise ValueError(f"{config_path} has no env group: not a waterair run config")
    env = migrated_env(config["env"])
    if env == config["env"]:
        return None
    shutil.copyfile(config_path, config_path.with_name(config_path.name + ".orig"))
    atomic_write_text(config_path, OmegaConf.to_yaml({**config, "env": env}))
    return config_path


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m waterair.cli.migrate", description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", metavar="RUN", help="a run directory or a config file")
    args = parser.parse_args(argv)
    for run in args.runs:
        try:
            rewritten = migrate(run)
        except ValueError as error:
            sys.exit(f"error: {error}")
        done = f"rewritten (the original kept as {rewritten.name}.orig)" if rewritten else "already current"
        print(f"{run}: {done}")


if __name__ == "__main__":
    main()
