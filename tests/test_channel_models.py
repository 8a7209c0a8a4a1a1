"""The channel models as one interface (docs/model.md §4.7): the registry's names, validation that names
the key, and what every model must satisfy: on a calm sea, both ends aligned receive G_0."""

import pytest
import torch
from conftest import F64, calm, ends

from waterair.physics.channel import (
    CHANNELS,
    ChannelModel,
    LinkEnds,
    LocalEstimate,
    MonteCarlo,
    RayTube,
    SinglePath,
    Transceiver,
    TwoScale,
    channel_model,
)
from waterair.physics.optics import unit_vector
from waterair.physics.paths import flat_sea_point, solve_path
from waterair.physics.sea import sea_state
from waterair.physics.surface import WaveSurface

OPTICS = Transceiver()


@pytest.mark.parametrize(
    ("name", "two_scale", "kind"),
    [
        ("single_path", False, SinglePath),
        ("single_path", True, SinglePath),
        ("full", False, RayTube),
        ("full", True, TwoScale),
        ("montecarlo", False, MonteCarlo),
        ("montecarlo", True, LocalEstimate),
        ("counting", False, MonteCarlo),
        ("counting", True, MonteCarlo),
    ],
)
def test_the_registry_maps_each_name_to_its_model(name, two_scale, kind):
    model = channel_model(name, OPTICS, two_scale, lattice_nodes=9, montecarlo_rays=300)
    assert type(model) is kind and model.optics is OPTICS
    assert isinstance(model, ChannelModel) and name in CHANNELS
    if kind is TwoScale:
        assert model.nodes == 9
    if kind in (MonteCarlo, LocalEstimate):
        assert model.rays == 300 and not model.compiles and not model.needs_exact_point


@pytest.mark.parametrize(
    ("settings", "message"),
    [
        ({"lattice_nodes": 4}, r"^lattice_nodes = 4 is not allowed; it must be odd"),
        ({"lattice_nodes": 33}, r"^lattice_nodes = 33 is out of range"),
        ({"lattice_span": 0.5}, r"^lattice_span = 0.5 is out of range"),
        ({"montecarlo_rays": 0}, r"^montecarlo_rays = 0 is out of range"),
        ({"montecarlo_facets": 0}, r"^montecarlo_facets = 0 is out of range"),
        ({"montecarlo_points": 0}, r"^montecarlo_points = 0 is out of range"),
    ],
)
def test_every_setting_is_checked_whichever_model_is_chosen_and_named_by_its_key(settings, message):
    with pytest.raises(ValueError, match=message):
        channel_model("single_path", OPTICS, False, **settings)


def test_an_unknown_channel_is_a_one_line_error():
    with pytest.raises(
        ValueError, match=r"^channel = 'exact' is not allowed; choose one of single_path, full, montecarlo, counting$"
    ):
        channel_model("exact", OPTICS, False)


@pytest.mark.parametrize(
    "model", [SinglePath(OPTICS), RayTube(OPTICS), TwoScale(OPTICS)], ids=lambda m: type(m).__name__
)
@pytest.mark.parametrize("offset", [0.0, 0.3])
def test_on_a_calm_sea_aligned_ends_receive_the_reference_gain(model, offset):
    """G / G_0 = 1 along the calm-sea path, for every model that compiles (the tracer has its own test):
    exactly for the one-path models, within 0.5 % for the lattice (the aperture's blur on a trapezoid rule)."""
    sea = sea_state(wind=12.0, spectrum="elfouhaily", n_wavenumbers=8, n_dir=4) if model.prepared_keys else sea_state()
    surface = calm(WaveSurface.sample(sea, 2, seed=0, dtype=F64))
    tx, rx = ends(offset, 2)
    point = flat_sea_point(tx, rx, OPTICS.n_water, OPTICS.n_air)
    path = solve_path(surface, tx, rx, 0.0)
    prepared = model.prepare(tx, rx, surface.unresolved)
    assert set(prepared) == set(model.prepared_keys)
    time = torch.zeros(2, dtype=F64)
    light = model.light(surface.harmonics, path, LinkEnds(tx, rx, point), time, prepared)
    reception = model.receive(light, unit_vector(point - tx), unit_vector(point - rx))
    ratio = reception.gain / model.reference_gain(tx, rx)
    tolerance = 5e-3 if model.prepared_keys else 1e-9
    torch.testing.assert_close(ratio, torch.ones_like(ratio), rtol=0, atol=tolerance)
    assert bool(reception.valid.all())


@pytest.mark.parametrize(
    "model", [SinglePath(OPTICS), RayTube(OPTICS), TwoScale(OPTICS)], ids=lambda m: type(m).__name__
)
def test_a_compiling_model_traces_once_for_every_divergence_and_measures_what_the_float_does(model):
    """Inside the compiled step every model that compiles gets ω_D as a 0-dim tensor (Transceiver.traced):
    its light and reception must trace into one graph without a break (a ``math`` call or ``float()`` on ω_D
    breaks it) that serves two divergences, and measure what the model measures eagerly with the float, on a
    wavy sea with both ends off the path. Traced with dynamo's counting backend."""
    from dataclasses import replace

    from torch._dynamo.testing import CompileCounter

    sea = sea_state(wind=12.0, spectrum="elfouhaily", n_wavenumbers=8, n_dir=4) if model.prepared_keys else sea_state()
    surface = WaveSurface.sample(sea, 3, seed=1, dtype=F64)
    tx, rx = ends(0.2, 3)
    point = flat_sea_point(tx, rx, OPTICS.n_water, OPTICS.n_air)
    path = solve_path(surface, tx, rx, 1.0)
    tilt = torch.tensor([0.004, -0.003, 0.0], dtype=F64)
    tx_dir, rx_dir = unit_vector(point - tx + tilt), unit_vector(point - rx - tilt)
    link, time = LinkEnds(tx, rx, point, tx_dir), torch.ones(3, dtype=F64)

    def measure(channel, prepared):
        reception = channel.receive(channel.light(surface.harmonics, path, link, time, prepared), tx_dir, rx_dir)
        return reception.gain, reception.upper_bound, reception.alpha_d

    counter = CompileCounter()
    traced = torch.compile(measure, backend=counter, fullgraph=True)
    torch._dynamo.reset()
    for divergence in (0.02, 0.005):
        optics = Transceiver(divergence=divergence)
        prepared = replace(model, optics=optics).prepare(tx, rx, surface.unresolved)
        eager = measure(replace(model, optics=optics), prepared)
        compiled = traced(replace(model, optics=optics.traced()), prepared)
        assert bool((eager[0] > 0).all())
        for got, want in zip(compiled, eager, strict=True):
            torch.testing.assert_close(got, want, rtol=1e-12, atol=0)
    assert counter.frame_count == 1
