"""Sweep summaries: failed and cancelled jobs marked with their logs, the rebuild command, the Optuna search."""

import csv
import importlib.util
import json
import logging
import os
from pathlib import Path

import optuna
import pytest
import run_scripts
from conftest import ONE_PATH, ROOT, TINY, compose_config
from hydra import initialize_config_dir
from hydra.core.global_hydra import GlobalHydra
from hydra.core.override_parser.overrides_parser import OverridesParser
from omegaconf import OmegaConf
from optuna.distributions import CategoricalDistribution, FloatDistribution, IntDistribution
from optuna.trial import TrialState

from hydra_plugins.waterair_sweeps.search import search_space, trial_overrides
from waterair.cli import training
from waterair.cli.preflight import preflight
from waterair.cli.sweep import main as rebuild
from waterair.training.sweep import ERROR_FILE, LAUNCH_FILE, learning_curves, read_jobs


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
    assert "| job | seed | frames |" in table and rows[1]["seed"] == "1"  # a column per swept key
    assert "| 0 | `0` | 800 | 12 | 0.910 |" in table and "| 1 | `1` | 800 | 12 | 0.930 |" in table
    assert "Best: job 1 (`seed=1`), 0.930." in table and "over 2 jobs: mean 0.920" in table
    assert "Did not finish (3 of 5 jobs):" in table
    assert "| 2 | `seed=2` | failed | RuntimeError: boom | 2/train.log |" in table
    assert "| 4 | `seed=4` | timeout | the scheduler's state is TIMEOUT | .submitit/7_4/7_4_0_log.err |" in table
    assert (sweep / "learning_curves.png").read_bytes()[:4] == b"\x89PNG"


def test_jobs_that_logged_once_draw_their_learning_curves_without_a_warning(tmp_path, recwarn):
    import numpy as np

    curves = {"0": (np.array([400.0]), np.array([0.8])), "1": (np.array([400.0]), np.array([0.9]))}
    png = learning_curves(curves, tmp_path / "curves.png")
    assert png is not None and png.read_bytes()[:4] == b"\x89PNG"
    assert not [str(w.message) for w in recwarn.list if "xlim" in str(w.message)]


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
    done = run_scripts.run(
        "train.py", "-m", "hydra/sweeper=optuna", "hydra.sweeper.n_trials=2", "hydra.sweeper.n_jobs=1",
        "hydra.sweeper.sampler.seed=0", *TINY, *ONE_PATH, "total_frames=400", "agent.gamma=interval(0,0.3)",
        "reward.pointing=interval(0,0.2)", "env/sea=choice(calm,rough)", f"hydra.sweep.dir={tmp_path}",
        timeout=600, env={**os.environ, "OMP_NUM_THREADS": "1"},
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.strip().splitlines()[-1] == f"Summary of 2 jobs: {tmp_path / 'summary.md'}"
    jobs = read_jobs(tmp_path)
    assert [job.status for job in jobs] == ["finished", "finished"]
    assert all(any(o.startswith("agent.gamma=") for o in job.overrides) for job in jobs)
    best = max(jobs, key=lambda job: job.metrics["agent/ratio_to_ub"])
    assert OmegaConf.load(tmp_path / "optimization_results.yaml").best_value == best.metrics["agent/ratio_to_ub"]
    assert f"Best: job {best.number} " in (tmp_path / "summary.md").read_text()


SEARCH_CONFIG = """
defaults:
  - override hydra/sweeper: optuna
  - override hydra/job_logging: none
  - override hydra/hydra_logging: none
  - _self_
x: 0.5
word: a
"""
"""A config of two keys for searches whose jobs are :func:`score`, not training runs."""
SAMPLERS = {"tpe": optuna.samplers.TPESampler, "gp": optuna.samplers.GPSampler}


def score(cfg):
    """A toy job: largest at x = 0.3 with word b; the word "bad" raises, as a training run with a bad value does."""
    if cfg.word == "bad":
        raise ValueError("word = 'bad'")
    return -((cfg.x - 0.3) ** 2) + (0.1 if cfg.word == "b" else 0.0)


@pytest.fixture
def multirun(hydra_restore_singletons):
    """``run(config_dir, config_name, task, overrides, job_name)``: ``JOB_NAME.py -m overrides`` in this process,
    without the preflight; the jobs' logging is taken down afterwards."""
    handlers, level = logging.root.handlers[:], logging.root.level
    existing = [logger for logger in logging.Logger.manager.loggerDict.values() if isinstance(logger, logging.Logger)]
    loggers = {logger.name: (logger.level, logger.handlers[:], logger.propagate) for logger in existing}

    def run(config_dir, config_name, task, overrides, job_name="app"):
        with initialize_config_dir(config_dir=str(config_dir), job_name=job_name, version_base="1.3"):
            arguments = [*overrides, "hydra.mode=MULTIRUN"]  # what -m adds
            GlobalHydra.instance().hydra.multirun(config_name, task, arguments, with_log_configuration=False)

    yield run
    logging.root.handlers[:], logging.root.level = handlers, level
    for name, (logger_level, logger_handlers, propagate) in loggers.items():
        logger = logging.getLogger(name)
        logger.level, logger.handlers[:], logger.propagate = logger_level, logger_handlers, propagate


def search(multirun, tmp_path, sweep_dir, *overrides):
    """A search of :func:`score` over ``x`` and ``word`` into ``sweep_dir``."""
    (tmp_path / "conf").mkdir(exist_ok=True)
    (tmp_path / "conf" / "search.yaml").write_text(SEARCH_CONFIG)
    multirun(tmp_path / "conf", "search", score, [f"hydra.sweep.dir={sweep_dir}", "hydra.sweeper.n_jobs=1", *overrides])


@pytest.mark.parametrize("sampler", ["tpe", "gp"])
def test_the_search_draws_its_trials_with_the_sampler_chosen(sampler, multirun, tmp_path):
    storage = f"sqlite:///{tmp_path / 'study.db'}"
    search(multirun, tmp_path, tmp_path / "sweep", f"hydra/sweeper/sampler={sampler}", "hydra.sweeper.sampler.seed=0",
           "hydra.sweeper.sampler.n_startup_trials=2", "hydra.sweeper.n_trials=4", f"hydra.sweeper.storage={storage}",
           "hydra.sweeper.study_name=toy", "x=interval(0,1)", "word=choice(a,b)")  # fmt: skip
    trials = optuna.load_study(study_name="toy", storage=storage).trials
    assert [trial.value for trial in trials] == [score(OmegaConf.create(trial.params)) for trial in trials]

    # Each sampler asked and told the same by hand: the chosen one draws the search's values, the other does not.
    space = {"x": FloatDistribution(0.0, 1.0), "word": CategoricalDistribution(["a", "b"])}
    drawn = {}
    for name, sampler_class in SAMPLERS.items():
        reference = optuna.create_study(sampler=sampler_class(seed=0, n_startup_trials=2), direction="maximize")
        drawn[name] = []
        for trial in trials:
            asked = reference.ask(space)
            drawn[name].append(asked.params)
            reference.tell(asked, trial.value)
    assert [trial.params for trial in trials] == drawn[sampler]
    assert drawn["tpe"][2:] != drawn["gp"][2:]  # after the two random startup trials


def test_a_search_with_a_storage_is_continued_by_the_next_command(multirun, tmp_path):
    storage = f"sqlite:///{tmp_path / 'study.db'}"
    for name in ("first", "second"):
        search(multirun, tmp_path, tmp_path / name, "hydra.sweeper.n_trials=2", f"hydra.sweeper.storage={storage}",
               "hydra.sweeper.study_name=toy", "x=interval(0,1)")  # fmt: skip
    trials = optuna.load_study(study_name="toy", storage=storage).trials
    assert [trial.number for trial in trials] == [0, 1, 2, 3]
    assert [(Path(trial.user_attrs["sweep_dir"]).name, trial.user_attrs["job"]) for trial in trials] == [
        ("first", 0), ("first", 1), ("second", 0), ("second", 1)]  # fmt: skip
    assert trials[2].user_attrs["overrides"] == [f"x={trials[2].params['x']}"]
    assert all(trial.state == TrialState.COMPLETE for trial in trials)
    best = OmegaConf.load(tmp_path / "second" / "optimization_results.yaml")  # the study's best, both commands'
    assert best.best_value == max(trial.value for trial in trials)
    assert best.best_params.x == next(t.params["x"] for t in trials if t.value == best.best_value)


def test_a_search_stops_when_more_of_a_batch_fail_than_max_failure_rate(multirun, tmp_path, caplog):
    search(multirun, tmp_path, tmp_path / "sweep", "hydra.sweeper.n_trials=3", "hydra.sweeper.max_failure_rate=0",
           "word=choice(bad)", "x=interval(0,1)")  # fmt: skip
    assert sorted(path.name for path in (tmp_path / "sweep").iterdir() if path.is_dir()) == ["0"]
    assert "The search stops after 1 of 3 trials: 1 of the last 1 failed" in caplog.text
    assert not (tmp_path / "sweep" / "optimization_results.yaml").exists()  # no trial finished


SEARCH_REFUSALS = [
    (["hydra.sweeper.max_failure_rate=2"], "error: hydra.sweeper.max_failure_rate = 2.0 is out of range; allowed [0,"),
    (["hydra.sweeper.n_jobs=0"], "error: hydra.sweeper.n_jobs = 0 is out of range; allowed [1, inf]"),
    (["hydra.sweeper.direction=up"], "error: hydra.sweeper.direction = 'up' is not allowed; choose one of maximize"),
    (["agent.gamma=tag(log,interval(0,0.3))"], "error: agent.gamma=tag(log,interval(0,0.3)): a log scale needs low"),
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


@pytest.mark.slow
def test_a_search_of_three_trials_two_failing_tells_them_failed_and_summarises_the_one_that_finished(
    multirun, tmp_path
):
    # The three trials' values are enqueued in the study's storage, so that the trials are these, in this order.
    storage, sweep = f"sqlite:///{tmp_path / 'study.db'}", tmp_path / "sweep"
    study = optuna.create_study(study_name="gamma", storage=storage, direction="maximize")
    for gamma in ("1.5", "0.1", "2.0"):
        study.enqueue_trial({"agent.gamma": gamma})
    spec = importlib.util.spec_from_file_location("train", ROOT / "train.py")
    entry_point = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(entry_point)
    with pytest.raises(SystemExit) as stop:
        multirun(ROOT / "conf", "config", entry_point.main,
                 ["hydra/sweeper=optuna", "hydra.sweeper.n_trials=3", "hydra.sweeper.n_jobs=1",
                  f"hydra.sweeper.storage={storage}", "hydra.sweeper.study_name=gamma", *TINY, *ONE_PATH,
                  "total_frames=800", "agent.gamma=choice(0.1,1.5,2.0)", f"hydra.sweep.dir={sweep}"],
                 job_name="train")  # fmt: skip
    message = str(stop.value.code)
    assert message.startswith("error: 2 of 3 jobs did not finish: job 0 (agent.gamma=1.5) failed: ValueError: ")
    assert "job 2 (agent.gamma=2.0) failed: ValueError: agent.gamma = 2.0 is out of range" in message
    jobs = read_jobs(sweep)
    assert [job.status for job in jobs] == ["failed", "finished", "failed"]
    ratio = jobs[1].metrics["agent/ratio_to_ub"]
    table = (sweep / "summary.md").read_text()
    assert f"Best: job 1 (`agent.gamma=0.1`), {ratio:.3f}." in table and "Did not finish (2 of 3 jobs):" in table

    trials = optuna.load_study(study_name="gamma", storage=storage).trials
    assert [trial.state for trial in trials] == [TrialState.FAIL, TrialState.COMPLETE, TrialState.FAIL]
    assert [trial.params["agent.gamma"] for trial in trials] == ["1.5", "0.1", "2.0"]
    assert trials[1].value == ratio
    assert OmegaConf.load(sweep / "optimization_results.yaml") == {
        "name": "optuna", "best_params": {"agent.gamma": "0.1"}, "best_value": ratio}  # fmt: skip


def test_the_search_space_is_hydras_sweep_syntax_and_every_other_override_is_passed_as_written():
    overrides = ["agent.gamma=interval(0,0.3)", "actor.lr=tag(log,interval(1e-4,1e-2))", "env/sea=choice(calm,rough)",
                 "collector.updates_per_frame=range(1,5)", "eval.steps=range(10,40,10)", "x=range(0,1,0.25)",
                 "seed=3", "actor.hidden=[32,32]"]  # fmt: skip
    space = search_space(OverridesParser.create().parse_overrides(overrides))
    assert [(key, distribution) for key, distribution, _ in space] == [
        ("agent.gamma", FloatDistribution(0.0, 0.3)),
        ("actor.lr", FloatDistribution(1e-4, 1e-2, log=True)),
        ("env/sea", CategoricalDistribution(["calm", "rough"])),
        ("collector.updates_per_frame", IntDistribution(1, 4)),  # stop excluded, as in a grid
        ("eval.steps", IntDistribution(10, 30, step=10)),
        ("x", FloatDistribution(0.0, 0.75, step=0.25)),
        ("seed", None),
        ("actor.hidden", None),
    ]
    drawn = {"agent.gamma": 0.125, "actor.lr": 0.001, "env/sea": "rough", "collector.updates_per_frame": 2,
             "eval.steps": 20, "x": 0.5}  # fmt: skip
    assert trial_overrides(space, drawn) == [
        "agent.gamma=0.125", "actor.lr=0.001", "env/sea=rough", "collector.updates_per_frame=2", "eval.steps=20",
        "x=0.5", "seed=3", "actor.hidden=[32,32]"]  # fmt: skip


def hparams_of(events: Path) -> dict:
    """The hparams plugin's session values in the event files under ``events`` (name → number or string)."""
    from tensorboard.backend.event_processing.event_file_loader import EventFileLoader
    from tensorboard.plugins.hparams.plugin_data_pb2 import HParamsPluginData

    found = {}
    for path in events.glob("events.out.tfevents.*"):
        for event in EventFileLoader(str(path)).Load():
            for value in event.summary.value:
                if value.tag == "_hparams_/session_start_info":
                    start = HParamsPluginData.FromString(value.metadata.plugin_data.content).session_start_info
                    found = {key: getattr(hp, hp.WhichOneof("kind")) for key, hp in start.hparams.items()}
    return found


@pytest.mark.slow
def test_a_sweep_over_the_discount_and_the_wind_summarises_and_names_each_job_by_its_values(multirun, tmp_path):
    spec = importlib.util.spec_from_file_location("train", ROOT / "train.py")
    entry_point = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(entry_point)
    small = [*TINY, *ONE_PATH, "total_frames=400", "eval.realisations=2", "eval.steps=10"]
    sweep = tmp_path / "sweep"
    swept = ["agent.gamma=0,0.9", "env.wind=4,12", "reward.a=5"]
    multirun(ROOT / "conf", "config", entry_point.main, [*swept, *small, f"hydra.sweep.dir={sweep}"], "train")
    with (sweep / "summary.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert [(row["agent.gamma"], row["env.wind"], row["status"]) for row in rows] == [
        ("0", "4", "finished"),
        ("0", "12", "finished"),
        ("0.9", "4", "finished"),
        ("0.9", "12", "finished"),
    ]
    assert all(0 < float(row["agent/ratio_to_ub"]) <= 1.2 for row in rows)
    table = (sweep / "summary.md").read_text()
    assert "| job | agent.gamma | env.wind | frames |" in table and "| 3 | `0.9` | `12` | 400 |" in table
    for row in rows:
        gamma, wind = row["agent.gamma"], row["env.wind"]
        saved = OmegaConf.load(sweep / row["job"] / "config.yaml")
        assert saved.env.sea.wind == float(wind) and saved.env.wind_range is None  # it trained at its wind
        # each job's run is named by its overrides, and its hparams row holds its values and its closing ratio
        run = sweep / "tensorboard" / f"agent.gamma={gamma},env.wind={wind}"
        assert saved.logger.dir == str(run)
        values = hparams_of(run)
        assert (values["agent.gamma"], values["env.wind"], values["reward.a"]) == (float(gamma), float(wind), 5.0)
        assert values["env.sea.wind"] == float(wind) and values["agent.name"] == "ppo"
    names = sorted(path.name for path in (sweep / "tensorboard").iterdir())
    assert names == [f"agent.gamma={g},env.wind={w}" for g in ("0", "0.9") for w in ("12", "4")]
