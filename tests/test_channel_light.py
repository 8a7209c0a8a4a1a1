"""What pointings make of the light (docs/model.md §4.4-§4.5): the upper bound against a brute-force search."""

import torch
from conftest import F64, ends
from test_channel_two_scale import two_scale

from waterair.physics.channel import Transceiver, pointing, received_gain, upper_bound
from waterair.physics.sea import sea_state
from waterair.physics.surface import WaveSurface

OPTICS = Transceiver()


def test_upper_bound_is_within_one_percent_of_a_brute_force_search():
    """Over a 4-D grid of pointings around the bound's own (±1.5 ω_D, ±0.1 rad), nothing beats the
    bound by more than 1 %, and the bound's pointings give the bound."""
    surface = WaveSurface.sample(sea_state(wind=20.0, spectrum="elfouhaily", n_dir=16), 8, seed=2, dtype=F64)
    tx, rx = ends(0.5, 8)
    light = two_scale(surface, tx, rx, 4.0, OPTICS)
    bound, best_tx, best_rx = upper_bound(light, OPTICS)
    torch.testing.assert_close(received_gain(light, best_tx, best_rx, OPTICS), bound)
    steps = torch.linspace(-1.0, 1.0, 7, dtype=F64)
    offsets = torch.cartesian_prod(steps, steps)  # [49, 2]
    tilt_tx = best_tx[:, None, :2] + 1.5 * OPTICS.divergence * offsets  # tilts are horizontal components
    tilt_rx = best_rx[:, None, :2] + 0.1 * offsets
    best = torch.zeros_like(bound)
    for i in range(offsets.shape[0]):
        tx_dir = pointing(tilt_tx[:, i], up=True)
        rx_dir = pointing(tilt_rx, up=False)
        gains = torch.stack([received_gain(light, tx_dir, rx_dir[:, j], OPTICS) for j in range(offsets.shape[0])], 1)
        best = torch.maximum(best, gains.max(1).values)
    assert (best <= bound * 1.01).all()
    assert (bound > 0).all()
