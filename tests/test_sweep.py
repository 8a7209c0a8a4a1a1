"""Sweep summaries: failed and cancelled jobs marked with their logs, the rebuild command, the Optuna search."""

import csv
import json
import os
import subprocess
import sys

import pytest
from conftest import ROOT, TINY, compose_config
from omegaconf import OmegaConf

from waterair.cli import training
from waterair.cli.preflight import preflight
from waterair.cli.sweep import main as rebuild
from waterair.training.sweep import ERROR_FILE, LAUNCH_FILE, read_jobs


def finished_job(root, number, ratio):
    """A job folder as a finished run leaves it: its overrides, final metrics and learning curve."""
    folder = root / str(number)
    (folder / ".hydra").mkdir(parents=True)
    OmegaConf.save(OmegaConf.create([f"seed={number}", "total_frames=800"]), folder / ".hydra" / "overrides.yaml")
    metrics = {"frames": 800, "train_seconds": 12.0, "agent/ratio_to_ub": ratio, "aoa_tracker/ratio_to_ub": 0.88,
               "flat_snell/ratio_to_ub": 0.7, "straight_facing/ratio_to_ub": 0.6}  # fmt: skip
    (folder / "final_metrics.json").write_text(json.dumps(metrics))
    rows = "".join(f"{400 * (i + 1)},{ratio - 0.01 * (7 - i)}\n" for i in range(8))
    (folder / "metrics.csv").write_text("frames,train/gain_ratio_ub\n" + rows)
    (folder / "train.log").write_text("[time] Run directory: ...\n")


@pytest.fixture
def sweep(tmp_path):
    """Five jobs: two finished, one that raised, one cancelled before it started, one the scheduler timed out."""
    finished_job(tmp_path, 0, 0.91)
    finished_job(tmp_path, 1, 0.93)
    failed = tmp_path / "2"
    (failed / ".hydra").mkdir(parents=True)
    OmegaConf.save(OmegaConf.create(["seed=2", "total_frames=800"]), failed / ".hydra" / "overrides.yaml")
    (failed / ERROR_FILE).write_text("RuntimeError: boom\n")
    (failed / "train.log").write_text("Traceback (most recent call last):\nRuntimeError: boom\n")
    log = tmp_path / ".submitit" / "7_4" / "7_4_0_log.err"
    log.parent.mkdir(parents=True)
    log.write_text("slurmstepd: error: *** JOB 7 ON vm CANCELLED AT 2026-11-23T12:00:00 DUE TO TIME LIMIT ***\n")
    for number, state, path in ((3, "CANCELLED by 0", tmp_path / ".submitit" / "7_3" / "7_3_0_log.err"),
                                (4, "TIMEOUT", log)):  # fmt: skip
        record = {
            "id": f"7_{number}",
            "state": state,
            "log": str(path),
            "overrides": [f"seed={number}", "total_frames=800"],
        }
        (tmp_path / str(number)).mkdir(exist_ok=True)
        (tmp_path / str(number) / LAUNCH_FILE).write_text(json.dumps(record))
    return tmp_path


def test_the_summary_keeps_the_finished_jobs_and_marks_the_others_with_their_logs(sweep):
    with pytest.raises(SystemExit) as stop:
        rebuild([str(sweep)])
    message = str(stop.value.code)
    assert "\n" not in message and message.startswith("error: 3 of 5 jobs did not finish: ")
    assert f"job 2 (seed=2) failed: RuntimeError: boom (log: {sweep / '2' / 'train.log'})" in message
    assert "job 3 (seed=3) cancelled: the scheduler's state is CANCELLED; it never started (log: –)" in message
    assert (
        f"job 4 (seed=4) timeout: the scheduler's state is TIMEOUT (log: {sweep / '.submitit/7_4/7_4_0_log.err'})"
        in message
    )
    assert message.endswith(f"summary: {sweep / 'summary.md'}")

    with (sweep / "summary.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert [row["status"] for row in rows] == ["finished", "finished", "failed", "cancelled", "timeout"]
    assert rows[2]["log"] == "2/train.log" and rows[1]["agent/ratio_to_ub"] == "0.93"
    table = (sweep / "summary.md").read_text()
    assert table.startswith("Every job: `total_frames=800`")
    assert "| 0 | `seed=0` | 800 | 12 | 0.910 |" in table and "| 1 | `seed=1` | 800 | 12 | 0.930 |" in table
    assert "Best: job 1 (`seed=1`), 0.930." in table and "over 2 jobs: mean 0.920" in table
    assert "Did not finish (3 of 5 jobs):" in table
    assert "| 2 | `seed=2` | failed | RuntimeError: boom | 2/train.log |" in table
    assert "| 4 | `seed=4` | timeout | the scheduler's state is TIMEOUT | .submitit/7_4/7_4_0_log.err |" in table
    assert (sweep / "learning_curves.png").read_bytes()[:4] == b"\x89PNG"


def test_a_sweep_that_finished_says_where_its_summary_is(sweep, capsys):
    for number in (2, 3, 4):
        for path in sorted((sweep / str(number)).rglob("*"), reverse=True):
            path.rmdir() if path.is_dir() else path.unlink()
        (sweep / str(number)).rmdir()
    rebuild([str(sweep)])
    assert capsys.readouterr().out.strip().splitlines()[-1] == f"Summary of 2 jobs: {sweep / 'summary.md'}"
    assert [job.status for job in read_jobs(sweep)] == ["finished", "finished"]


def test_the_rebuild_refuses_what_is_not_a_folder(tmp_path):
    with pytest.raises(SystemExit) as stop:
        rebuild([str(tmp_path / "missing")])
    assert str(stop.value.code).startswith("error: ") and "is not a directory" in str(stop.value.code)


def test_the_search_and_slurm_options_are_train_pys():
    cfg = compose_config("config", ["hydra/sweeper=optuna", "hydra/launcher=submitit_slurm", "device=cuda"],
                         return_hydra_config=True)  # fmt: skip
    sweeper, launcher = cfg.hydra.sweeper, OmegaConf.to_container(cfg.hydra.launcher, resolve=True)
    assert sweeper._target_.endswith("SearchSweeper") and sweeper.direction == "maximize"
    assert sweeper.max_failure_rate == 1.0  # a failed job is a failed trial, not the end of the search
    assert (sweeper.n_trials, sweeper.n_jobs, sweeper.storage, sweeper.study_name) == (20, 2, None, None)
    assert sweeper.sampler._target_ == "optuna.samplers.TPESampler" and sweeper.sampler.seed is None
    assert launcher["_target_"].endswith("waterair_sweeps.launchers.SlurmLauncher")
    assert (launcher["cpus_per_task"], launcher["mem_gb"], launcher["timeout_min"], launcher["gpus_per_node"]) == (
        1, 4, 60, 1)  # fmt: skip
    assert launcher["setup"] == [
        "export OMP_NUM_THREADS=1",
        f"export TORCHINDUCTOR_CACHE_DIR={cfg.hydra.sweep.dir}/.compile_cache",
    ]
    on_cpu = compose_config("config", ["hydra/launcher=submitit_slurm"], return_hydra_config=True)
    assert OmegaConf.to_container(on_cpu.hydra.launcher, resolve=True)["gpus_per_node"] is None


@pytest.mark.slow
def test_an_optuna_search_of_two_tiny_trials_writes_its_summary_and_best(tmp_path):
    done = subprocess.run(
        [sys.executable, "train.py", "-m", "hydra/sweeper=optuna", "hydra.sweeper.n_trials=2", "hydra.sweeper.n_jobs=1",
         "hydra.sweeper.sampler.seed=0", *TINY, "total_frames=800", "agent.gamma=interval(0,0.3)",
         "reward.pointing=interval(0,0.2)", "env/sea=choice(calm,rough)", f"hydra.sweep.dir={tmp_path}"],
        cwd=ROOT, capture_output=True, text=True, timeout=600, env={**os.environ, "OMP_NUM_THREADS": "1"},
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.strip().splitlines()[-1] == f"Summary of 2 jobs: {tmp_path / 'summary.md'}"
    jobs = read_jobs(tmp_path)
    assert [job.status for job in jobs] == ["finished", "finished"]
    assert all(any(o.startswith("agent.gamma=") for o in job.overrides) for job in jobs)
    best = max(jobs, key=lambda job: job.metrics["agent/ratio_to_ub"])
    assert OmegaConf.load(tmp_path / "optimization_results.yaml").best_value == best.metrics["agent/ratio_to_ub"]
    assert f"Best: job {best.number} " in (tmp_path / "summary.md").read_text()


SEARCH_REFUSALS = [
    (["hydra.sweeper.max_failure_rate=2"], "error: hydra.sweeper.max_failure_rate = 2.0 is out of range; allowed [0,"),
    (["hydra.sweeper.n_jobs=0"], "error: hydra.sweeper.n_jobs = 0 is out of range; allowed [1, inf]"),
    (["hydra.sweeper.direction=up"], "error: hydra.sweeper.direction = 'up' is not allowed; choose one of maximize"),
    (["agent.gamma=tag(log,interval(0,0.3))"], "error: agent.gamma=tag(log,interval(0,0.3)): `low > 0` must hold"),
    (["hydra/sweeper/sampler=cmaes"], "error: hydra/sweeper/sampler=cmaes is not an option of hydra/sweeper/sampler"),
]
"""Searches the sweeper cannot run, and the start of the one line each is refused with."""


@pytest.mark.parametrize("overrides,message", SEARCH_REFUSALS, ids=[case[0][0] for case in SEARCH_REFUSALS])
def test_a_search_its_sweeper_cannot_run_is_refused_in_one_line_before_anything_is_written(overrides, message):
    before = sorted((ROOT / "outputs").rglob("*")) if (ROOT / "outputs").is_dir() else []
    with pytest.raises(SystemExit) as stop:
        preflight("config", ["-m", "hydra/sweeper=optuna", *overrides], training.check)
    assert str(stop.value.code).startswith(message) and "\n" not in str(stop.value.code)
    assert (sorted((ROOT / "outputs").rglob("*")) if (ROOT / "outputs").is_dir() else []) == before
