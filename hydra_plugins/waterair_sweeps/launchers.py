"""The submitit launchers of ``train.py -m`` (``hydra/launcher=submitit_slurm``, ``submitit_local``).

They are hydra-submitit-launcher's, with three changes:

- defaults for a training job (:class:`SlurmConf`): CPUs, memory and time limit, a GPU when
  ``device=cuda``, torch's threads set to the job's CPUs, and, on Slurm, one torch compile cache
  for the whole sweep under its root, so that jobs started after the first compiles reuse them
  whichever node they run on;
- every job is waited for: a job that raised, or that the scheduler cancelled, timed out or killed,
  comes back as a failed job instead of stopping the sweep with the first, and its state and log go
  into its folder (``waterair.training.sweep.LAUNCH_FILE``) for the summary;
- sbatch refusing the jobs is one line, and the sweep folder goes when no job of it ran.

Every key is in docs/training.md. Jobs run the submitting machine's Python (the absolute path of
``.venv/bin/python``) in the submitting directory: the cluster's nodes must see both.
"""

# No "from __future__ import annotations": Hydra runs this module before it is in sys.modules, where
# dataclasses look string annotations up.
import contextlib
import io
import logging
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hydra.core.config_store import ConfigStore
from hydra.core.singleton import Singleton
from hydra.core.utils import JobReturn, JobStatus, filter_overrides
from hydra.errors import CompactHydraException
from omegaconf import OmegaConf

from waterair.core.files import atomic_write_json

log = logging.getLogger(__name__)

POLL_S = 5.0
"""Seconds between two looks at the jobs still running."""
VANISHED_AFTER_S = 60.0
"""A job neither queued nor in Slurm's accounting for this long has left without running."""
COMPILE_CACHE = ".compile_cache"
"""The torch compile cache of a Slurm sweep, under its root (``TORCHINDUCTOR_CACHE_DIR``)."""


class JobStopped(CompactHydraException):
    """A job that ended without a result: failed outside Python, cancelled, timed out, out of memory."""


def remove_sweep_dir(root: Path) -> None:
    """Remove a sweep folder in which no job ran, and the parents it leaves empty inside the working directory."""
    if not root.is_dir() or not set(os.listdir(root)) <= {"multirun.yaml", ".submitit"}:
        return
    shutil.rmtree(root)
    here = Path.cwd().resolve()
    for parent in root.resolve().parents:
        if here not in parent.parents or any(parent.iterdir()):
            break
        parent.rmdir()


try:
    from hydra_plugins.hydra_submitit_launcher.config import BaseQueueConf, LocalQueueConf, SlurmQueueConf
    from hydra_plugins.hydra_submitit_launcher.submitit_launcher import BaseSubmititLauncher
except ImportError:  # hydra-submitit-launcher not installed: the preflight refuses its launchers in one line
    BaseSubmititLauncher = None


if BaseSubmititLauncher is not None:

    class WaitForAll(BaseSubmititLauncher):
        """The plugin's launcher, waiting for every job and recording how each ended (module docstring)."""

        def executor(self, folder: str | Path):
            """The submitit executor with this launcher's parameters (the plugin's translation of its keys)."""
            import submitit

            init_keys = {"max_num_timeout"}
            executor = submitit.AutoExecutor(
                cluster=self._EXECUTOR,
                folder=folder,
                **{f"{self._EXECUTOR}_{k}": v for k, v in self.params.items() if k in init_keys},
            )
            common = set(OmegaConf.structured(BaseQueueConf).keys())
            executor.update_parameters(
                **{
                    key if key in common else f"{self._EXECUTOR}_{key}": value
                    for key, value in self.params.items()
                    if key not in init_keys | {"submitit_folder"}
                }
            )
            return executor

        def launch(self, job_overrides: Sequence[Sequence[str]], initial_job_idx: int) -> Sequence[JobReturn]:
            import submitit

            assert self.config is not None
            root = Path(str(self.config.hydra.sweep.dir))
            root.mkdir(parents=True, exist_ok=True)
            executor = self.executor(self.params["submitit_folder"])
            numbers = range(initial_job_idx, initial_job_idx + len(job_overrides))
            log.info(f"Submitit '{self._EXECUTOR}' sweep output dir: {root}")
            for number, overrides in zip(numbers, job_overrides, strict=True):
                log.info(f"\t#{number} : {' '.join(filter_overrides(overrides))}")
            arguments = [
                (list(overrides), "hydra.sweep.dir", number, f"job_id_for_{number}", Singleton.get_state())
                for number, overrides in zip(numbers, job_overrides, strict=True)
            ]
            refusal = io.StringIO()  # submitit prints sbatch's whole error before raising it
            try:
                with contextlib.redirect_stderr(refusal):
                    jobs = executor.map_array(self, *zip(*arguments, strict=True))
            except submitit.core.utils.FailedJobError as error:
                if initial_job_idx == 0:
                    remove_sweep_dir(root)
                lines = [line for line in str(error).splitlines() if line.strip()] or ["no message"]
                # sys.exit, not an exception: Hydra follows any exception's message with a hint about HYDRA_FULL_ERROR
                sys.exit(f"error: the scheduler refused the jobs: {lines[-1].strip()}")
            for job, number, overrides in zip(jobs, numbers, job_overrides, strict=True):
                _record(root / str(number), job, overrides, "SUBMITTED")
            vanished = self._wait(jobs)
            return [
                self._outcome(job, root / str(number), overrides, job.job_id in vanished)
                for job, number, overrides in zip(jobs, numbers, job_overrides, strict=True)
            ]

        def _wait(self, jobs) -> set[str]:
            """Wait until every job has ended; the ids of those that left the queue without a trace.

            Slurm keeps no accounting record of an array job cancelled before it started, so submitit
            would wait for it forever: a job that is neither queued nor known to sacct for
            :data:`VANISHED_AFTER_S` is taken to have left without running.
            """
            waiting, vanished, missing_since = list(jobs), set(), {}
            while waiting:
                queued = _queued() if self._EXECUTOR == "slurm" else None  # local jobs always end with a state
                for job in list(waiting):
                    if job.done():
                        waiting.remove(job)
                    elif queued is not None and job.job_id not in queued and job.state == "UNKNOWN":
                        first = missing_since.setdefault(job.job_id, time.monotonic())
                        if time.monotonic() - first > VANISHED_AFTER_S and not job.done(force_check=True):
                            waiting.remove(job)
                            vanished.add(job.job_id)
                    else:
                        missing_since.pop(job.job_id, None)
                if waiting:
                    time.sleep(POLL_S)
            return vanished

        def _outcome(self, job, folder: Path, overrides: Sequence[str], vanished: bool) -> JobReturn:
            """The job's own result once it has ended, or a failed result saying how it ended."""
            import submitit

            try:
                if vanished:
                    raise submitit.core.utils.UncompletedJobError("it left the queue before it started")
                result = job.results()[0]
                state = "COMPLETED"
            except submitit.core.utils.UncompletedJobError:
                state = "CANCELLED" if vanished else job.get_info(mode="force").get("State", "UNKNOWN")
                stopped = JobStopped(f"job {folder.name} ended without a result ({state}); log: {job.paths.stderr}")
                result = JobReturn(overrides=list(overrides), status=JobStatus.FAILED, _return_value=stopped)
            _record(folder, job, overrides, state)
            return result

    def _queued() -> set[str] | None:
        """The ids of the jobs in Slurm's queue, one per array task (``12_3``); None if squeue cannot tell."""
        done = subprocess.run(["squeue", "--noheader", "--array", "--format=%i"], capture_output=True, text=True)
        return set(done.stdout.split()) if done.returncode == 0 else None

    def _record(folder: Path, job, overrides: Sequence[str], state: str) -> None:
        from waterair.training.sweep import LAUNCH_FILE  # the summary's reader; imported when a job is recorded

        folder.mkdir(parents=True, exist_ok=True)
        record = {"id": job.job_id, "state": state, "log": str(job.paths.stderr), "overrides": list(overrides)}
        atomic_write_json(folder / LAUNCH_FILE, record)

    class SlurmLauncher(WaitForAll):
        _EXECUTOR = "slurm"

    class LocalLauncher(WaitForAll):
        _EXECUTOR = "local"

    THREADS = "export OMP_NUM_THREADS=${hydra.launcher.cpus_per_task}"
    """torch's threads: the job's CPUs (without CPU binding torch would take every core of the node)."""

    @dataclass
    class SlurmConf(SlurmQueueConf):
        """hydra/launcher=submitit_slurm for train.py (docs/training.md has every key)."""

        _target_: str = "hydra_plugins.waterair_sweeps.launchers.SlurmLauncher"
        timeout_min: int = 60
        cpus_per_task: int = 1
        mem_gb: int = 4
        gpus_per_node: Any = "${gpus_for_device:${device}}"
        setup: Any = field(
            default_factory=lambda: [THREADS, f"export TORCHINDUCTOR_CACHE_DIR=${{hydra.sweep.dir}}/{COMPILE_CACHE}"]
        )

    @dataclass
    class LocalConf(LocalQueueConf):
        """hydra/launcher=submitit_local for train.py: the jobs as processes of this machine, all at once."""

        _target_: str = "hydra_plugins.waterair_sweeps.launchers.LocalLauncher"
        cpus_per_task: int = 1
        gpus_per_node: Any = "${gpus_for_device:${device}}"
        setup: Any = field(default_factory=lambda: [THREADS])


def register() -> None:
    """Make hydra/launcher=submitit_slurm and submitit_local these launchers (called by :mod:`.options`)."""
    if BaseSubmititLauncher is None:
        return
    ConfigStore.instance().store(group="hydra/launcher", name="submitit_slurm", node=SlurmConf, provider="waterair")
    ConfigStore.instance().store(group="hydra/launcher", name="submitit_local", node=LocalConf, provider="waterair")
