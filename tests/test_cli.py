"""Entry points a user can trust: a rejected command line exits with one line and writes nothing."""

import subprocess
import sys

import pytest
import torch
from conftest import ROOT

from waterair.cli.preflight import jobs, one_line

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
    ("train.py", "env.device=cuda", "env.device = 'cuda' is not available"),
    ("train.py", "resume={missing}", "does not exist"),
    ("train.py", "resume={tmp}", "is not a waterair run directory"),
    ("train.py", "agent=sac", "agent=sac is not an option of agent; choose one of ddpg, ppo, td3"),
    ("evaluate.py", "run={missing}", "is not a run directory"),
    ("evaluate.py", "checkpoint={random}", "is not a torch file"),
    ("evaluate.py", "checkpoint={truncated}", "is truncated or damaged"),
    ("evaluate.py", "+foo=1", "foo is not a config key"),
    ("train.py", "env.offset_range=5", "env.offset_range = 5 must be a list"),
    ("train.py", "actor.hidden=5", "actor.hidden = 5 must be a list of layer widths"),
    ("train.py", "link.k_a=1.5", "link.k_a = 1.5 is out of range; allowed [0, 1]"),
    ("evaluate.py", "link.power_w=-1", "link.power_w = -1 is out of range; allowed (0, 1000] W"),
]


@pytest.mark.parametrize("script,override,message", CASES, ids=[f"{s}:{o}" for s, o, _ in CASES])
def test_a_rejected_command_prints_one_line_and_leaves_the_output_root_as_it_was(script, override, message, bad_files):
    if "cuda" in override and torch.cuda.is_available():
        pytest.skip("a CUDA device is present: env.device=cuda is valid here")
    before = tree(ROOT / "outputs")
    done = subprocess.run(
        [sys.executable, script, override.format(**bad_files)], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert done.returncode != 0
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], done.stderr
    assert tree(ROOT / "outputs") == before


def test_a_sweep_is_checked_job_by_job_before_it_starts():
    assert jobs(["-m", "env.wind=8,12", "agent=td3"]) == [["env.wind=8", "agent=td3"], ["env.wind=12", "agent=td3"]]
    assert jobs(["env.wind=8"]) == [["env.wind=8"]]


def test_hydra_messages_become_one_line():
    error = ValueError("In 'config': Could not find 'agent/sac'\n\n"
                       "Available options in 'agent':\n\tddpg\n\tppo\n\ttd3\n"
                       "Config search path:\n\tprovider=hydra")  # fmt: skip
    assert one_line(error) == "agent=sac is not an option of agent; choose one of ddpg, ppo, td3"
    assert one_line(ValueError("Could not override 'env.wnd'.\nTo append use +env.wnd=3")).startswith(
        "env.wnd is not a config key"
    )
