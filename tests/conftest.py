"""Shared fixtures and helpers: the default geometry as tensors, Hydra configs composed from conf/."""

from pathlib import Path

import pytest
import torch
from hydra import compose, initialize_config_dir

from waterair.physics.channel import LinkGeometry

ROOT = Path(__file__).resolve().parents[1]
"""The repository root (where train.py, evaluate.py and conf/ live)."""


def compose_config(name: str, overrides=(), **kwargs):
    """``conf/NAME.yaml`` composed with ``overrides``, as train.py / evaluate.py would see it."""
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        return compose(config_name=name, overrides=list(overrides), **kwargs)


@pytest.fixture
def default_positions():
    """T and R of the default link (10 m deep, 10 m high, 10 % offset) in float64."""
    return LinkGeometry().positions(torch.float64)
