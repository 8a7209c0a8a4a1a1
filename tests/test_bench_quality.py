"""The time-to-quality benchmark's plumbing: what a run's seconds count, and how Stable-Baselines3's best time is
set against ours on each base.

The pipelines themselves run for minutes (``python -m waterair.bench quality``); here one tiny training run
shows what our time counts, and recorders stand in for the pipelines when the ratios are formed.
"""

import gc
import importlib.util
import json
import sys
import time

import pytest
import torch
from conftest import ONE_PATH, TINY

from waterair.bench import quality
from waterair.bench.common import COLLECTOR_OFF


def test_our_run_is_scored_at_each_checkpoint_and_ends_at_the_first_that_reaches_without_the_scorings(monkeypatch):
    from waterair.training import loop

    slowed = {"closing": 0, "scoring": 0}
    scores = iter([0.5, 0.99])  # the first checkpoint falls short of the target, the second reaches it

    def slower(name, function):  # the same function, 0.6 s later, counted
        return lambda *a, **k: slowed.update({name: slowed[name] + 1}) or time.sleep(0.6) or function(*a, **k)

    monkeypatch.setattr(loop, "final_evaluation", slower("closing", loop.final_evaluation))
    monkeypatch.setattr(quality, "score", slower("scoring", lambda cfg, policy: next(scores)))
    start = time.perf_counter()
    record = quality.ours(2000, 400, 0.9, [*ONE_PATH, *TINY])  # five batches of 400 frames at most
    wall = time.perf_counter() - start
    first, second = record["runs"]
    # scored at the first two checkpoints, then ended: a third scoring would have found no score left
    assert slowed == {"closing": 1, "scoring": 2} and (first["frames"], second["frames"]) == (400, 800)
    assert record["seconds_to_target"] == second["seconds"]
    # the loop up to the second checkpoint (environment, updates, about a second each batch) is counted; the
    # scorings and the closing evaluation (0.6 s each at least) are not
    assert 0.2 < first["seconds"] < second["seconds"] < wall - 1.8


@pytest.mark.parametrize("kind, module", [("ours", "waterair.training.loop"), ("sb3", "stable_baselines3")])
def test_a_pipelines_process_imports_what_it_runs_then_freezes_it_as_train_py_does(kind, module):
    """Its Python starts with the collector off; entering imports the pipeline's modules, moves what is alive out
    of the collector's walks and turns it on, so that the run's full collections walk only what the run makes."""
    assert quality.CHILD.startswith(COLLECTOR_OFF) and "gc.disable()" in COLLECTOR_OFF
    gc.disable()
    try:
        frozen = gc.get_freeze_count()
        quality.enter_child(kind)
        assert gc.isenabled() and gc.get_freeze_count() > frozen
        # Stable-Baselines3 is the bench extra's (make bench), not the tests'; where it is installed, it is imported
        assert module in sys.modules or importlib.util.find_spec(module) is None
    finally:
        gc.enable()


def in_this_process(monkeypatch):
    """Each pipeline called here rather than in a Python of its own, so that the fakes below stand in for it."""
    monkeypatch.setattr(quality, "in_fresh_python", lambda kind, *args: getattr(quality, kind)(*args))


def fake_runs(*seconds_and_ratios):
    runs = [{"frames": 1600 * (i + 1), "seconds": s, "ratio_to_ub": r} for i, (s, r) in enumerate(seconds_and_ratios)]
    return {"runs": runs, "seconds_to_target": quality._first_reaching(runs, 0.95)}


def test_sb3s_best_time_on_each_base_over_ours_and_a_lower_bound_where_none_reached(monkeypatch):
    ours = {"": fake_runs((10.0, 0.96)), "_flat_base": fake_runs((20.0, 0.90), (40.0, 0.97))}
    theirs = {
        ("sb3_ddpg", ""): fake_runs((100.0, 0.94), (300.0, 0.955)),
        ("sb3_ppo", ""): fake_runs((200.0, 0.96)),
        ("sb3_ddpg", "_flat_base"): fake_runs((500.0, 0.90)),
        ("sb3_ppo", "_flat_base"): fake_runs((800.0, 0.93)),
    }
    flat = tuple(quality.FLAT_BASE)

    def base_of(overrides) -> str:
        return "_flat_base" if set(flat) <= set(overrides) else ""

    def our_pipeline(frames, chunk, target, overrides):
        return ours[base_of(overrides)]

    in_this_process(monkeypatch)
    monkeypatch.setattr(quality, "ours", our_pipeline)
    monkeypatch.setattr(
        quality, "sb3", lambda name, frames, chunk, target, threads, overrides: theirs[name, base_of(overrides)]
    )
    record = quality.bench_quality(1600, 1600, 4800)
    assert record["sb3_over_ours"] == record["sb3_over_ours_ddpg"] == pytest.approx(200.0 / 10.0)  # PPO's 200 s
    assert record["sb3_flat_base_over_ours_flat_base_at_least"] == pytest.approx(500.0 / 40.0)
    assert record["sb3_flat_base_over_ours_ddpg_flat_base_at_least"] == pytest.approx(500.0 / 40.0)
    assert "sb3_flat_base_over_ours_flat_base" not in record and "sb3_over_ours_eager" not in record
    table = quality.quality_table(record)
    assert "| SB3's best median seconds / ours_flat_base's to 0.95 | | | at least 12.5 | |" in table
    assert "| sb3_ppo_flat_base | 0 | 1,600 | 800 | 0.930 |" in table


def test_every_pipeline_runs_once_per_seed_and_counts_the_median(monkeypatch):
    """Each seed reaches ours as train.py's ``seed`` and Stable-Baselines3's model as its seed; a pipeline's time is
    the median over its seeds, one that never reached counted as never; where SB3's median never reached, the
    median of each seed's seconds to the target or at the end of its budget bounds it from below."""
    ours_seconds = {0: (10.0, 0.96), 1: (30.0, 0.96), 2: (20.0, 0.90)}  # seed 2 never reaches: median 30
    their_seconds = {
        "sb3_ddpg": {0: (300.0, 0.96), 1: (600.0, 0.90), 2: (900.0, 0.90)},  # median: never
        "sb3_ppo": {0: (400.0, 0.90), 1: (500.0, 0.90), 2: (450.0, 0.96)},  # median: never
    }
    seen: list[tuple[str, int]] = []  # (pipeline, seed), in the order they ran

    def seed_of(overrides) -> int:
        (seed,) = (int(o.removeprefix("seed=")) for o in overrides if o.startswith("seed="))
        return seed

    def our_pipeline(frames, chunk, target, overrides):
        seen.append(("ours", seed_of(overrides)))
        return fake_runs(ours_seconds[seed_of(overrides)])

    def their_model(cfg, seed):  # what the real sb3() builds its model with; None: as if not installed
        seen.append((cfg.agent.name, seed))

    sb3 = quality.sb3

    def their_pipeline(name, frames, chunk, target, threads, overrides):
        assert sb3(name, frames, chunk, target, threads, overrides) is None
        return fake_runs(their_seconds[name][seed_of(overrides)])

    in_this_process(monkeypatch)
    monkeypatch.setattr(quality, "BASES", {"_flat_base": quality.FLAT_BASE})
    monkeypatch.setattr(quality, "OURS", {"ours": []})
    monkeypatch.setattr(quality, "SB3", {name: (f"agent={name[4:]}", their_model) for name in quality.SB3})
    monkeypatch.setattr(quality, "ours", our_pipeline)
    monkeypatch.setattr(quality, "sb3", their_pipeline)

    record = quality.bench_quality(1600, 1600, 4800, seeds=(0, 1, 2))
    # seed by seed, each seed's pipelines in turn, so that a drift of the machine's speed falls on all alike
    assert seen == [(pipeline, seed) for seed in (0, 1, 2) for pipeline in ("ours", "ddpg", "ppo")]
    assert [r["seed"] for r in record["ours_flat_base"]["by_seed"]] == [0, 1, 2]
    assert record["ours_flat_base"]["seconds_to_target"] == 30.0
    assert record["sb3_ddpg_flat_base"]["seconds_to_target"] is None
    assert record["sb3_ddpg_flat_base"]["seconds_at_least"] == 600.0
    assert record["sb3_ppo_flat_base"]["seconds_at_least"] == 450.0
    assert record["sb3_flat_base_over_ours_flat_base_at_least"] == pytest.approx(450.0 / 30.0)


@pytest.mark.parametrize("threads", [None, 1, "auto"])
def test_every_pipeline_runs_on_the_same_threads(monkeypatch, threads):
    """Ours through train.py's ``threads``, Stable-Baselines3's as torch's thread count while it builds and learns:
    the same count for both, by default every CPU the process may use (train.py's ``auto`` leaves one idle)."""
    import os

    from waterair.core.threads import choose_threads

    seen: dict[str, set] = {"ours": set(), "sb3": set()}

    def our_pipeline(frames, chunk, target, overrides):
        seen["ours"].update(int(o.removeprefix("threads=")) for o in overrides if o.startswith("threads="))
        return fake_runs((10.0, 0.96))

    def their_model(cfg, seed):  # what the real sb3() runs its model on
        seen["sb3"].add(torch.get_num_threads())

    sb3 = quality.sb3
    in_this_process(monkeypatch)
    monkeypatch.setattr(quality, "SB3", {name: ("agent=ddpg", their_model) for name in quality.SB3})
    monkeypatch.setattr(quality, "ours", our_pipeline)
    monkeypatch.setattr(quality, "sb3", lambda *args: sb3(*args) or fake_runs((100.0, 0.96)))
    before = torch.get_num_threads()
    record = quality.bench_quality(1600, 1600, 4800, ("compiled", "eager"), threads=threads)
    expected = len(os.sched_getaffinity(0)) if threads is None else choose_threads(threads)[0]
    assert seen == {"ours": {expected}, "sb3": {expected}} and record["threads"] == expected
    assert torch.get_num_threads() == before  # the caller's count restored


@pytest.mark.slow
def test_each_pipeline_runs_in_a_python_of_its_own_and_a_failing_one_is_named():
    """The suite's pipelines each start a fresh Python (a pipeline run after others in one process ran up to 17 %
    slower); one that fails there raises here, naming it, with the child's error."""
    with pytest.raises(RuntimeError, match=r"the time-to-quality pipeline nothing\(1,\) failed:\n(.|\n)*no "):
        quality.in_fresh_python("nothing", 1)


def test_the_summary_sets_our_best_pipeline_on_the_flat_base_against_the_target(tmp_path):
    """Each of our flat-base pipelines is listed; the best of them (the same rule as SB3's side: its best) is the
    one set against the target, a lower bound (SB3 never reached) counted as what it is."""
    from waterair.bench.summary import summary_lines

    to, target = "SB3's best seconds to 0.95 of the bound", "≥ 10 over ≥ 5 seeds, compiles included"
    record = {"target": 0.95, "seeds": [0, 1, 2, 3, 4], "sb3_flat_base_over_ours_flat_base": 0.8}
    record |= {"sb3_flat_base_over_ours_flat_base_eager": 3.0, "sb3_flat_base_over_ours_ddpg_flat_base_eager": 10.4}
    record["sb3_over_ours_ddpg_eager"] = 20.0
    (tmp_path / "quality.json").write_text(json.dumps(record))
    assert summary_lines(tmp_path)[2:] == [
        f"| {to} / ours_flat_base's | 0.8 | – | – |",
        f"| {to} / ours_flat_base_eager's | 3.0 | – | – |",
        f"| {to} / ours_ddpg_flat_base_eager's | 10.4 | – | – |",
        f"| {to} / our best pipeline's (ours_ddpg_flat_base_eager) | 10.4 (5 seeds) | {target} | yes |",
    ]
    record = {"target": 0.95, "seeds": [0, 1, 2, 3, 4, 5], "sb3_flat_base_over_ours_flat_base_at_least": 9.0}
    record["sb3_flat_base_over_ours_ddpg_flat_base"] = 2.0
    (tmp_path / "quality.json").write_text(json.dumps(record))
    assert summary_lines(tmp_path)[-1] == (
        f"| {to} / our best pipeline's (ours_flat_base) | at least 9.0 (6 seeds) | {target} | no |"
    )


@pytest.mark.parametrize("seeds", [[0], [0, 1, 2, 3]])
def test_the_summary_leaves_the_target_unjudged_over_fewer_than_five_seeds(tmp_path, seeds):
    """A ratio over one seed, or a few, is shown with their count and not judged either way (three seeds of one code
    read 10.5x where five read 7.4x); a record from before the seeds key counts as one seed."""
    from waterair.bench.summary import summary_lines

    record = {"target": 0.95, "seeds": seeds, "sb3_flat_base_over_ours_ddpg_flat_base_eager": 10.4}
    (tmp_path / "quality.json").write_text(json.dumps(record))
    count = "1 seed" if len(seeds) == 1 else f"{len(seeds)} seeds"
    assert summary_lines(tmp_path)[-1].endswith(f"| 10.4 ({count}) | ≥ 10 over ≥ 5 seeds, compiles included | – |")
    del record["seeds"]
    (tmp_path / "quality.json").write_text(json.dumps(record))
    assert summary_lines(tmp_path)[-1].endswith("| 10.4 (1 seed) | ≥ 10 over ≥ 5 seeds, compiles included | – |")


def test_the_suite_runs_only_the_pipelines_and_bases_asked_for(monkeypatch):
    """``--pipelines`` and ``--bases`` choose some of the pipelines (the flat-base DDPG pair alone, as a target's
    re-measurement wants it), their ratio formed as in the whole suite; a name that is neither is refused, naming
    the known ones."""
    ran: list[tuple] = []

    def our_pipeline(frames, chunk, target, overrides):
        ran.append(("ours", "agent=ddpg" in overrides, "env.residual_base=flat_snell" in overrides))
        return fake_runs((10.0, 0.96))

    def their_pipeline(name, frames, chunk, target, threads, overrides):
        ran.append((name, "env.residual_base=flat_snell" in overrides))
        return fake_runs((120.0, 0.96))

    in_this_process(monkeypatch)
    monkeypatch.setattr(quality, "ours", our_pipeline)
    monkeypatch.setattr(quality, "sb3", their_pipeline)
    record = quality.bench_quality(
        1600, 1600, 4800, ("eager",), seeds=(0, 1), pipelines=["ours_ddpg", "sb3_ddpg"], bases=["flat_base"]
    )
    assert ran == [("ours", True, True), ("sb3_ddpg", True)] * 2  # seed by seed
    runs = {key for key, value in record.items() if isinstance(value, dict) and "by_seed" in value}
    assert runs == {"ours_ddpg_flat_base_eager", "sb3_ddpg_flat_base"}
    assert record["sb3_flat_base_over_ours_ddpg_flat_base_eager"] == pytest.approx(12.0)
    assert record["pipelines"] == ["ours_ddpg", "sb3_ddpg"] and record["bases"] == ["flat_base"]
    with pytest.raises(
        ValueError, match="no time-to-quality pipeline sb3_td3: one of ours, ours_ddpg, sb3_ddpg, sb3_ppo"
    ):
        quality.bench_quality(1600, 1600, 4800, pipelines=["sb3_td3"])
    with pytest.raises(ValueError, match="no time-to-quality base flat: one of default, flat_base"):
        quality.bench_quality(1600, 1600, 4800, bases=["flat"])


@pytest.mark.parametrize("installed", [False, True])
def test_the_suite_says_first_when_stable_baselines3_is_missing(monkeypatch, capsys, tmp_path, installed):
    """Without Stable-Baselines3 (it is the ``bench`` extra, not a dependency) the quality suite's first line says
    that its rows are left out and how to install it; with it, no such line."""
    from waterair.bench import __main__ as cli

    monkeypatch.setattr(cli, "sb3_installed", lambda: installed)
    in_this_process(monkeypatch)
    monkeypatch.setattr(quality, "ours", lambda frames, chunk, target, overrides: fake_runs((10.0, 0.96)))
    monkeypatch.setattr(quality, "sb3", lambda name, *args: fake_runs((100.0, 0.96)) if installed else None)
    assert cli.main(["quality", "--frames", "1600", "--flat-frames", "1600", "--out", str(tmp_path / "q.json")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert (lines[0] == cli.SB3_MISSING) is (not installed)
    assert "pip install -e '.[bench]'" in cli.SB3_MISSING
    record = json.loads((tmp_path / "q.json").read_text())
    assert len(record["rounds"]) == 3  # the suite's default: three whole runs in turn, the summary their median
    ratios = [[key for key in each if "_over_" in key] for each in record["rounds"]]
    assert all(bool(each) is installed for each in ratios)
