"""Link geometry, channel gain, upper bound and calm-sea reference (docs/model.md §0, §4)."""

import math

import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from waterair.physics.channel import LinkGeometry, Transceiver, calm_sea_gain, channel_gain, gain_upper_bound, pointing
from waterair.physics.paths import solve_path
from waterair.physics.sea import SeaState
from waterair.physics.surface import WaveSurface


def test_positions_follow_the_spec():
    tx, rx = LinkGeometry(tx_depth=10, rx_height=10, offset_ratio=0.1, offset_azimuth_deg=90).positions(torch.float64)
    torch.testing.assert_close(tx, torch.tensor([0.0, 0.0, -10.0], dtype=torch.float64))
    torch.testing.assert_close(rx, torch.tensor([0.0, 2.0, 10.0], dtype=torch.float64), atol=1e-12, rtol=0)


def test_calm_sea_gain_matches_closed_form():
    """G_0 for normal incidence (no offset) is exp(−c h) / (h_t + h_r)² · T(0) / sin² ω_A."""
    optics = Transceiver()
    g0 = calm_sea_gain(LinkGeometry(offset_ratio=0.0), optics)
    want = math.exp(-0.151 * 10.0) / 20.0**2 * (1 - (0.33 / 2.33) ** 2) / math.sin(0.17) ** 2
    assert g0 == pytest.approx(want, rel=1e-12)
    assert calm_sea_gain(LinkGeometry(offset_ratio=0.3), optics) < g0


def aligned_and_random(batch=256, seed=0):
    tx, rx = LinkGeometry().positions(torch.float64)
    surface = WaveSurface.sample(SeaState(wind=12.0), batch, seed=seed, dtype=torch.float64)
    return solve_path(surface, tx, rx, 2.0)


def test_aligned_pointing_reaches_the_upper_bound():
    path = aligned_and_random()
    optics = Transceiver()
    gain = channel_gain(path, path.departure, -path.arrival, optics)
    torch.testing.assert_close(gain.gain, gain_upper_bound(path, optics))
    assert torch.all(gain.departure[path.valid] == 1.0)


@settings(max_examples=30, deadline=None)
@given(
    tilts=st.lists(st.floats(-0.7, 0.7), min_size=4, max_size=4),
    seed=st.integers(0, 1000),
)
def test_upper_bound_dominates_any_pointing(tilts, seed):
    path = aligned_and_random(batch=32, seed=seed)
    tilt = torch.tensor(tilts, dtype=torch.float64).expand(32, 4)
    tx_dir, rx_dir = pointing(tilt[:, :2], up=True), pointing(tilt[:, 2:], up=False)
    optics = Transceiver()
    gain = channel_gain(path, tx_dir, rx_dir, optics)
    assert torch.all(gain.gain <= gain_upper_bound(path, optics) * (1 + 1e-12))
    assert torch.all(torch.isfinite(gain.gain)) and torch.all(gain.gain >= 0)


def test_invalid_paths_have_zero_gain():
    path = aligned_and_random(batch=8)
    path.valid[:] = False
    optics = Transceiver()
    assert torch.all(gain_upper_bound(path, optics) == 0)
    assert torch.all(channel_gain(path, path.departure, -path.arrival, optics).gain == 0)


def test_pointing_vectors_are_unit_and_face_the_right_way():
    tilt = torch.tensor([[0.0, 0.0], [0.3, -0.4], [0.7, 0.0]], dtype=torch.float64)
    up, down = pointing(tilt, up=True), pointing(tilt, up=False)
    torch.testing.assert_close(up.norm(dim=-1), torch.ones(3, dtype=torch.float64))
    assert torch.all(up[:, 2] > 0) and torch.all(down[:, 2] < 0)


@pytest.mark.parametrize(
    "factory,kwargs,key",
    [
        (LinkGeometry, {"tx_depth": -1.0}, "tx_depth"),
        (LinkGeometry, {"rx_height": 0.0}, "rx_height"),
        (LinkGeometry, {"offset_ratio": -0.1}, "offset_ratio"),
        (Transceiver, {"half_fov": 0.0}, "half_fov"),
        (Transceiver, {"half_fov": 1.6}, "half_fov"),
        (Transceiver, {"divergence": -0.01}, "divergence"),
        (Transceiver, {"water": "lake"}, "water"),
    ],
)
def test_bad_link_parameters_name_key_value_and_range(factory, kwargs, key):
    with pytest.raises(ValueError) as info:
        factory(**kwargs)
    assert str(info.value).startswith(f"{key} = {next(iter(kwargs.values()))!r}")
