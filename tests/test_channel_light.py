"""What pointings make of the light (docs/model.md §4.4-§4.5): the upper bound against a brute-force search."""

import torch
from conftest import F64, ends
from test_channel_two_scale import two_scale

from waterair.physics.channel import LightSamples, Transceiver, pointed_gains, pointing, received_gain, upper_bound
from waterair.physics.channel.light import joined, paper_gains, repeated, sliced
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


def test_a_rays_gains_from_sines_and_cosines_are_the_papers_of_the_angles():
    """pointed_gains (G_D and G_A of the angles' sines and cosines, as the bound's ascent evaluates them) against
    paper_gains (eqs. (2) and (5) of the angles, the paper's one path bit for bit) on the two-scale light's nodes
    as rays, at pointings across the beam and the field of view's edge: equal within float64 rounding."""
    surface = WaveSurface.sample(sea_state(wind=12.0, spectrum="elfouhaily", n_dir=16), 8, seed=3, dtype=F64)
    tx, rx = ends(0.5, 8)
    light = two_scale(surface, tx, rx, 2.0, OPTICS)
    rays = LightSamples(weight=light.weight, departure=light.departure, arrival=light.arrival)
    _, best_tx, best_rx = upper_bound(rays, OPTICS)
    for offset in (0.0, OPTICS.divergence, 0.3 * OPTICS.half_fov, 1.2 * OPTICS.half_fov):
        tx_dir = pointing(best_tx[:, :2] + offset, up=True)
        rx_dir = pointing(best_rx[:, :2] + offset, up=False)
        paper = paper_gains(rays, tx_dir, rx_dir, OPTICS)
        torch.testing.assert_close(pointed_gains(rays, tx_dir, rx_dir, OPTICS), paper, rtol=1e-12, atol=1e-300)
        if offset < OPTICS.half_fov:
            assert (paper.sum(-1) > 0).all()


def test_the_bound_with_a_divergence_per_link_is_each_links_own_bound():
    """The bound's ascent runs its two starts for all links in one batch: with a divergence per link (5 to 80 mrad)
    each link's bound and pointings are what the link alone, with its divergence as a number, gives (float64)."""
    surface = WaveSurface.sample(sea_state(wind=12.0, spectrum="elfouhaily", n_dir=16), 6, seed=4, dtype=F64)
    tx, rx = ends(0.5, 6)
    light = two_scale(surface, tx, rx, 3.0, OPTICS)
    divergences = torch.tensor([0.005, 0.01, 0.02, 0.04, 0.06, 0.08], dtype=F64)
    together = upper_bound(light, Transceiver(divergence=divergences))
    for link, divergence in enumerate(divergences.tolist()):
        alone = upper_bound(sliced(light, slice(link, link + 1)), Transceiver(divergence=divergence))
        for got, expected in zip(together, alone, strict=True):
            torch.testing.assert_close(got[link : link + 1], expected, rtol=1e-12, atol=1e-300)
    assert len({round(value, 12) for value in together[0].tolist()}) == 6  # the divergences made a difference


def test_joined_sliced_and_repeated_light_is_the_sum_of_its_parts():
    """The gain of light joined side by side is the sum of its parts' gains; slicing the samples back gives each
    part; repeating the links repeats each link's gain; a part without cells leaves the joined light without."""
    surface = WaveSurface.sample(sea_state(wind=12.0, spectrum="elfouhaily", n_dir=16), 4, seed=2, dtype=F64)
    tx, rx = ends(0.3, 4)
    lattice = two_scale(surface, tx, rx, 1.0, OPTICS)
    ray = LightSamples(
        weight=lattice.weight[:, :1] * 2.0, departure=lattice.departure[:, :1], arrival=lattice.arrival[:, :1]
    )
    up = torch.zeros_like(tx)
    up[:, 2] = 1.0
    gain = {name: received_gain(light, up, -up, OPTICS) for name, light in (("lattice", lattice), ("ray", ray))}
    both = joined(lattice, ray)
    assert both.shape == (4, lattice.shape[1] + 1) and both.cell is None and lattice.cell is not None
    without_cells = lattice._replace(cell=None)
    torch.testing.assert_close(
        received_gain(both, up, -up, OPTICS),
        received_gain(without_cells, up, -up, OPTICS) + gain["ray"],
        rtol=1e-12,
        atol=0,
    )
    twice = joined(lattice, lattice)
    torch.testing.assert_close(received_gain(twice, up, -up, OPTICS), 2 * gain["lattice"], rtol=1e-12, atol=0)
    back = sliced(twice, samples=slice(lattice.shape[1], None))
    assert all(torch.equal(a, b) for a, b in zip(back, lattice, strict=True))
    copies = repeated(sliced(lattice, rows=slice(1, 3)), 3)
    torch.testing.assert_close(
        received_gain(copies, up[:1].expand(6, 3), -up[:1].expand(6, 3), OPTICS),
        gain["lattice"][1:3].repeat(3),
        rtol=1e-12,
        atol=0,
    )
