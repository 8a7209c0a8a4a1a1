"""scripts/cuda_check.py (``make cuda-check``), the parts that run without a GPU: how it tells a link that steered
apart from rounding, and its refusal where there is no CUDA device. The GPU parts run where there is one."""

import importlib.util
import sys

import pytest
import torch
from conftest import ROOT

SCRIPT = ROOT / "scripts" / "cuda_check.py"


def load_script():
    spec = importlib.util.spec_from_file_location("cuda_check", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def traces(steps: int, batch: int) -> dict[str, torch.Tensor]:
    generator = torch.Generator().manual_seed(0)
    shapes = {"observation": (steps, batch, 6), "path_valid": (steps, batch)}
    keys = load_script().COMPARED
    return {key: torch.rand(shapes.get(key, (steps, batch)), generator=generator) + 0.5 for key in keys}


def test_a_link_is_apart_when_an_output_differs_beyond_rounding_and_only_that_link():
    check = load_script()
    steps, batch = 5, 8
    want = traces(steps, batch)
    got = {key: value.clone() for key, value in want.items()}
    got["gain"][3, 2] *= 1 + 1e-6  # float32 rounding: not apart
    assert check.links_apart(got, want, steps, batch).sum() == 0
    got["observation"][4, 5, 1] += 1e-3 * want["observation"].abs().max()  # one reading of link 5
    assert check.links_apart(got, want, steps, batch).nonzero().flatten().tolist() == [5]


def test_without_a_cuda_device_it_says_so_in_one_line_and_exits_1(tmp_path, monkeypatch, capsys):
    check = load_script()
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)  # where there is a GPU the script runs
    out = tmp_path / "out"
    monkeypatch.setattr(sys, "argv", ["cuda_check", "--out", str(out)])
    with pytest.raises(SystemExit) as exit_:
        check.main()
    assert exit_.value.code == 1
    assert capsys.readouterr().err.strip().splitlines() == [
        "error: no CUDA device here (torch.cuda.is_available() is False); --device cpu: a dry run"
    ]
    assert not out.exists()  # nothing written before the refusal
