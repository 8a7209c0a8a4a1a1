"""The two-scale lattice placed for the pointing (docs/model.md §4.3): the bound's lattice does not move with
the pointing, the beam's lattice is the bound's when the beam is aimed at the patch, and the full channel
holds against the local estimate at flat-sea Snell and with the transmitter pointed straight up."""

import math

import pytest
import torch
from conftest import F64, ends

from waterair.physics.channel import LightSamples, LinkEnds, Transceiver, TwoScale, standard_error
from waterair.physics.channel.lattice import (
    BEAM_LATTICE_FROM,
    EIGH_CHUNK,
    across_cells,
    beam_aim,
    beam_share,
    symmetric_eigen,
)
from waterair.physics.channel.local_estimate import LocalEstimate
from waterair.physics.optics import unit_vector
from waterair.physics.paths import flat_sea_point, solve_path
from waterair.physics.sea import sea_state
from waterair.physics.surface import WaveSurface

OPTICS = Transceiver()
SEAS = 8
WIND = 4.0  # where the bound's lattice alone is furthest off straight up (docs/model.md §4.3)
BEAMS = 1.0  # the reference's proposal, in beam widths: wide enough for straight up


def ocean(wind: float, seed: int) -> WaveSurface:
    return WaveSurface.sample(sea_state(wind=wind, spectrum="elfouhaily", n_dir=16), SEAS, seed=seed, dtype=F64)


def pointings(tx: torch.Tensor, rx: torch.Tensor) -> dict[str, tuple[torch.Tensor, torch.Tensor]]:
    flat = flat_sea_point(tx, rx, OPTICS.n_water, OPTICS.n_air)
    snell = unit_vector(flat - tx), unit_vector(flat - rx)
    up = torch.zeros_like(tx)
    up[:, 2] = 1.0
    return {"snell": snell, "up": (up, snell[1])}


def lattice_light(model: TwoScale, surface: WaveSurface, tx, rx, t: float, pointing: torch.Tensor | None):
    path = solve_path(surface, tx, rx, t)
    calm = flat_sea_point(tx, rx, OPTICS.n_water, OPTICS.n_air)
    time = torch.full((tx.shape[0],), t, dtype=F64)
    prepared = model.prepare(tx, rx, surface.unresolved)
    return model.light(surface.harmonics, path, LinkEnds(tx, rx, calm, pointing), time, prepared)


def test_the_bound_does_not_move_with_the_pointing_and_the_gain_does():
    surface, (tx, rx) = ocean(12.0, 21), ends(0.1, SEAS)
    model = TwoScale(OPTICS)
    receptions = {
        name: model.receive(lattice_light(model, surface, tx, rx, 3.0, tx_dir), tx_dir, rx_dir)
        for name, (tx_dir, rx_dir) in pointings(tx, rx).items()
    }
    snell, up = receptions["snell"], receptions["up"]
    assert torch.equal(snell.upper_bound, up.upper_bound)
    assert torch.equal(snell.departure, up.departure)
    assert (up.gain < 0.5 * snell.gain).all()  # pointed away, it receives less, from its own lattice
    assert (snell.gain <= snell.upper_bound).all()


def test_a_beam_aimed_at_the_patch_reads_the_bound_lattice():
    # pointed at the tracked refraction point the pull has nothing to move: the gain is read from the bound's lattice
    surface, (tx, rx) = ocean(12.0, 22), ends(0.1, SEAS)
    model = TwoScale(OPTICS)
    path = solve_path(surface, tx, rx, 3.0)
    aimed = unit_vector(path.point * torch.tensor([1.0, 1.0, 0.0], dtype=F64) - tx)
    torch.testing.assert_close(beam_aim(tx, aimed), path.point[:, :2], rtol=0, atol=1e-12)
    light = lattice_light(model, surface, tx, rx, 3.0, aimed)
    nodes = model.nodes**2
    torch.testing.assert_close(light.weight[:, nodes : 2 * nodes], light.weight[:, :nodes], rtol=1e-12, atol=0)
    assert (light.weight[:, 2 * nodes :] == 0).all()  # the beam's lattice, on the same nodes, has no share


def test_the_gain_moves_smoothly_from_the_bound_lattice_to_the_beams():
    apart = torch.linspace(0.0, 5.0, 501, dtype=F64)
    share = beam_share(apart)
    near, far = BEAM_LATTICE_FROM
    assert (share[apart <= near] == 0).all() and (share[apart >= far] == 1).all()
    assert (share.diff() >= 0).all() and share.diff().max() < 2 * 0.01 / (far - near)  # no jump: slope ≤ 1.5 / width


@pytest.mark.slow
def test_the_full_channel_holds_against_the_local_estimate():
    """8 ocean seas at 4 m/s, one step, float64, 10⁴ rays: at flat-sea Snell the mean within 1 % and each link
    within 2 % rms, straight up within 10 % rms (noise of the reference taken out; docs/model.md §4.3). The
    bound's lattice alone (no pointing given) is off straight up, so the test sees the beam's lattice."""
    surface, (tx, rx) = ocean(WIND, 23), ends(0.1, SEAS)
    model, t = TwoScale(OPTICS), 10.0
    calm = flat_sea_point(tx, rx, OPTICS.n_water, OPTICS.n_air)
    reference = LocalEstimate(OPTICS, rays=10_000, points=1, proposal_beams=BEAMS).estimate(
        surface.harmonics, surface.unresolved, LinkEnds(tx, rx, calm), t, torch.Generator().manual_seed(5)
    )
    errors = {}
    for name, (tx_dir, rx_dir) in pointings(tx, rx).items():
        exact, se = standard_error(reference, tx_dir, rx_dir, OPTICS)
        mean = exact.mean()
        noise = se.pow(2).mean()
        for placed, pointing in (("beam", tx_dir), ("bound", None)):
            light = lattice_light(model, surface, tx, rx, t, pointing)
            gain = model.receive(light, tx_dir, rx_dir).gain
            rms = math.sqrt(max(0.0, ((gain - exact).pow(2).mean() - noise).item())) / mean.item()
            errors[name, placed] = (gain.mean() / mean).item(), rms, (se.pow(2).sum().sqrt() / SEAS / mean).item()
    ratio, rms, pooled = errors["snell", "beam"]
    assert abs(ratio - 1.0) < 0.01 + 2 * pooled
    assert rms < 0.02
    assert errors["up", "beam"][1] < 0.10
    assert errors["up", "bound"][1] > 1.5 * errors["up", "beam"][1]


def test_across_cells_is_the_change_between_neighbours_one_sided_at_the_edge():
    nodes = 5
    i, j = torch.meshgrid(torch.arange(nodes, dtype=F64), torch.arange(nodes, dtype=F64), indexing="ij")
    field = torch.stack((2.0 * i + 3.0 * j, i * i, torch.zeros_like(i)), -1).reshape(1, nodes * nodes, 3)
    steps = across_cells(field, nodes).reshape(nodes, nodes, 2, 3)
    assert torch.equal(steps[..., 0, 0], torch.full((nodes, nodes), 2.0, dtype=F64))  # linear: exact
    assert torch.equal(steps[..., 1, 0], torch.full((nodes, nodes), 3.0, dtype=F64))
    assert torch.equal(steps[:, 0, 0, 1], torch.tensor([1.0, 2.0, 4.0, 6.0, 7.0], dtype=F64))  # i²: central inside
    assert torch.equal(steps[..., 1, 1], torch.zeros(nodes, nodes, dtype=F64))


@pytest.mark.slow
def test_straight_facing_holds_against_the_local_estimate_with_the_field_of_view_averaged_over_each_cell():
    """Both ends vertical: the receiver's field-of-view edge cuts through the light. 8 ocean seas at 20 m/s (the
    wind where the edge cut deepest; every wind is measured in docs/model.md §4.3), one step, float64, 5,000 rays
    (the reference's noise 5 % rms, taken out): within 10 % rms per link with the field of view averaged over each
    node's cell (2 %); as rays, the edge's first-order error (16 %) is more than twice that."""
    surface, (tx, rx) = ocean(20.0, 29), ends(0.1, SEAS)
    model, t = TwoScale(OPTICS), 10.0
    calm = flat_sea_point(tx, rx, OPTICS.n_water, OPTICS.n_air)
    reference = LocalEstimate(OPTICS, rays=5_000, points=1, proposal_beams=BEAMS).estimate(
        surface.harmonics, surface.unresolved, LinkEnds(tx, rx, calm), t, torch.Generator().manual_seed(7)
    )
    up = torch.zeros_like(tx)
    up[:, 2] = 1.0
    exact, se = standard_error(reference, up, -up, OPTICS)
    light = lattice_light(model, surface, tx, rx, t, up)
    rays = LightSamples(weight=light.weight, departure=light.departure, arrival=light.arrival)
    errors = []
    for samples in (light, rays):
        gain = model.receive(samples, up, -up).gain
        errors.append(math.sqrt(max(0.0, ((gain - exact).pow(2).mean() - se.pow(2).mean()).item())) / exact.mean())
    cells, as_rays = errors
    assert cells < 0.10 and as_rays > 2 * cells, errors


def test_the_eigensolver_in_pieces_gives_each_matrix_its_own_decomposition():
    """More links than one call of the eigensolver takes (:data:`EIGH_CHUNK`, kept under cuSOLVER's batch limit):
    every matrix, the last piece's too, is rebuilt from its own eigenvalues (ascending) and orthonormal vectors,
    and equals the solver's answer for that matrix alone, laid out in memory as one call lays it out."""
    generator = torch.Generator().manual_seed(0)
    a = torch.randn(EIGH_CHUNK + 5, 2, 2, dtype=F64, generator=generator)
    matrices = a @ a.transpose(-1, -2) + 0.1 * torch.eye(2, dtype=F64)
    values, vectors = symmetric_eigen(matrices)
    assert vectors.stride() == torch.linalg.eigh(matrices).eigenvectors.stride()
    rebuilt = vectors @ torch.diag_embed(values) @ vectors.transpose(-1, -2)
    assert torch.allclose(rebuilt, matrices, rtol=1e-12, atol=1e-12)
    assert (values[:, 1] >= values[:, 0]).all()
    for link in (0, EIGH_CHUNK - 1, EIGH_CHUNK, EIGH_CHUNK + 4):
        alone_values, alone_vectors = torch.linalg.eigh(matrices[link : link + 1])
        assert torch.equal(values[link], alone_values[0]) and torch.equal(vectors[link], alone_vectors[0])
