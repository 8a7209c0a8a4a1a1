"""Entry points a user can trust: a rejected command line exits with one line and writes nothing."""

import logging
import warnings

import pytest
import run_scripts
import torch
from conftest import ROOT, compose_config, rejection

from waterair.cli import launch, training
from waterair.cli.console import quiet_dependencies
from waterair.cli.preflight import check_renamed, jobs, on_a_cpu, one_line, preflight

SHIPPED = ROOT / "waterair" / "assets" / "default.pt"


def tree(root):
    """Every path under ``root`` with its size, to compare before and after a command."""
    return {str(p.relative_to(root)): p.stat().st_size for p in root.rglob("*")} if root.exists() else None


@pytest.fixture
def bad_files(tmp_path):
    random_bytes = tmp_path / "random.pt"
    random_bytes.write_bytes(bytes(range(256)) * 12)
    truncated = tmp_path / "truncated.pt"
    truncated.write_bytes(SHIPPED.read_bytes()[:50_000])
    return {"random": random_bytes, "truncated": truncated, "missing": tmp_path / "missing", "tmp": tmp_path}


CASES = [
    ("train.py", "+foo=1", "foo is not a config key"),
    ("train.py", "foo=1", "foo is not a config key"),
    ("train.py", "env.geometry={{offset_ratio:0.2,foo:1}}", "names a key env.geometry does not have"),
    ("train.py", "env.device=cuda", "env.device = 'cuda' is not available"),
    ("train.py", "resume={missing}", "does not exist"),
    ("train.py", "resume={tmp}", "is not a waterair run directory"),
    ("train.py", "agent=a2c", "agent=a2c is not an option of agent; choose one of ddpg, ppo, sac, td3"),
    ("evaluate.py", "run={missing}", "is not a run directory"),
    ("evaluate.py", "checkpoint={random}", "is not a torch file"),
    ("evaluate.py", "checkpoint={truncated}", "is truncated or damaged"),
    ("evaluate.py", "+foo=1", "foo is not a config key"),
    ("train.py", "env.offset_range=5", "env.offset_range = 5 must be a list"),
    ("train.py", "actor.hidden=5", "actor.hidden = 5 must be a list of layer widths"),
    ("train.py", "link.k_a=1.5", "link.k_a = 1.5 is out of range; allowed [0, 1]"),
    ("evaluate.py", "link.power_w=-1", "link.power_w = -1 is out of range; allowed (0, 1000] W"),
    (
        "evaluate.py",
        "env.wind=8",
        "env.wind = 8 is not where evaluate.py takes its points; each scenario sets its own: "
        "scenarios.S1.wind, scenarios.S3.winds",
    ),
]


@pytest.mark.parametrize("script,override,message", CASES, ids=[f"{s}:{o}" for s, o, _ in CASES])
def test_a_rejected_command_line_is_one_line_and_leaves_the_output_root_as_it_was(script, override, message, bad_files):
    if "cuda" in override and torch.cuda.is_available():
        pytest.skip("a CUDA device is present: env.device=cuda is valid here")
    before = tree(ROOT / "outputs")
    assert message in rejection(script, [override.format(**bad_files)])
    assert tree(ROOT / "outputs") == before


END_TO_END = [case for case in CASES if case[1] in ("link.k_a=1.5", "checkpoint={truncated}")]


@pytest.mark.parametrize("script,override,message", END_TO_END, ids=[f"{s}:{o}" for s, o, _ in END_TO_END])
def test_a_rejected_command_exits_non_zero_with_one_line_on_stderr(script, override, message, bad_files):
    before = tree(ROOT / "outputs")
    done = run_scripts.run(script, override.format(**bad_files), timeout=120)
    assert done.returncode == 1
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], done.stderr
    assert tree(ROOT / "outputs") == before


@pytest.mark.parametrize(
    ("argv", "line"),
    [
        (["env.wind=12", "env.wind_range=[4,20]"], "error: env.wind = 12 and env.wind_range = [4, 20] are both set; "),
        (["env.wind=12", "env.sea.wind=8"], "error: env.wind = 12 and env.sea.wind = 8 disagree; env.wind sets env.se"),
        (["-m", "env.offset=0.1,0.3", "env.offset_values=[0.2]"], "error: env.offset = 0.1 and env.offset_values = "),
    ],
)
def test_an_operating_point_given_twice_is_one_line_and_writes_nothing(argv, line, tmp_path):
    before = tree(ROOT / "outputs")
    assert rejection("train.py", [*argv, f"hydra.run.dir={tmp_path}/run"]).startswith(line)
    assert tree(ROOT / "outputs") == before and not any(tmp_path.iterdir())


def test_a_sweep_is_checked_job_by_job_before_it_starts():
    assert jobs(["-m", "env.sea.wind=8,12", "agent=td3"]) == [
        ["env.sea.wind=8", "agent=td3"],
        ["env.sea.wind=12", "agent=td3"],
    ]
    assert jobs(["env.sea.wind=8"]) == [["env.sea.wind=8"]]


@pytest.mark.parametrize(
    ("argv", "line"),
    [
        (["-m", "env.fetch=1e4,2e4"], "error: env.fetch is env.sea.fetch in this version (env.fetch=1e4,2e4 → env.sea"),
        (["+env.aperture_diameter=0.1"], "error: env.aperture_diameter is env.optics.aperture_diameter in this versi"),
        (["env.lattice_nodes=5"], "error: env.lattice_nodes is env.channel.nodes in this version"),
        (["env.channel=single_path"], "error: env.channel=single_path: the channel is a config group now; write en"),
        (["env/spectrum=ocean"], "error: env/spectrum=ocean is not an option of env/spectrum; choose one of elfouha"),
    ],
)
def test_a_key_of_the_first_releases_is_one_line_naming_todays(argv, line):
    assert rejection("train.py", argv).startswith(line)
    assert rejection("evaluate.py", argv).startswith(line)


def test_todays_keys_and_unknown_ones_are_not_taken_for_old_ones():
    check_renamed(["env.sea.wind=3", "envx.wind=1", "env/channel=single_path", "env.channel.nodes=5"])
    assert rejection("train.py", ["env.windy=3"]) == (
        "error: env.windy is not a config key (check the spelling; every key is in docs/training.md)"
    )
    assert rejection("train.py", ["env.sea.gamma=2", "env/spectrum=elfouhaily"]) == (
        "error: env.sea.gamma is not a key of the chosen option; env/spectrum=jonswap has it (choose one, or leave "
        "env.sea.gamma out)"
    )


@pytest.mark.parametrize("reward", ["le", "pointing"])
def test_a_reward_coefficient_is_a_key_of_every_reward_that_uses_it_and_one_line_under_another(reward):
    for jobs_argv in (["reward.a=5", "reward.b=50", "reward.c=0.5"], ["-m", "reward.a=5,10", "agent.gamma=0,0.9"]):
        preflight("config", [f"reward={reward}", *jobs_argv], training.check)  # returns: every job is valid
    for other in ("snr", "linear", "log"):
        assert rejection("train.py", [f"reward={other}", "reward.a=5"]) == (
            "error: reward.a is not a key of the chosen option; reward=le, reward=pointing have it (choose one, or "
            "leave reward.a out)"
        )


def test_hydra_messages_become_one_line():
    error = ValueError("In 'config': Could not find 'agent/sac'\n\n"
                       "Available options in 'agent':\n\tddpg\n\tppo\n\ttd3\n"
                       "Config search path:\n\tprovider=hydra")  # fmt: skip
    assert one_line(error) == "agent=sac is not an option of agent; choose one of ddpg, ppo, td3"
    assert one_line(ValueError("Could not override 'env.wnd'.\nTo append use +env.wnd=3")).startswith(
        "env.wnd is not a config key"
    )


def stub(folder, name, output="", status=0):
    """An executable ``folder/name`` that prints ``output`` and exits with ``status`` (a Slurm command)."""
    path = folder / name
    path.write_text(f"#!/bin/sh\nprintf '{output}'\nexit {status}\n")
    path.chmod(0o755)


SLURM = ["-m", "seed=0,1", "hydra/launcher=submitit_slurm"]
REFUSED = "sbatch: error: Batch job submission failed: Requested node configuration is not available\\n"
LAUNCHES = [
    (
        ["hydra.launcher.partition=gpux"],
        {"sinfo": "debug\\ngpu\\n"},
        "error: hydra.launcher.partition = 'gpux' is not a partition of this cluster; choose one of debug, gpu",
    ),
    (
        ["hydra.launcher.partition=gpu"],
        {"sinfo": "debug\\ngpu\\n"},
        "error: hydra/launcher=submitit_slurm needs Slurm's sbatch",
    ),
    ([], {"sbatch": (REFUSED, 1), "srun": ""}, "error: sbatch --test-only refused: sbatch: error: Batch job"),
    (["hydra.launcher.cpus_per_task=0"], {}, "error: hydra.launcher.cpus_per_task = 0 is out of range"),
    (["hydra.launcher.cpus_per_tsk=2"], {}, "error: hydra.launcher.cpus_per_tsk is not a config key"),
    (["agent.gamma=interval(0,0.5)"], {}, "error: agent.gamma=interval(0,0.5): only hydra/sweeper=optuna samples"),
]
"""Launch problems, each with the Slurm commands on PATH (what they print, their exit status) and its line."""


@pytest.mark.parametrize("overrides,commands,message", LAUNCHES, ids=[" ".join(c[0]) or "sbatch" for c in LAUNCHES])
def test_a_sweep_the_cluster_cannot_run_is_refused_in_one_line(overrides, commands, message, tmp_path, monkeypatch):
    for name, answer in commands.items():
        stub(tmp_path, name, *(answer if isinstance(answer, tuple) else (answer,)))
    monkeypatch.setenv("PATH", str(tmp_path))  # the stubs, and no other Slurm command
    before = tree(ROOT / "outputs")
    with pytest.raises(SystemExit) as stop:
        preflight("config", [*SLURM, *overrides], training.check)
    assert str(stop.value.code).startswith(message) and "\n" not in str(stop.value.code)
    assert tree(ROOT / "outputs") == before


def test_a_missing_launcher_package_is_named_with_what_to_install(monkeypatch):
    monkeypatch.setattr(launch, "find_spec", lambda name: None)
    with pytest.raises(SystemExit) as stop:
        preflight("config", SLURM, training.check)
    assert str(stop.value.code).startswith("error: hydra/launcher=submitit_slurm needs the package submitit")
    error = ValueError("In 'hydra/config': Could not find 'hydra/sweeper/optuna'\n\nAvailable options in "
                       "'hydra/sweeper':\n\tbasic\n\tgrid\nConfig search path:\n\tprovider=hydra")  # fmt: skip
    assert one_line(error).startswith("hydra/sweeper=optuna needs the package optuna")


def test_a_slurm_sweep_asking_for_cuda_is_checked_on_a_cpu_here_and_a_search_at_its_ends():
    # The jobs' machines have the GPU, not this one: device=cuda passes here and is checked in each job.
    assert on_a_cpu(compose_config("config", ["device=cuda"])).env.device == "cpu"
    search = ["-m", "hydra/sweeper=optuna", "agent.gamma=interval(0,0.5)", "env/sea=choice(calm,rough)"]
    assert [job[1:] for job in jobs(search, None, search=True)] == [
        ["agent.gamma=0.0", "env/sea=calm"],
        ["agent.gamma=0.5", "env/sea=calm"],
        ["agent.gamma=0.0", "env/sea=rough"],
    ]


def test_the_dependencies_messages_are_silenced_by_name_and_no_other():
    logger, seen_records = logging.getLogger("torch._dynamo.variables.ctx_manager"), []
    handler = logging.Handler()
    handler.emit = seen_records.append
    logger.addHandler(handler)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        quiet_dependencies()
        warnings.warn(
            "torch._dynamo.config.inline_inbuilt_nn_modules is deprecated and does nothing", FutureWarning, stacklevel=1
        )
        warnings.warn("torch._dynamo.config.another_option is deprecated", FutureWarning, stacklevel=1)
        logger.warning("Profiler record function %s will be ignored", "record_function")
        logger.warning("Graph break: something to look at")
    logger.removeHandler(handler)
    assert [str(w.message) for w in seen] == ["torch._dynamo.config.another_option is deprecated"]
    assert [record.getMessage() for record in seen_records] == ["Graph break: something to look at"]


@pytest.mark.slow
def test_jobs_sbatch_refuses_after_the_checks_are_one_line_and_leave_no_sweep_folder(tmp_path):
    # The scheduler accepts the test submission but refuses the array itself (e.g. a limit on array sizes).
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    refusal = "sbatch: error: Batch job submission failed: Invalid job array specification"
    (bin_dir / "sbatch").write_text(f'#!/bin/sh\n[ "$1" = --test-only ] && exit 0\necho "{refusal}" >&2\nexit 1\n')
    (bin_dir / "sbatch").chmod(0o755)
    stub(bin_dir, "srun")
    sweep = tmp_path / "sweep"
    env = {"PATH": f"{bin_dir}:/usr/bin:/bin", "HOME": str(tmp_path)}
    done = run_scripts.run("train.py", *SLURM, f"hydra.sweep.dir={sweep}", env=env)
    assert done.returncode == 1, done.stderr[-3000:]
    assert done.stderr.strip().splitlines() == [f"error: the scheduler refused the jobs: {refusal}"]
    assert not sweep.exists()


def documented_commands() -> list[tuple[str, list[str]]]:
    """Each ``train.py``/``evaluate.py`` line of the README's and docs/training.md's code blocks: (script, its
    arguments), the comment after ``#`` dropped."""
    import shlex

    found = []
    for path in (ROOT / "README.md", ROOT / "docs" / "training.md"):
        blocks = path.read_text().replace("\\\n", " ").split("```")[1::2]  # the code blocks, continued lines joined
        for line in (line for block in blocks for line in block.splitlines() if ".py " in line):
            words = shlex.split(line, comments=True)
            script = next((word for word in words if word in ("train.py", "evaluate.py")), None)
            if script is not None and (script, words[words.index(script) + 1 :]) not in found:
                found.append((script, words[words.index(script) + 1 :]))
    return found


COMMANDS = documented_commands()


@pytest.mark.parametrize(("script", "argv"), COMMANDS, ids=[" ".join([s, *a]) for s, a in COMMANDS])
def test_every_documented_command_line_passes_the_checks_as_printed(script, argv):
    """Every key and value of the documented lines, checked as the script checks them before it runs. A run
    directory written DATE/TIME names no real run (resume and run= are tested on runs of their own), and a Slurm
    launcher needs a cluster (make slurm-check): those arguments are left out, the rest checked as printed."""
    from waterair.cli import evaluation

    left_out = ("DATE/TIME", "submitit_slurm", "hydra.launcher.")
    kept = [arg for arg in argv if not any(part in arg for part in left_out)]
    check = {"train.py": training.check, "evaluate.py": evaluation.check}[script]
    preflight({"train.py": "config", "evaluate.py": "evaluate"}[script], kept, check)  # returns: it would run


def test_the_documented_commands_include_the_ones_the_project_is_used_by():
    lines = {" ".join([script, *argv]) for script, argv in COMMANDS}
    assert "train.py env.wind=12 reward.a=5" in lines
    assert "train.py -m agent.gamma=0,0.9 reward.a=5,10 env.wind=4,12,20 hydra/launcher=joblib" in lines


def test_make_trains_first_look_is_s1_and_s5s_headline_points_of_the_whole_study():
    from waterair.cli import evaluation

    first, whole = compose_config("evaluate", ["+study=first_run"]), compose_config("evaluate")
    assert [name for name, scenario in first.scenarios.items() if scenario is not None] == ["S1", "S5"]
    assert first.scenarios.S1 == whole.scenarios.S1 and first.scenarios.S5.offset_ratios == [0.1]
    assert first.scenarios.S5.winds == whole.scenarios.S5.winds  # the headline rates at 4, 12 and 20 m/s
    assert {"tracking", "beacon_tracker", "aoa_tracker", "intensity_dither"} <= set(first.baselines)
    assert set(first.baselines) < set(whole.baselines)
    assert "evaluate.py run=$(RUN) hydra.run.dir=$(RUN)/evaluation +study=first_run" in (ROOT / "Makefile").read_text()
    preflight("evaluate", ["+study=first_run"], evaluation.check)  # returns: it runs
