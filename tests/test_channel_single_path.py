"""The paper's channel (docs/model.md §0, §4.1): link geometry, the gain, the SinglePath model's one ray
and its bound, the calm-sea reference."""

import math

import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from waterair.physics.channel import (
    LinkEnds,
    LinkGeometry,
    SinglePath,
    Transceiver,
    calm_sea_gain,
    channel_gain,
    pointing,
)
from waterair.physics.paths import flat_sea_point, solve_path
from waterair.physics.sea import sea_state
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
    surface = WaveSurface.sample(sea_state("jonswap", wind=12.0), batch, seed=seed, dtype=torch.float64)
    return solve_path(surface, tx, rx, 2.0)


def received(path, tx_dir, rx_dir, optics=None):
    """The SinglePath model's reception of ``path`` for pointings ``[B, 3]``."""
    model = SinglePath(optics or Transceiver())
    tx, rx = LinkGeometry().positions(torch.float64)
    tx, rx = tx.expand_as(path.point), rx.expand_as(path.point)
    ends = LinkEnds(tx, rx, flat_sea_point(tx, rx))
    light = model.light(None, path, ends, torch.zeros(path.point.shape[0], dtype=torch.float64), {})
    return model.receive(light, tx_dir, rx_dir)


def test_aligned_pointing_reaches_the_upper_bound():
    path = aligned_and_random()
    optics = Transceiver()
    gain = channel_gain(path, path.departure, -path.arrival, optics)
    reception = received(path, path.departure, -path.arrival)
    torch.testing.assert_close(gain.gain, reception.upper_bound)
    assert torch.all(gain.departure[path.valid] == 1.0)
    # the best pointing is the path, and the bound is the paper's G_UB = G_p G_ref n_c² / sin² ω_A
    assert torch.equal(reception.departure, path.departure) and torch.equal(reception.arrival, path.arrival)
    peak = optics.concentrator_index**2 / math.sin(optics.half_fov) ** 2
    torch.testing.assert_close(reception.upper_bound, gain.path * gain.refraction * peak, rtol=1e-15, atol=0)


def test_the_single_path_model_is_the_papers_gain_bit_for_bit():
    """One ray weighted G_p G_ref, read through the shared readout, is eq. (1) to the last bit."""
    path = aligned_and_random(batch=64, seed=3)
    tilt = 0.3 * torch.randn(64, 4, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    tx_dir, rx_dir = pointing(tilt[:, :2], up=True), pointing(tilt[:, 2:], up=False)
    gain = channel_gain(path, tx_dir, rx_dir, Transceiver())
    reception = received(path, tx_dir, rx_dir)
    assert gain.gain.max() > 0
    assert torch.equal(reception.gain, gain.gain)
    assert torch.equal(reception.alpha_d, gain.alpha_d) and torch.equal(reception.alpha_a, gain.alpha_a)
    # the detector reads the path's arrival wherever it falls within the field of view, lit or not
    assert torch.equal(reception.lit, gain.arrival > 0) and torch.equal(reception.spot_arrival, path.arrival)


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
    assert torch.all(gain.gain <= received(path, tx_dir, rx_dir, optics).upper_bound * (1 + 1e-12))
    assert torch.all(torch.isfinite(gain.gain)) and torch.all(gain.gain >= 0)


def test_invalid_paths_have_zero_gain():
    path = aligned_and_random(batch=8)
    path.valid[:] = False
    optics = Transceiver()
    reception = received(path, path.departure, -path.arrival, optics)
    assert torch.all(reception.upper_bound == 0) and not reception.valid.any()
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
