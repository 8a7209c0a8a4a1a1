"""Checks a command line completely before Hydra or the program writes anything.

``train.py`` and ``evaluate.py`` call :func:`preflight` first. It composes the config exactly as
Hydra will (every job of a ``-m`` sweep), refuses keys the config does not have (``foo=1`` and
``+foo=1`` alike: a typo must not silently start a run), refuses removed keys (``~key``), and
runs the program's own validation. A sweep's launcher is checked too (:mod:`waterair.cli.launch`),
and a search's keys and space by its sweeper.
Any problem exits with status 1 and one line on stderr, before Hydra creates a run directory.
Adding a whole config group with ``+group=option`` stays allowed. A key of earlier releases (``env.fetch``,
``env.lattice_nodes``, ``env.channel=NAME``) is an error naming today's (:func:`check_renamed`).
"""

from __future__ import annotations

import re
import sys
from collections.abc import Callable, Sequence

from hydra import compose, initialize_config_dir
from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.errors import HydraException, InstantiationException
from hydra.utils import instantiate
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from waterair.cli.errors import CommandLineError
from waterair.cli.launch import check_launcher, runs_elsewhere
from waterair.envs.groups import RENAMED
from waterair.envs.operating_point import FIXED
from waterair.training.config import CONF_DIR, is_group_choice

PASS_THROUGH = {
    *("-h", "--help", "--hydra-help", "-i", "--info", "-c", "--cfg", "--version", "--shell-completion", "-sc"),
    *("-cn", "--config-name", "-cp", "--config-path", "-cd", "--config-dir", "--experimental-rerun"),
}
"""Hydra flags that print something and run nothing, or that choose another config: left to Hydra."""
MULTIRUN = {"-m", "--multirun"}
MAX_JOBS = 256
"""A sweep with more jobs is checked on its first MAX_JOBS jobs (every value still appears)."""
PLUGINS = {
    "hydra/launcher=submitit_slurm": "hydra-submitit-launcher",
    "hydra/launcher=submitit_local": "hydra-submitit-launcher",
    "hydra/launcher=joblib": "hydra-joblib-launcher",
    "hydra/sweeper=optuna": "optuna",
}
"""Hydra options that come with a package: the package to install when the option is missing."""


def preflight(config_name: str, argv: Sequence[str], check: Callable[[DictConfig, list[str]], None]) -> None:
    """Compose every job of ``argv`` and ``check(cfg, overrides)`` each, then a sweep's launcher; exit with
    one line on a problem. A job that a scheduler runs on other machines is checked as on a CPU here
    (``device=cuda`` is checked where it runs)."""
    if any(arg.split("=")[0] in PASS_THROUGH for arg in argv):
        return
    try:
        check_renamed(argv)
        hydra = sweep_config(config_name, argv) if any(arg in MULTIRUN for arg in argv) else None
        remote = hydra is not None and runs_elsewhere(hydra)
        search = hydra is not None and hydra.runtime.choices.get("hydra/sweeper") == "optuna"
        for overrides in jobs(argv, hydra, search):
            cfg = compose_checked(config_name, overrides)
            check(on_a_cpu(cfg) if remote else cfg, overrides)
        if hydra is not None:
            check_launcher(hydra)
            if search:
                check_search(hydra, argv)
    except (CommandLineError, ValueError) as error:
        sys.exit(f"error: {error}")
    except (OmegaConfBaseException, HydraException) as error:  # a key missing or of the wrong type
        sys.exit(f"error: {one_line(error)}")
    except TypeError as error:  # a scalar where a list belongs, or the like
        sys.exit(f"error: a config value has the wrong type ({error})")


OLD_KEY = re.compile(r"^[+~]*env\.(\w+)(?==|$)")


def check_renamed(argv: Sequence[str]) -> None:
    """Refuse a key of earlier releases with one line naming today's: ``env.fetch=1e4`` (``env.sea.fetch``),
    ``env.lattice_nodes=5`` (``env.channel.nodes``), ``env.channel=single_path`` (the group
    ``env/channel=single_path``). ``env.wind`` and ``env.divergence`` are today's keys again (the operating point,
    :data:`~waterair.envs.operating_point.FIXED`). docs/environment.md, "Renamed keys"."""
    for arg in argv:
        old = OLD_KEY.match(arg)
        if old is None:
            continue
        key, value = old.group(1), arg.partition("=")[2]
        if key in FIXED:  # an old name that is today's key again: the operating point
            continue
        if key == "channel":
            raise CommandLineError(f"{arg}: the channel is a config group now; write env/channel={value}")
        if key in RENAMED:
            raise CommandLineError(
                f"env.{key} is env.{RENAMED[key]} in this version ({arg} → env.{RENAMED[key]}={value})"
            )


def jobs(argv: Sequence[str], hydra: DictConfig | None = None, search: bool = False) -> list[list[str]]:
    """The override lists of every job ``argv`` starts: one, or each job of a ``-m`` sweep.

    A sweep's values come from the command line and from ``hydra.sweeper.params`` in ``hydra`` (the
    composed ``hydra`` node). A search (``search``: the Optuna sweeper) is checked at each of its
    values and at both ends of each interval, the other keys at their first value.
    """
    overrides = [arg for arg in argv if not arg.startswith("-")]
    if not any(arg in MULTIRUN for arg in argv):
        return [overrides]
    params = hydra.sweeper.get("params") if hydra is not None else None
    swept = [f"{key}={value}" for key, value in (params or {}).items()]
    try:
        parsed = OverridesParser.create().parse_overrides([*swept, *overrides])
    except HydraException as error:
        raise CommandLineError(one_line(error)) from None
    if not search:
        interval = next((o for o in parsed if o.is_sweep_override() and not o.is_discrete_sweep()), None)
        if interval is not None:
            raise CommandLineError(
                f"{interval.input_line}: only hydra/sweeper=optuna samples from an interval; a grid takes a,b,c "
                f"or range(start,stop,step)"
            )
        batches = BasicSweeper.split_arguments(parsed, None)
        return [job for batch in batches for job in batch][:MAX_JOBS]
    values = [(override.get_key_element(), _search_values(override)) for override in parsed]
    first = [f"{key}={choices[0]}" for key, choices in values]
    found = [first]
    for index, (key, choices) in enumerate(values):
        found += [[*first[:index], f"{key}={value}", *first[index + 1 :]] for value in choices[1:]]
    return found[:MAX_JOBS]


def sweep_config(config_name: str, argv: Sequence[str]) -> DictConfig:
    """The ``hydra`` node of a sweep's config: its launcher, its sweeper and their choices."""
    try:
        parsed = OverridesParser.create().parse_overrides([arg for arg in argv if not arg.startswith("-")])
    except HydraException as error:
        raise CommandLineError(one_line(error)) from None
    plain = [override.input_line for override in parsed if not override.is_sweep_override()]
    try:
        with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
            return compose(config_name=config_name, overrides=plain, return_hydra_config=True).hydra
    except (HydraException, OmegaConfBaseException) as error:
        raise CommandLineError(one_line(error)) from None


def check_search(hydra: DictConfig, argv: Sequence[str]) -> None:
    """A search's keys and space, checked by its sweeper as it is built and as it starts (``hydra/sweeper=optuna``)."""
    try:
        sweeper = instantiate(hydra.sweeper)
    except InstantiationException as error:  # the sweeper's own one-line ValueError, wrapped by Hydra
        raise error.__cause__ if isinstance(error.__cause__, ValueError) else error from None
    sweeper.space([arg for arg in argv if not arg.startswith("-")])


def on_a_cpu(cfg: DictConfig) -> DictConfig:
    """``cfg`` with ``device`` and ``env.device`` on the CPU: the checks a machine without the job's GPU can make."""
    devices = {"device": "cpu", "env": {"device": "cpu"}}
    return OmegaConf.merge(cfg, devices) if "cuda" in (cfg.device, cfg.env.device) else cfg


def _search_values(override) -> list[str]:
    """The values of one override of a search to check: itself, its choices, or an interval's ends."""
    if not override.is_sweep_override():
        return [override.get_value_element_as_str()]
    if override.is_discrete_sweep():
        return list(override.sweep_string_iterator())
    return [str(override.value().start), str(override.value().end)]


def compose_checked(config_name: str, overrides: Sequence[str]) -> DictConfig:
    """The config Hydra composes for ``overrides``, after checking it has exactly the known keys.

    The known keys are those of the same group choices without the other overrides: a key that
    only ``+key=value`` brings in is an error naming it, and so is removing one with ``~key``.
    """
    groups = [o for o in overrides if is_group_choice(o)]
    removal = next((o for o in overrides if o.startswith("~") and o not in groups), None)
    if removal:
        raise CommandLineError(f"{removal.split('=')[0]} removes a key; set a value instead")
    config = _compose(config_name, overrides)
    # Only '+key=value' and a mapping value ('key={...}') bring keys in (Hydra refuses an unknown 'key=value'):
    # the second compose, half a second, runs only for those.
    adding = [o for o in overrides if o not in groups and (o.startswith("+") or "{" in o)]
    added = sorted(_keys(config) - _keys(_compose(config_name, groups))) if adding else []
    if added:
        raise CommandLineError(
            f"{added[0]} is not a config key; keys cannot be added, with or without '+' (every key is in "
            f"docs/training.md and docs/evaluation.md)"
        )
    return config


def one_line(error: BaseException) -> str:
    """Hydra's or OmegaConf's multi-line message as one line, without the search-path dump."""
    text = str(error).split("\nConfig search path:")[0].split("\nSee https://")[0]
    missing = re.match(r"Could not override '([^']+)'", text)
    if missing and re.search(r"use \+[^=]+=\{", text):  # a mapping value on a node that has the key
        return (
            f"{missing.group(1)}={{...}} names a key {missing.group(1)} does not have (check the spelling; keys "
            f"cannot be added; every key is in docs/training.md)"
        )
    if missing and (owners := options_with(missing.group(1))):
        return (
            f"{missing.group(1)} is not a key of the chosen option; {', '.join(owners)} "
            f"{'has' if len(owners) == 1 else 'have'} it (choose one, or leave {missing.group(1)} out)"
        )
    if missing:
        return f"{missing.group(1)} is not a config key (check the spelling; every key is in docs/training.md)"
    option = re.search(r"Could not find '([^']+)/([^'/]+)'\s+Available options in '[^']+':\s+(.*)", text, re.S)
    if option:
        group, name, choices = option.group(1), option.group(2), ", ".join(option.group(3).split())
        if f"{group}={name}" in PLUGINS:
            package = PLUGINS[f"{group}={name}"]
            return f"{group}={name} needs the package {package}, not installed (.venv/bin/pip install {package})"
        return f"{group}={name} is not an option of {group}; choose one of {choices}"
    return " ".join(text.replace("\t", " ").split())


def options_with(key: str) -> list[str]:
    """The group options of conf/ that hold ``key`` (``reward.a``: ``reward=le``, ``reward=pointing``), at the package
    each option's ``# @package`` line names (its group's path by default)."""
    owners = []
    for path in sorted(CONF_DIR.glob("*/**/*.yaml")):
        group = path.parent.relative_to(CONF_DIR).as_posix()
        header = re.match(r"# @package (\S+)", path.read_text())
        package = header.group(1) if header else group.replace("/", ".")
        keys = _keys(OmegaConf.load(path))
        prefix = "" if package == "_global_" else f"{package}."
        if any(f"{prefix}{own}" == key for own in keys):
            owners.append(f"{group}={path.stem}")
    return owners


def _compose(config_name: str, overrides: Sequence[str]) -> DictConfig:
    try:
        with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
            return compose(config_name=config_name, overrides=list(overrides))
    except (HydraException, OmegaConfBaseException) as error:
        raise CommandLineError(one_line(error)) from None


def _keys(config: DictConfig) -> set[str]:
    """Every leaf and container path of ``config`` (``a.b.c``), without Hydra's own node."""
    plain = OmegaConf.to_container(config, resolve=False)
    found: set[str] = set()

    def walk(node, prefix: str) -> None:
        if isinstance(node, dict):
            for key, value in node.items():
                path = f"{prefix}{key}"
                found.add(path)
                walk(value, path + ".")

    walk({k: v for k, v in plain.items() if k != "hydra"}, "")
    return found
