"""Checks of a sweep's launcher before anything is written (``train.py -m hydra/launcher=...``).

The submitit launchers need the submitit package. Slurm's needs ``sbatch``; its keys must be in
range (docs/training.md); the partition must be one of the cluster's (asked of ``sinfo`` when it is
on PATH); and the scheduler must accept the job that submitit would submit (``sbatch --test-only``
on the same script: memory, time limit, GPUs, account, QOS). Each problem is one line.
"""

from __future__ import annotations

import subprocess
import tempfile
from importlib.util import find_spec
from shutil import which

from hydra.utils import instantiate
from omegaconf import DictConfig, OmegaConf

from waterair.cli.errors import CommandLineError
from waterair.core.validation import check_int, check_range

SUBMITIT = ("submitit_slurm", "submitit_local")
REMOTE = ("submitit_slurm",)
"""Launchers whose jobs run on other machines than the one that checks them."""
TIMEOUT_S = 30
"""How long sinfo and sbatch --test-only may take before the cluster is taken as unreachable."""


def runs_elsewhere(hydra: DictConfig) -> bool:
    """Whether the sweep's jobs run on other machines (a scheduler's nodes)."""
    return hydra.runtime.choices.get("hydra/launcher") in REMOTE


def check_launcher(hydra: DictConfig) -> None:
    """Refuse, in one line, a launcher that cannot start the sweep's jobs (``hydra``: the composed ``hydra`` node)."""
    choice = hydra.runtime.choices.get("hydra/launcher")
    if choice not in SUBMITIT:
        return
    if find_spec("submitit") is None:
        raise CommandLineError(
            f"hydra/launcher={choice} needs the package submitit, which is not installed "
            f"(.venv/bin/pip install hydra-submitit-launcher)"
        )
    launcher = hydra.launcher
    check_int("hydra.launcher.timeout_min", launcher.timeout_min, 1)
    check_int("hydra.launcher.cpus_per_task", launcher.cpus_per_task, 1, 4096)
    if launcher.mem_gb is not None:
        check_range("hydra.launcher.mem_gb", launcher.mem_gb, 0.0, 1e6, low_open=True, unit="GB")
    if launcher.gpus_per_node is not None:
        check_int("hydra.launcher.gpus_per_node", launcher.gpus_per_node, 0, 64)
    if choice == "submitit_slurm":
        check_slurm(launcher)


def check_slurm(launcher: DictConfig) -> None:
    """The partition (asked of ``sinfo``), ``sbatch``, and the scheduler's answer to the job submitit would submit."""
    check_int("hydra.launcher.array_parallelism", launcher.array_parallelism, 1)
    if launcher.partition is not None and which("sinfo"):
        partitions = _ask("sinfo", "--noheader", "--format=%R")
        if launcher.partition not in partitions:
            raise CommandLineError(
                f"hydra.launcher.partition = {launcher.partition!r} is not a partition of this cluster; choose one "
                f"of {', '.join(partitions)}"
            )
    missing = [command for command in ("sbatch", "srun") if not which(command)]
    if missing:
        raise CommandLineError(
            f"hydra/launcher=submitit_slurm needs Slurm's {' and '.join(missing)} on PATH: start the sweep on a "
            f"machine that submits to the cluster"
        )
    with tempfile.TemporaryDirectory() as folder:
        params = OmegaConf.to_container(launcher, resolve=True)
        executor = instantiate({**params, "submitit_folder": folder}).executor(folder)
        # The script submitit would submit (a private helper of its executor: the exact #SBATCH lines).
        script = f"{folder}/test.sh"
        with open(script, "w") as handle:
            handle.write(executor._executor._make_submission_file_text("true", "preflight"))
        _ask("sbatch", "--test-only", script)


def _ask(*command: str) -> list[str]:
    """The lines a Slurm command prints; its last error line as a one-line error if it fails."""
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        raise CommandLineError(f"{command[0]} did not answer in {TIMEOUT_S} s: is the cluster reachable?") from None
    if done.returncode:
        lines = [line.strip() for line in (done.stderr + done.stdout).splitlines() if line.strip()] or ["no message"]
        raise CommandLineError(f"{' '.join(command[:2])} refused: {lines[-1]} (hydra.launcher.*, docs/training.md)")
    return [line.strip() for line in done.stdout.splitlines() if line.strip()]
