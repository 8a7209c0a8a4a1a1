"""The training benchmark's plumbing: ``--override`` reaches every run it times, SB3's included.

The runs themselves are minutes long and measured by ``python -m waterair.bench training``; here each is
replaced by a recorder, so what is checked is which configuration each would have run.
"""

import contextlib

import pytest

from waterair.bench import __main__ as cli
from waterair.bench import training


@pytest.fixture
def recorded(monkeypatch):
    calls: dict[str, list] = {"train": [], "sb3": []}

    def train_run(frames, overrides):
        calls["train"].append(list(overrides))
        return {"loop_frames_per_s": 100.0, "frames": frames}

    def bench_sb3(frames, updates_per_frame, overrides=None):
        calls["sb3"].append(list(overrides or []))
        return {"frames": frames, "updates_per_frame": updates_per_frame, "frames_per_s": 50.0}

    monkeypatch.setattr(training, "train_run", train_run)
    monkeypatch.setattr(training, "bench_sb3", bench_sb3)
    monkeypatch.setattr(training, "bench_update", lambda updates: {"bare_ms": 1.0})
    monkeypatch.setattr(training, "busy_process", contextlib.nullcontext)
    return calls


def test_every_timed_run_and_sb3_get_the_overrides(recorded):
    record = training.bench_training(1, 3200, 32000, 100, 1, load=True, overrides=("env/channel=single_path",))
    assert record["overrides"] == ["env/channel=single_path"]
    # short and long, eager and compiled, agent=ddpg, then quiet and loaded per thread setting
    assert len(recorded["train"]) >= 7
    assert all(run[0] == "env/channel=single_path" for run in recorded["train"])
    assert recorded["sb3"] and all(run == ["env/channel=single_path"] for run in recorded["sb3"])
    assert all(row["over_sb3"] == pytest.approx(2.0) for row in record["runs"])


def test_the_command_line_passes_repeated_overrides_in_order(monkeypatch, tmp_path):
    seen = {}

    def bench_training(*args):
        seen["overrides"] = args[-1]
        raise SystemExit(0)

    monkeypatch.setattr(cli, "bench_training", bench_training)
    with pytest.raises(SystemExit):
        cli.main(
            [
                "training",
                "--override",
                "env/channel=single_path",
                "--override",
                "seed=3",
                "--out",
                str(tmp_path / "t.json"),
            ]
        )
    assert seen["overrides"] == ("env/channel=single_path", "seed=3")
