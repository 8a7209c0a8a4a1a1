"""An evaluation's batches side by side in processes: ``workers`` in evaluate.py.

An evaluation runs batches: S1, S2+S3+S4 (one batch of their shared seas), S5 at each divergence. Each
seeds its own environment, and a group's graphs do not depend on what ran before them in the process (the batch
size is symbolic, :func:`waterair.envs.stepper.varying_environments`). So the batches can run in processes of
their own and give the numbers one process gives, bit for bit where each process runs on as many torch threads
as the one process would (one, on 2 CPUs). Processes of one thread each never wait for each other, as a team of
threads waits for its slowest at every parallel operation (:mod:`waterair.core.threads`), so ``auto`` takes
every CPU, not all but one: on the 2-core VM, two processes finish an evaluation in 0.6–0.7 of one's time
(docs/benchmarks.md, "Evaluation"). Each process compiles or loads a group's graphs itself; into an empty
compile cache they compile at once, on a core each.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import torch

from waterair.core.process import set_up_process
from waterair.core.threads import AUTO, check_threads, choose_threads, given_cpus
from waterair.envs.config import EnvConfig
from waterair.envs.stepper import varying_environments
from waterair.evaluation.compiling import note_compiled
from waterair.evaluation.rollouts import rollout_policies


@dataclass(frozen=True)
class Batch:
    """One batch of an evaluation: its ``points`` × ``realisations`` links for ``steps`` steps from ``seed``,
    stepped by each of its ``groups`` ``(env config, [(label, policy or baseline name)])``; ``what`` names it in
    the progress lines."""

    what: str
    groups: list[tuple[EnvConfig, list]]
    points: list[tuple[float, float, float]]
    realisations: int
    steps: int
    seed: int

    @property
    def frames(self) -> int:
        """Link-steps in all: what a batch costs, to hand out the largest first."""
        links = len(self.points) * self.realisations * self.steps
        return sum(len(members) for _, members in self.groups) * links


def choose_workers(
    setting: object, batches: int, device: str, environ=None, affinity: int | None = None
) -> tuple[int, int, str]:
    """The processes for ``batches`` batches on ``device`` (``setting``: ``auto`` or a count), the torch threads
    of each, and a line saying why.

    ``auto`` takes one process on a GPU; on the CPU, as many as there are CPUs (``OMP_NUM_THREADS``, a Slurm
    allocation, else this process's affinity), at most one a batch. The CPUs are shared out between the
    processes; one process (also any count in a daemonic process, which may start none) runs on
    ``threads: auto``'s count (:func:`waterair.core.threads.choose_threads`).
    """
    setting = check_threads(setting, "workers")
    affinity = len(os.sched_getaffinity(0)) if affinity is None else affinity
    given = given_cpus(environ, affinity)
    cpus = given[0] if given else affinity
    if setting == AUTO:
        workers = 1 if torch.device(device).type != "cpu" else min(batches, cpus)
    else:
        workers = min(int(setting), batches)
    if multiprocessing.current_process().daemon:  # a pool's worker (a launcher's) may start no processes
        workers = 1
    if workers <= 1:
        threads, why = choose_threads(AUTO, environ, affinity)
        return 1, threads, f"1 process of {threads} torch thread{'s' if threads > 1 else ''} ({why})"
    threads = max(1, cpus // workers)
    why = f"{'auto: ' if setting == AUTO else 'as configured: '}{batches} batches on {cpus} CPUs"
    return workers, threads, f"{workers} processes of {threads} torch thread{'s' if threads > 1 else ''} each ({why})"


def run_batch(batch: Batch) -> tuple[dict, list[str]]:
    """Every group's traces of ``batch`` (:func:`rollout_policies`, by label) and a progress line per group."""
    runs, lines = {}, []
    with varying_environments():  # one step graph per policy group, whatever the batch
        for env_config, members in batch.groups:
            start = time.perf_counter()
            runs.update(
                rollout_policies(env_config, members, batch.points, batch.realisations, batch.steps, batch.seed)
            )
            labels = ", ".join(label for label, _ in members)
            how = "compiled" if env_config.compile_kernel else "eager"
            lines.append(f"{batch.what}: {labels} in {time.perf_counter() - start:.0f} s ({how})")
    return runs, lines


def run_batches(batches: Sequence[Batch], workers: int, threads: int, progress: Callable[[str], object]) -> list:
    """:func:`run_batch` of each of ``batches``, in ``workers`` processes of ``threads`` torch threads (1: in
    this one, on its threads), the largest first; their results in ``batches``' order, their progress lines as
    they finish. Ctrl-C, or a batch's error, ends the processes at once and is raised here."""
    results: list = [None] * len(batches)

    def finished(index: int, result: tuple[dict, list[str]]) -> None:
        results[index] = result[0]
        for line in result[1]:
            progress(line)
        for env_config, _ in batches[index].groups:
            note_compiled(env_config)

    if workers <= 1:
        for index, batch in enumerate(batches):
            finished(index, run_batch(batch))
        return results
    order = sorted(range(len(batches)), key=lambda i: -batches[i].frames)
    spawn = multiprocessing.get_context("spawn")  # a forked torch inherits its threads' locks
    pool = spawn.Pool(workers, initializer=_start_process, initargs=(threads,))
    try:
        for index, result in pool.imap_unordered(_run_indexed, [(i, batches[i]) for i in order]):
            finished(index, result)
        pool.close()
    except BaseException:
        pool.terminate()
        raise
    finally:
        pool.join()
    return results


def _start_process(threads: int) -> None:
    """A batches' process: ``threads`` torch threads; Ctrl-C is left to the evaluation's process, which ends it.
    Its imports are done (unpickling this function imported this module): it is set up as the entry points set up
    theirs (:func:`~waterair.core.process.set_up_process`)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    torch.set_num_threads(threads)
    set_up_process()


def _run_indexed(item: tuple[int, Batch]) -> tuple[int, tuple[dict, list[str]]]:
    index, batch = item
    return index, run_batch(batch)
