"""An evaluation's batches in processes of their own (``workers``): how many, and the same numbers as one."""

import multiprocessing

import pytest
import torch
from conftest import rejection
from test_evaluation import S5_TINY, eval_cfg, write_policy

from waterair.envs.config import EnvConfig
from waterair.evaluation.runner import evaluate
from waterair.evaluation.workers import Batch, choose_workers, run_batches


@pytest.mark.parametrize(
    ("setting", "batches", "device", "environ", "affinity", "expected"),
    [
        ("auto", 7, "cpu", {}, 2, (2, 1)),  # the 2-core VM: every CPU, one thread each
        ("auto", 7, "cpu", {}, 16, (7, 2)),  # at most one process a batch, the CPUs shared out
        ("auto", 3, "cpu", {"OMP_NUM_THREADS": "4"}, 16, (3, 1)),  # the CPUs given, not the affinity
        ("auto", 7, "cpu", {"SLURM_CPUS_PER_TASK": "1"}, 16, (1, 1)),
        ("auto", 7, "cpu", {}, 1, (1, 1)),
        ("auto", 7, "cuda", {}, 16, (1, 15)),  # one process on a GPU, on threads: auto's count
        ("auto", 1, "cpu", {}, 16, (1, 15)),
        (3, 2, "cpu", {}, 2, (2, 1)),  # no more processes than batches
        (1, 7, "cpu", {}, 16, (1, 15)),
    ],
)
def test_workers_auto_takes_a_process_per_cpu_up_to_one_a_batch_and_one_on_a_gpu(
    setting, batches, device, environ, affinity, expected
):
    workers, threads, line = choose_workers(setting, batches, device, environ, affinity)
    assert (workers, threads) == expected
    assert line.startswith(f"{workers} process{'es' if workers > 1 else ''} of {threads} torch thread"), line


def test_a_daemonic_process_evaluates_in_itself(monkeypatch):
    """A pool's worker (a launcher's, say) may start no processes of its own: one process, whatever the setting."""
    monkeypatch.setattr(multiprocessing.current_process(), "daemon", True, raising=False)
    assert choose_workers(4, 7, "cpu", {}, 16)[:2] == (1, 15)


def test_workers_out_of_range_is_refused_in_one_line_before_any_work():
    expected = "workers = 0 is not allowed; choose auto or an integer in [1, 4096]"
    assert rejection("evaluate.py", ["workers=0"]) == f"error: {expected}"


def test_an_evaluation_in_two_processes_gives_one_processs_numbers_bit_for_bit(tmp_path, monkeypatch):
    """S1, S2 and S5 at two divergences: four batches, a learned policy (its actor sent to the processes) beside
    the baselines. Each process on one torch thread, as this one."""
    monkeypatch.setenv("OMP_NUM_THREADS", "2")  # two CPUs: two processes of one thread on any machine
    policy = write_policy(tmp_path / "policy.pt", observation_size=8)
    study = [o for o in S5_TINY if o not in ("scenarios.S1=null", "scenarios.S2=null")]
    overrides = (f"checkpoint={policy}", "scenarios.S3=null", "scenarios.S4=null", *study)
    lines: list[str] = []
    apart = evaluate(eval_cfg(*overrides, "workers=2"), progress=lines.append)
    one = evaluate(eval_cfg(*overrides))
    assert lines[0] == "Evaluating in 2 processes of 1 torch thread each (as configured: 4 batches on 2 CPUs)"
    assert len(lines) == 1 + 4  # and a line per batch's group, as each finishes
    assert apart.rows == one.rows  # every metric of every policy, point and divergence, in the same order
    assert apart.power_rows == one.power_rows
    for scenario, traces in one.traces.items():
        for label, trace in traces.items():
            for key, value in trace.items():
                assert torch.equal(apart.traces[scenario][label][key], value), (scenario, label, key)


def test_a_batchs_error_in_its_process_is_raised_in_the_evaluations_and_ends_the_others():
    """A member that is no baseline fails in its process (after the checks an evaluation makes, as a fault would):
    the error comes back with its type, and no process is left running."""
    config = EnvConfig(num_envs=2, max_steps=10, compile_kernel=False)
    batches = [
        Batch(f"batch {k}", [(config, [("x", "no_such_controller")])], [(12.0, 0.1, 0.0)], 2, 4, k) for k in (0, 1)
    ]
    lines: list[str] = []
    with pytest.raises(KeyError, match="no_such_controller"):
        run_batches(batches, workers=2, threads=1, progress=lines.append)
    assert lines == [] and multiprocessing.active_children() == []
