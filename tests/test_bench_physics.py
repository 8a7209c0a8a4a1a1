"""The physics benchmark (``python -m waterair.bench physics``) runs on both seas and writes what docs/benchmarks.md,
"Physics", reads: it once failed at its start (a measured-slope sea built from the paper's with keys it lacks)."""

import torch

from waterair.bench.__main__ import main
from waterair.bench.physics import bench_physics
from waterair.physics import sea_state


def test_the_suite_times_both_seas_and_writes_each_round(tmp_path):
    record = bench_physics([2], [], 1, torch.device("cpu"), torch.float32, sea_state("jonswap", n_freq=8, n_dir=4))
    (row,) = record["rows"]
    assert row["batch"] == 2 and row["newton_cold_s"] > 0 and row["sincos_floor_s"] > 0 and row["ocean_eval_s"] > 0
    assert record["ocean_harmonics"] == 48 * 16  # env/spectrum=elfouhaily's bins (its defaults), at the suite's wind
    out = tmp_path / "physics.json"
    assert (
        main(["physics", "--sizes", "1", "--centroid-sizes", "--repeats", "1", "--rounds", "2", "--out", str(out)]) == 0
    )
    assert out.read_text().count('"batch": 1') == 2  # a row for each of the two rounds
