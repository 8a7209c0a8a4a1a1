"""The two-scale channel (docs/model.md §4.3): energy conservation on the measured-slope sea, and the
TwoScale model's light against the lattice it is made of."""

import pytest
import torch
from conftest import F64, ends

from waterair.physics.channel import LightSamples, LinkEnds, Transceiver, TwoScale, flat_sea_irradiance
from waterair.physics.paths import flat_sea_point, solve_path
from waterair.physics.sea import sea_state
from waterair.physics.surface import WaveSurface


def two_scale(surface: WaveSurface, tx, rx, t: float, optics: Transceiver) -> LightSamples:
    """The TwoScale model's light around the converged path at time ``t`` (s)."""
    time = torch.full((tx.shape[0],), t, dtype=F64)
    path = solve_path(surface, tx, rx, t)
    model = TwoScale(optics)
    prepared = model.prepare(tx, rx, surface.unresolved)
    calm_point = flat_sea_point(tx, rx, optics.n_water, optics.n_air)
    return model.light(surface.harmonics, path, LinkEnds(tx, rx, calm_point), time, prepared)


@pytest.mark.parametrize("wind", [12.0, 20.0])
def test_the_surface_moves_light_and_does_not_create_it(wind):
    """A beam wide enough to cover the receiver's plane (ω_D = 0.3 rad, no angular gains): the
    irradiance averaged over 256 ocean seas × 3 times equals the calm sea's within 2 %."""
    optics = Transceiver(divergence=0.3)
    surface = WaveSurface.sample(sea_state(wind=wind, spectrum="elfouhaily", n_dir=16), 256, seed=3, dtype=F64)
    tx, rx = ends(0.1, 256)
    total = torch.cat([two_scale(surface, tx, rx, t, optics).weight.sum(-1) for t in (0.0, 3.0, 7.0)])
    ratio = (total.mean() / flat_sea_irradiance(tx, rx, optics)[0]).item()
    assert ratio == pytest.approx(1.0, abs=0.02)
    assert (total.std() / total.mean()).item() > 0.1  # it does move it
