"""threads: auto picks torch's threads from the CPUs a process may use; a count overrides; a bad value is one line."""

import pytest
import torch
from conftest import ROOT, TINY, compose_config
from omegaconf import OmegaConf

from waterair.cli import training
from waterair.cli.preflight import preflight
from waterair.core.threads import choose_threads, torch_threads
from waterair.training import train
from waterair.training.resume import plan_resume


@pytest.mark.parametrize(
    "environ,affinity,threads,why",
    [
        ({}, 2, 1, "2 CPUs in this process's affinity, one left"),
        ({}, 16, 15, "16 CPUs in this process's affinity, one left"),
        ({}, 1, 1, "1 CPU in this process's affinity"),
        ({"SLURM_CPUS_PER_TASK": "4", "SLURM_CPUS_ON_NODE": "8"}, 64, 4, "SLURM_CPUS_PER_TASK = 4"),
        ({"SLURM_CPUS_ON_NODE": "8"}, 64, 8, "SLURM_CPUS_ON_NODE = 8"),
        ({"SLURM_CPUS_PER_TASK": "8"}, 2, 2, "the 2 CPUs of this Slurm job"),  # bound to fewer: the affinity
        ({"OMP_NUM_THREADS": "3", "SLURM_CPUS_PER_TASK": "8"}, 16, 3, "OMP_NUM_THREADS = 3"),
        ({"OMP_NUM_THREADS": "", "SLURM_CPUS_PER_TASK": "junk"}, 4, 3, "4 CPUs"),  # unreadable: not set
    ],
)
def test_auto_takes_the_launchers_choice_then_slurms_allocation_then_the_affinity(environ, affinity, threads, why):
    chosen, reason = choose_threads("auto", environ, affinity)
    assert chosen == threads and reason.startswith("auto: ") and why in reason


def test_a_count_overrides_whatever_the_machine():
    assert choose_threads(3, {"OMP_NUM_THREADS": "1", "SLURM_CPUS_PER_TASK": "8"}, 2) == (3, "as configured")


def test_the_callers_threads_come_back_after_the_block():
    before = torch.get_num_threads()
    with torch_threads(1):
        assert torch.get_num_threads() == 1
    assert torch.get_num_threads() == before


@pytest.mark.parametrize("value", ["0", "-2", "two", "1.5", "4097"])
def test_a_bad_threads_value_is_one_line_before_anything_is_written(value):
    outputs = ROOT / "outputs"
    before = sorted(outputs.rglob("*")) if outputs.exists() else None
    with pytest.raises(SystemExit) as stop:
        preflight("config", [f"threads={value}"], training.check)
    message = str(stop.value.code)
    assert message.startswith("error: threads = ") and "choose auto or an integer in [1, 4096]" in message
    assert "\n" not in message
    assert (sorted(outputs.rglob("*")) if outputs.exists() else None) == before


def test_a_run_says_its_threads_first_and_gives_the_callers_back(tmp_path):
    before, lines = torch.get_num_threads(), []
    train(compose_config("config", [*TINY, "total_frames=400", "threads=1"]), tmp_path, progress=lines.append)
    assert lines[0] == "Running on 1 torch thread (as configured)"
    assert torch.get_num_threads() == before


def test_a_resumed_run_may_change_its_threads_and_an_older_run_without_the_key_is_auto(tmp_path):
    saved = OmegaConf.to_container(compose_config("config", TINY), resolve=True)
    saved.pop("hydra", None), saved.pop("threads")  # a run from before the key
    (tmp_path / "config.yaml").write_text(OmegaConf.to_yaml(saved))
    overrides = [f"resume={tmp_path}", "threads=2"]
    assert plan_resume(compose_config("config", overrides), overrides).config.threads == 2
    assert "threads" not in plan_resume(compose_config("config", overrides[:1]), overrides[:1]).config
