"""Shared fixtures: the default geometry as tensors."""

import pytest
import torch

from waterair.channel import LinkGeometry


@pytest.fixture
def default_positions():
    """T and R of the default link (10 m deep, 10 m high, 10 % offset) in float64."""
    return LinkGeometry().positions(torch.float64)
