"""``make docs``: what restates the env's defaults, generated from the dataclasses that hold them.

The dataclasses (:class:`~waterair.envs.config.EnvConfig`, the physics objects it holds, the seas of
:data:`~waterair.physics.sea.SPECTRA` and the channels of :data:`~waterair.physics.channel.CHANNELS`) are the one
source of the env's defaults. This writes the files that state them again: conf/env/default.yaml (the env group
Hydra composes), each option of conf/env/spectrum and conf/env/channel (each sea's and channel's own keys), and
docs/reference/env.md (each key's unit, default, what the entry points and each preset set it to, and what it
allows, from :data:`~waterair.envs.keys.KEYS`; each channel's compile thresholds). The hand-written options
(conf/env/sea, observation, sensor) hold only what they change.

``python -m waterair.cli.reference`` writes them; ``--check`` writes nothing and exits 1 naming the stale files.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import textwrap
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from waterair.envs.config import EnvConfig
from waterair.envs.groups import PHYSICS, SHARED_SEA_KEYS, as_mapping
from waterair.envs.keys import KEYS
from waterair.envs.operating_point import FIXED
from waterair.physics.actuator import Actuator
from waterair.physics.channel import CHANNELS, Beacon, LinkGeometry, Transceiver
from waterair.physics.motion import Motion
from waterair.physics.sea import SPECTRA
from waterair.training.config import CONF_DIR
from waterair.training.keys import TRAINING_KEYS

ROOT = CONF_DIR.parent
REFERENCE = ROOT / "docs" / "reference" / "env.md"
TRAINING_REFERENCE = ROOT / "docs" / "reference" / "training.md"
DECIDED = {"device": "${device}", "seed": "${seed}", "compile_kernel": "auto"}
"""The env keys the entry points fill in (their own ``device`` and ``seed``) or decide (``auto``: compile when the
run's frames repay it) where the dataclass has a value for a config built by hand."""
PRESETS = ("sea", "spectrum", "channel", "observation", "sensor", "actuator", "motion")
"""The option groups under conf/env whose options the reference names where they set a key."""
HAND_WRITTEN = ("sea", "observation", "sensor", "actuator", "motion")
"""The option groups written by hand, each option holding only the keys it changes."""
PACKAGES = {"sea": "sea", "spectrum": "sea", "channel": "channel", "actuator": "actuator", "motion": "motion"}
"""Where a group's keys sit in the env group (the others: at its top)."""
WIDTH = 118
SOURCE = "waterair/envs/config.py and the physics objects it holds"


def _scalar(value) -> str:
    """``value`` as YAML writes it (a float keeps its point or exponent, so that it reads back a float)."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_scalar(each) for each in value) + "]"
    return repr(value) if isinstance(value, float) else str(value)


def _shown(value) -> str:
    """``value`` as the reference shows it: ``2e+04``, ``null``, ``[0.005, 0.1]``."""
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_shown(each) for each in value) + "]"
    return _scalar(value)


def _comment(text: str) -> list[str]:
    return ["# " + line for line in textwrap.wrap(" ".join(text.split()), WIDTH - 2)]


def _yaml(values: Mapping, prefix: str = "", indent: str = "") -> list[str]:
    """``values`` as YAML lines, each scalar with its unit (:data:`KEYS`) as a comment."""
    lines = []
    for key, value in values.items():
        if isinstance(value, Mapping):
            lines += [f"{indent}{key}:", *_yaml(value, f"{prefix}{key}.", indent + "  ")]
            continue
        lines.append(f"{indent}{key}: {_scalar(value)}" + _note(f"{prefix}{key}"))
    return lines


def _note(key: str) -> str:
    """A YAML line's comment: the key's unit and range (the part of :data:`KEYS`' text before its explanation, where
    short), and the operating-point key that sets it."""
    unit, allowed = KEYS[key]
    parts = [unit] if unit != "–" else []
    if len(allowed.split(": ")[0]) <= 40 and key not in ("sea.spectrum", "channel.name"):
        parts.append(allowed.split(": ")[0])
    parts += [f"env.{point} sets it" for point, held in FIXED.items() if ".".join(held) == key]
    return f"   # {'; '.join(parts)}" if parts else ""


def env_group() -> dict:
    """conf/env/default.yaml's keys: every EnvConfig key at its dataclass default but for the physics options'
    own keys (env/spectrum, env/channel add them) and :data:`DECIDED`; each operating-point key's group key takes
    its value where it is set (``sea.wind: ${or_else:${..wind},12.0}``)."""
    config, values = EnvConfig(), {}
    for field in dataclasses.fields(EnvConfig):
        value = getattr(config, field.name)
        if field.name == "channel":
            continue
        if field.name in PHYSICS:
            value = as_mapping(value)
            value = {key: value[key] for key in SHARED_SEA_KEYS} if field.name == "sea" else value
        values[field.name] = DECIDED.get(field.name, value)
    for point, (group, key) in FIXED.items():
        values[group][key] = f"${{or_else:${{..{point}}},{_scalar(values[group][key])}}}"
    return values


def option_keys(kind: type) -> dict:
    """A sea's or a channel's own keys at their defaults, with its name."""
    mapping = as_mapping(kind())
    own = [field.name for field in dataclasses.fields(kind) if field.name not in (*SHARED_SEA_KEYS, "flat")]
    return {key: mapping[key] for key in ("spectrum", "name") if key in mapping} | {key: mapping[key] for key in own}


def _file(package: str | None, about: str, values: Mapping, prefix: str) -> str:
    header = [f"# @package {package}"] if package else []
    note = "Generated by `make docs` from the dataclasses: edit them, then run make docs."
    return "\n".join([*header, *_comment(about), *_comment(note), *_yaml(values, prefix)]) + "\n"


def conf_files() -> dict[Path, str]:
    """The generated YAML files of conf/env, by path."""
    env = CONF_DIR / "env"
    about = ("The batched environment's keys at their defaults (waterair.envs.config.EnvConfig); docs/reference/env.md "
             "gives each key's unit and range, docs/environment.md what they do.")  # fmt: skip
    files = {env / "default.yaml": _file(None, about, env_group(), "")}
    for group, package, options in (("spectrum", "sea", SPECTRA), ("channel", "channel", CHANNELS)):
        for name, kind in options.items():
            about = f"env/{group}={name}: the own keys of {kind.__module__}.{kind.__qualname__} at their defaults."
            files[env / group / f"{name}.yaml"] = _file(f"env.{package}", about, option_keys(kind), f"{package}.")
    return files


def dataclass_default(key: str):
    """The default the dataclasses give ``key``: EnvConfig's, its default sea's, geometry's, optics', beacon's;
    for a key of another sea or channel only, the first of :data:`SPECTRA` or :data:`CHANNELS` that has it."""
    defaults = EnvConfig()
    if "." not in key:
        return getattr(defaults, key)
    group, name = key.split(".")
    holders = {"sea": [defaults.sea, *(kind() for kind in SPECTRA.values())], "geometry": [LinkGeometry()],
               "optics": [Transceiver()], "beacon": [Beacon()], "actuator": [Actuator()], "motion": [Motion()],
               "channel": [defaults.channel, *(kind() for kind in CHANNELS.values())]}  # fmt: skip
    return next(as_mapping(each)[name] for each in holders[group] if name in as_mapping(each))


def _flat(values: Mapping, prefix: str = "") -> dict:
    flat = {}
    for key, value in values.items():
        if isinstance(value, Mapping):
            flat |= _flat(value, f"{prefix}{key}.")
        else:
            flat[f"{prefix}{key}"] = value
    return flat


_COMPOSED: dict[tuple, dict] = {}
"""The compositions made since the generated YAMLs were last written (each takes a third of a second)."""


def _composed(config_name: str, overrides: list[str], node: str | None = "env") -> dict:
    """The ``node`` group (None: the whole config) ``config_name`` composes with ``overrides``, resolved, as flat
    key paths."""
    key = (str(CONF_DIR), config_name, node, *overrides)
    if key not in _COMPOSED:
        with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
            config = compose(config_name, overrides=overrides)
            _COMPOSED[key] = _flat(OmegaConf.to_container(config[node] if node else config, resolve=True))
    return _COMPOSED[key]


def _same(a, b) -> bool:
    return list(a) == list(b) if isinstance(a, list | tuple) and isinstance(b, list | tuple) else a == b


def _options(group: str) -> dict[str, dict]:
    """Each option of ``conf/env/<group>``: the keys its file names (with their package's prefix), at the values
    train.py composes with it."""
    options = {}
    for path in sorted((CONF_DIR / "env" / group).glob("*.yaml")):
        prefix = f"{PACKAGES[group]}." if group in PACKAGES else ""
        named = {prefix + key for key in _flat(OmegaConf.to_container(OmegaConf.load(path)))}
        composed = _composed("config", [f"env/{group}={path.stem}"])
        options[path.stem] = {key: composed[key] for key in sorted(named, key=list(KEYS).index)}
    return options


def settings() -> dict[str, list[str]]:
    """For each key, where conf/ sets it to another value than its default: ``train.py 64``,
    ``env/observation=beacon 1``; a preset's value as train.py composes it (its interpolations resolved)."""
    found: dict[str, list[str]] = {key: [] for key in KEYS}
    for entry, config_name in (("train.py", "config"), ("evaluate.py", "evaluate")):
        for key, value in _composed(config_name, []).items():
            if key in found and not _same(value, dataclass_default(key)):
                found[key].append(f"{entry} {_shown(value)}")
    for group in PRESETS:
        for option, values in _options(group).items():
            for key, value in values.items():
                if key not in ("sea.spectrum", "channel.name") and not _same(value, dataclass_default(key)):
                    found[key].append(f"`env/{group}={option}` {_shown(value)}")
    return found


def preset_tables() -> list[str]:
    """One table per hand-written option group: each option and the keys it sets (blank: the key's default)."""
    lines = []
    for group in HAND_WRITTEN:
        options = _options(group)
        keys = sorted({key for values in options.values() for key in values}, key=list(KEYS).index)
        lines += ["", f"`env/{group}=`", "", f"| option | {' | '.join(f'`{key}`' for key in keys)} |",
                  "|---" * (len(keys) + 1) + "|"]  # fmt: skip
        for option, values in options.items():
            cells = [_shown(values[key]) if key in values else "" for key in keys]
            lines.append(f"| `{option}` | {' | '.join(cells)} |")
    return lines


def _key_page(title: str, intro: str, keys: Mapping[str, tuple[str, str]], defaults: Mapping[str, str]) -> list[str]:
    """A reference page's start: ``title``, ``intro`` and the table of ``keys`` (key → unit, allowed) with each
    one's ``defaults`` cell."""
    lines = [
        f"# {title}",
        "",
        *textwrap.wrap(intro, WIDTH),
        "",
        "| key | unit | default | allowed |",
        "|---|---|---|---|",
    ]
    return lines + [f"| `{key}` | {unit} | {defaults[key]} | {allowed} |" for key, (unit, allowed) in keys.items()]


def _with_settings(default: str, where: list[str]) -> str:
    """A default cell: the default, then where conf/ sets the key otherwise, in brackets."""
    return default + (f" ({'; '.join(where)})" if where else "")


def reference() -> str:
    """docs/reference/env.md: the key table and the compile thresholds."""
    intro = (
        f"Generated by `make docs` from {SOURCE} (the defaults) and waterair/envs/keys.py (units and ranges): "
        "edit those, then run `make docs`; a test fails while this page is stale. After each default, in "
        "brackets, what train.py and evaluate.py compose and each preset option that sets the key otherwise. "
        'What the keys do: docs/environment.md, "Config keys".'
    )
    defaults = {key: _with_settings(_shown(dataclass_default(key)), where) for key, where in settings().items()}
    lines = _key_page("The `env` group's keys", intro, KEYS, defaults)
    lines += [
        "",
        "## Presets",
        "",
        "What each option of a hand-written group sets, as train.py composes it; a blank cell: the key's default "
        "(above).",
        *preset_tables(),
    ]
    lines += [
        "",
        "## Compile thresholds",
        "",
        *textwrap.wrap(
            'The frames from which `auto` compiles (docs/training.md, "Compiles that pay"): train.py\'s from the '
            "frames still to collect, evaluate.py's and the closing evaluation's from each group's frames, with "
            "torch's compile cache empty (cold) or holding the graphs (warm); each channel's `compile_frames` and "
            "`evaluation_frames` (waterair/physics/channel/registry.py).",
            WIDTH,
        ),
        "",
        "| channel | train.py, cold | train.py, warm | evaluation, cold | evaluation, warm |",
        "|---|---|---|---|---|",
    ]
    for name, kind in CHANNELS.items():
        train, evaluation = kind.compile_frames, kind.evaluation_frames
        lines.append(f"| `{name}` | {train['cold']:,} | {train['warm']:,} | {evaluation['cold']:,} | "
                     f"{evaluation['warm']:,} |")  # fmt: skip
    return "\n".join(lines) + "\n"


def training_reference() -> str:
    """docs/reference/training.md: train.py's keys (but the env group's), each with what train.py composes and what
    each agent, noise, buffer, receiver and background option and the paper preset set it to where that differs."""
    groups = ("agent", "noise", "buffer", "link/receiver", "link/background")
    variants = [f"{group}={path.stem}" for group in groups
                for path in sorted((CONF_DIR / group).glob("*.yaml"))] + ["+experiment=paper"]  # fmt: skip
    base = _composed("config", [], node=None)
    intro = (
        "Generated by `make docs` from conf/ (config.yaml and each group's options: the defaults) and "
        "waterair/training/keys.py (units and ranges): edit those, then run `make docs`; a test fails while this "
        "page is stale. Each default is what `python train.py` composes; after it, in brackets, each option that "
        "sets the key otherwise (a key with no default: only those options have it). What the keys do: "
        'docs/training.md, "Config keys"; the `env` group: docs/reference/env.md.'
    )
    defaults = {}
    for key in TRAINING_KEYS:
        where = [
            f"`{variant}` {_shown(values[key])}"
            for variant in variants
            if key in (values := _composed("config", [variant], node=None))
            and (key not in base or not _same(values[key], base[key]))
        ]
        defaults[key] = _with_settings(_shown(base[key]) if key in base else "–", where)
    return "\n".join(_key_page("train.py's keys", intro, TRAINING_KEYS, defaults)) + "\n"


def stale(write: bool, parts: Sequence[Callable[[], dict[Path, str]]] | None = None) -> list[Path]:
    """The generated files that differ from a fresh generation (written, where ``write``), of ``parts`` (each gives
    files by path; by default all: the YAMLs first, which the references' compositions read)."""
    changed = []
    default = (conf_files, lambda: {REFERENCE: reference()}, lambda: {TRAINING_REFERENCE: training_reference()})
    for files in parts or default:
        for path, text in files().items():
            if not path.exists() or path.read_text() != text:
                changed.append(path)
                if write:
                    path.parent.mkdir(parents=True, exist_ok=True)
                    path.write_text(text)
                    _COMPOSED.clear()
    return changed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m waterair.cli.reference", description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="write nothing; exit 1 naming the stale files")
    args = parser.parse_args(argv)
    changed = stale(write=not args.check)
    for path in changed:
        verb = "stale" if args.check else "wrote"
        print(f"{verb}: {path.relative_to(ROOT)}" + (" (run make docs)" if args.check else ""))
    return 1 if args.check and changed else 0


if __name__ == "__main__":
    sys.exit(main())
