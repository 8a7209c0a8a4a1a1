"""torch's intra-op threads: the ``threads`` setting (``auto`` or a count) and the CPUs a process may use.

torch starts one intra-op thread per CPU it sees. When something else runs on those CPUs, its
threads wait for each other at every parallel operation: on the 2-core development machine, with
one busy single-threaded process beside it (and other work), a short default run went at 8 frames/s
on torch's two threads and at 124 on one (docs/benchmarks.md, "The default run, short and long,
and under load"). ``auto`` therefore takes:

1. ``OMP_NUM_THREADS`` when it is set: whoever started the process chose (joblib's workers get
   cores ÷ jobs, the submitit launchers their ``cpus_per_task``);
2. else, in a Slurm job, its allocation (``SLURM_CPUS_PER_TASK``, else ``SLURM_CPUS_ON_NODE``), at
   most the CPUs of the process's affinity: those CPUs are the job's own;
3. else one fewer than the CPUs of the process's affinity (``os.sched_getaffinity``), at least one:
   the machine is shared, and one CPU is left to whatever else runs.

Inter-op threads are left at torch's default: the training loop and the evaluation start no
inter-op work, so that pool never starts a thread.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Mapping
from contextlib import contextmanager

import torch

AUTO = "auto"
MAX_THREADS = 4096
"""The largest ``threads`` accepted (as ``hydra.launcher.cpus_per_task``)."""
SLURM_ALLOCATION = ("SLURM_CPUS_PER_TASK", "SLURM_CPUS_ON_NODE")
"""Slurm's variables for the CPUs a job's task may use, the more specific first."""


def check_threads(value: object, key: str = "threads") -> int | str:
    """``auto`` or an integer in [1, :data:`MAX_THREADS`]; else a one-line ``ValueError`` naming ``key``."""
    if isinstance(value, str) and value.lower() == AUTO:
        return AUTO
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_THREADS:
        raise ValueError(f"{key} = {value!r} is not allowed; choose auto or an integer in [1, {MAX_THREADS}]")
    return value


def choose_threads(
    setting: object, environ: Mapping[str, str] | None = None, affinity: int | None = None
) -> tuple[int, str]:
    """The intra-op threads for ``setting`` (``auto`` or a count) and a line saying why.

    ``environ`` (default ``os.environ``) and ``affinity`` (default: the CPUs of this process's
    affinity) are what ``auto`` reads; the module docstring has the rule.
    """
    setting = check_threads(setting)
    if setting != AUTO:
        return int(setting), "as configured"
    affinity = len(os.sched_getaffinity(0)) if affinity is None else affinity
    given = given_cpus(environ, affinity)
    if given is not None:
        return given
    if affinity == 1:
        return 1, "auto: 1 CPU in this process's affinity"
    return affinity - 1, f"auto: {affinity} CPUs in this process's affinity, one left to the rest of the machine"


def given_cpus(environ: Mapping[str, str] | None = None, affinity: int | None = None) -> tuple[int, str] | None:
    """The CPUs whoever started this process gave it (rules 1 and 2 of the module docstring) and a line saying
    why; None when neither ``OMP_NUM_THREADS`` nor a Slurm allocation says."""
    environ = os.environ if environ is None else environ
    affinity = len(os.sched_getaffinity(0)) if affinity is None else affinity
    omp = _count(environ.get("OMP_NUM_THREADS"))
    if omp is not None:
        return omp, f"auto: OMP_NUM_THREADS = {omp}"
    for name in SLURM_ALLOCATION:
        allocated = _count(environ.get(name))
        if allocated is not None:
            cpus = min(allocated, affinity)
            return cpus, f"auto: the {cpus} CPUs of this Slurm job ({name} = {allocated}, affinity {affinity})"
    return None


@contextmanager
def torch_threads(count: int) -> Iterator[int]:
    """Run the body with torch's intra-op threads at ``count``, then restore the previous count."""
    before = torch.get_num_threads()
    torch.set_num_threads(count)
    try:
        yield count
    finally:
        torch.set_num_threads(before)


def _count(text: str | None) -> int | None:
    """A positive CPU count from an environment variable (``OMP_NUM_THREADS=4,2``: the outer 4); None if absent."""
    try:
        value = int((text or "").split(",")[0])
    except ValueError:
        return None
    return value if value >= 1 else None
