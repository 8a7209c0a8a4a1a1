"""Atomic writes: the target holds the old content or the new, never a part, and no temp file is left."""

import json
import math

import pytest
import torch

from waterair.core.files import atomic_write, atomic_write_csv, atomic_write_json, atomic_write_text


def test_a_failed_write_keeps_the_old_file_and_leaves_no_temp_file(tmp_path):
    target = atomic_write_text(tmp_path / "state.txt", "old")

    def half_then_fail(handle):
        handle.write(b"new, but only ha")
        raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        atomic_write(target, half_then_fail)
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["state.txt"]


def test_text_json_csv_and_torch_round_trip(tmp_path):
    atomic_write_json(tmp_path / "m.json", {"a": 1.5})
    assert json.loads((tmp_path / "m.json").read_text()) == {"a": 1.5}
    atomic_write_csv(tmp_path / "m.csv", ["x", "y"], [{"x": 1, "y": 2, "ignored": 3}, {"x": 4}])
    assert (tmp_path / "m.csv").read_text().splitlines() == ["x,y", "1,2", "4,"]
    atomic_write(tmp_path / "t.pt", lambda handle: torch.save({"w": torch.arange(3)}, handle))
    assert torch.equal(torch.load(tmp_path / "t.pt", weights_only=True)["w"], torch.arange(3))


def test_json_records_are_one_line_each_and_read_back_as_written(tmp_path):
    data = {"schema_version": 6, "link": {"power_w": 0.05}, "rows": [{"a": 1.5, "b": float("nan")}, {"a": 2, "b": "x"}]}
    path = atomic_write_json(tmp_path / "m.json", data, records=True)
    lines = path.read_text().splitlines()
    assert '    {"a":1.5,"b":NaN},' in lines and '    {"a":2,"b":"x"}' in lines
    back = json.loads(path.read_text())
    assert back["rows"][1] == data["rows"][1] and back["link"] == data["link"] and math.isnan(back["rows"][0]["b"])
