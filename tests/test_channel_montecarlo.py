"""The Monte Carlo tracer (docs/model.md §4.6) against the closed form of a calm sea."""

import torch
from conftest import F64, calm, ends

from waterair.physics.channel import (
    LightSamples,
    LinkEnds,
    MonteCarlo,
    Transceiver,
    flat_sea_irradiance,
    received_gain,
    standard_error,
)
from waterair.physics.optics import beam_divergence
from waterair.physics.paths import flat_sea_point
from waterair.physics.sea import sea_state
from waterair.physics.surface import WaveSurface

OPTICS = Transceiver()
BEAM = beam_divergence(OPTICS.divergence, OPTICS.wavelength)


def test_monte_carlo_on_a_calm_sea_counts_the_closed_form():
    """Rays through a calm surface counted on the 5 cm aperture: the closed form within 3 standard errors."""
    surface = calm(WaveSurface.sample(sea_state("jonswap", wind=12.0, n_freq=4, n_dir=4), 2, seed=0, dtype=F64))
    tx, rx = ends(0.3, 2)
    point = flat_sea_point(tx, rx, OPTICS.n_water, OPTICS.n_air)
    axis = (point - tx) / torch.linalg.vector_norm(point - tx, dim=-1, keepdim=True)
    arrival = (rx - point) / torch.linalg.vector_norm(rx - point, dim=-1, keepdim=True)
    # the proposal: 1 mrad wide around the calm-sea departure
    tracer = MonteCarlo(OPTICS, rays=20_000, facets=1, proposal_beams=0.001 / BEAM)
    generator = torch.Generator().manual_seed(0)
    result = tracer.estimate(surface.harmonics, surface.unresolved, LinkEnds(tx, rx, point), 0.0, generator)
    wide = Transceiver(divergence=1.5, half_fov=1.5)  # G_D within 0.2 % of 1 over the rays, G_A constant
    gain, error = standard_error(result, axis, -arrival, wide)
    closed = flat_sea_irradiance(tx, rx, OPTICS) * received_gain(
        LightSamples(weight=torch.ones(2, 1, dtype=F64), departure=axis[:, None], arrival=arrival[:, None]),
        axis,
        -arrival,
        wide,
    )
    assert (error / gain).max() < 0.02
    assert ((gain - closed).abs() < 3 * error).all()
