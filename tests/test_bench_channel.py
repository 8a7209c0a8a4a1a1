"""The channel benchmark's lattice floor (``python -m waterair.bench channel``): what it counts, and the summary's
rows for the full channel's targets. The suite itself times minutes of compiled steps; here only its arithmetic
and what it assumes of the step."""

import json

import pytest
import torch

from waterair.bench import env as bench_env
from waterair.bench.summary import summary_lines
from waterair.envs.env import WaterAirEnv
from waterair.physics.channel import TwoScale, lattice


def test_a_full_channel_step_evaluates_the_lattices_the_floor_counts(monkeypatch):
    env = WaterAirEnv(num_envs=3, seed=0, channel={"name": "full", "nodes": 5}, compile_kernel=False)
    assert isinstance(env.channel, TwoScale)  # the defaults' sea: the full channel on lattices
    td = env.reset().set("action", torch.zeros(3, 4))
    evaluated = []
    real = lattice.two_scale_light

    def counted(sea, tx, rx, time, grid, blur, optics):
        evaluated.append(grid.nodes**2 * tx.shape[0])  # nodes of this lattice, over the links
        return real(sea, tx, rx, time, grid, blur, optics)

    monkeypatch.setattr(lattice, "two_scale_light", counted)
    env.step(td)
    assert sum(evaluated) == bench_env.LATTICES_PER_STEP * 5**2 * 3
    per_element = 1e-9
    floor = bench_env.lattice_floor(per_element, 3, env.channel.nodes, env.surface.num_harmonics)
    assert floor == pytest.approx(per_element * sum(evaluated) * env.surface.num_harmonics, rel=1e-12)


def rows(batch: int, rate: float, lattice_ratio: float, lattice_key: str = "") -> list[dict]:
    full = {"batch": batch, "channel": "full", "sea": "ocean", "lattice": lattice_key, "env_steps_per_s": rate}
    other = {"batch": batch, "channel": "single_path", "sea": "ocean", "lattice": "", "env_steps_per_s": 10 * rate}
    return [other, {**full, "lattice_floor_ratio": lattice_ratio}]


@pytest.mark.parametrize(
    ("compiled", "ratio", "target", "met"), [(True, 0.70, "≤ 0.35", "no"), (False, 1.2, "≤ 1.5", "yes")]
)
def test_the_summary_sets_the_defaults_step_against_the_lattice_floor(tmp_path, compiled, ratio, target, met):
    # another lattice's row (7:4) must not be taken for the defaults'
    record = {
        "compiled_kernel": compiled,
        "rows": [*rows(16, 5000.0, 9.9), *rows(1024, 8000.0, ratio), *rows(1024, 1.0, 0.01, "7:4")],
    }
    (tmp_path / "channel.json").write_text(json.dumps(record))
    mode = "compiled" if compiled else "eager"
    expected = [f"| full channel step / lattice sin+cos floor, B = 1024, {mode} | {ratio:.2f} | {target} | {met} |"]
    if compiled:
        expected.append("| full channel env-steps/s, B = 16 / B = 1024, compiled | 0.62 | ≥ 0.4 | yes |")
    assert summary_lines(tmp_path)[2:] == expected


def test_the_summary_judges_the_median_of_three_rounds_and_says_so(tmp_path):
    """Three rounds of the channel suite, one of them over the target: the median meets it, the spread is shown, and
    a line says what was judged; a suite of one round beside them is shown as measured."""
    record = {"rounds": [{"compiled_kernel": True, "rows": [*rows(16, 5000.0, 9.9), *rows(1024, 8000.0, ratio)]}
                         for ratio in (0.30, 0.40, 0.33)]}  # fmt: skip
    (tmp_path / "channel.json").write_text(json.dumps(record))
    lines = summary_lines(tmp_path)
    name = "full channel step / lattice sin+cos floor, B = 1024, compiled"
    assert lines[2] == f"| {name} | 0.33 (median of 3; 0.30–0.40) | ≤ 0.35 | yes |"
    assert lines[-1] == "Judged on the median of 3 rounds, each a whole run of its suite."
    record["rounds"][2]["rows"] = [*rows(16, 5000.0, 9.9), *rows(1024, 8000.0, 0.38)]  # now the median fails
    (tmp_path / "channel.json").write_text(json.dumps(record))
    assert summary_lines(tmp_path)[2] == f"| {name} | 0.38 (median of 3; 0.30–0.40) | ≤ 0.35 | no |"
