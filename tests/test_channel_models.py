"""The channel models as one interface (docs/model.md §4.7): the registry of the ``env/channel`` options (its
classes and YAMLs in agreement), validation that names the key, and what every model must satisfy: on a calm
sea, both ends aligned receive G_0."""

import dataclasses

import pytest
import torch
from conftest import F64, ROOT, calm, ends
from omegaconf import OmegaConf

from waterair.physics.channel import (
    CHANNELS,
    Channel,
    ChannelModel,
    LinkEnds,
    LocalEstimate,
    MonteCarlo,
    RayTube,
    SinglePath,
    Transceiver,
    TwoScale,
    channel,
    channel_model,
    registry,
)
from waterair.physics.optics import unit_vector
from waterair.physics.paths import flat_sea_point, solve_path
from waterair.physics.sea import sea_state
from waterair.physics.surface import WaveSurface

OPTICS = Transceiver()


OWN = {
    "single_path": {},
    "full": {"nodes": 7},
    "montecarlo": {"rays": 300, "points": 2},
    "counting": {"rays": 300, "facets": 4},
}
"""Non-default settings of each channel, its own keys only."""


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
    model = channel_model(name, OPTICS, two_scale, **OWN[name])
    assert type(model) is kind and model.optics is OPTICS
    assert isinstance(model, ChannelModel) and CHANNELS[name].name == name
    if kind is TwoScale:
        assert model.nodes == 7
    if kind in (MonteCarlo, LocalEstimate):
        assert model.rays == 300 and not model.compiles and not model.needs_exact_point
    if kind is LocalEstimate:
        assert model.points == 2
    if name == "counting":
        assert model.facets == 4


def test_the_registry_the_yaml_group_and_the_classes_agree():
    """Each option of conf/env/channel is a registered class of the same name with the same keys and defaults,
    and every registered class has its YAML: adding a model is a class, its entry and its YAML."""
    yamls = {
        path.stem: OmegaConf.to_container(OmegaConf.load(path)) for path in (ROOT / "conf/env/channel").glob("*.yaml")
    }
    assert set(yamls) == set(CHANNELS)
    assert set(CHANNELS.values()) == {kind for kind in vars(registry).values() if isinstance(kind, type)
                                       and issubclass(kind, Channel) and kind is not Channel}  # fmt: skip
    for name, kind in CHANNELS.items():
        assert kind.name == name and yamls[name]["name"] == name
        defaults = {field.name: field.default for field in dataclasses.fields(kind)}
        assert {key: value for key, value in yamls[name].items() if key != "name"} == defaults, name
        assert channel(**yamls[name]) == kind()


@pytest.mark.parametrize(
    ("name", "two_scale", "settings", "message"),
    [
        ("full", True, {"nodes": 4}, r"^nodes = 4 is not allowed; it must be odd"),
        ("full", False, {"nodes": 33}, r"^nodes = 33 is out of range"),  # RayTube has no lattice: checked beside it
        ("full", True, {"span": 0.5}, r"^span = 0.5 is out of range"),
        ("montecarlo", True, {"rays": 0}, r"^rays = 0 is out of range"),
        ("montecarlo", False, {"points": 0}, r"^points = 0 is out of range"),  # the counting tracer has no points
        ("counting", True, {"facets": 0}, r"^facets = 0 is out of range"),
        ("single_path", True, {"rays": 10}, r"^rays is not a key of the single_path channel; it has no keys$"),
        ("counting", True, {"points": 2}, r"^points is not a key of the counting channel; its keys: rays, facets$"),
    ],
)
def test_every_setting_is_checked_whichever_model_the_sea_needs_and_named_by_its_key(
    name, two_scale, settings, message
):
    with pytest.raises(ValueError, match=message):
        channel_model(name, OPTICS, two_scale, **settings)


def test_an_unknown_channel_is_a_one_line_error():
    with pytest.raises(
        ValueError, match=r"^name = 'exact' is not allowed; choose one of full, single_path, montecarlo, counting$"
    ):
        channel_model("exact", OPTICS, False)


@pytest.mark.parametrize(
    "model", [SinglePath(OPTICS), RayTube(OPTICS), TwoScale(OPTICS)], ids=lambda m: type(m).__name__
)
@pytest.mark.parametrize("offset", [0.0, 0.3])
def test_on_a_calm_sea_aligned_ends_receive_the_reference_gain(model, offset):
    """G / G_0 = 1 along the calm-sea path, for every model that compiles (the tracer has its own test):
    exactly for the one-path models, within 0.5 % for the lattice (the aperture's blur on a trapezoid rule)."""
    sea = (
        sea_state("elfouhaily", wind=12.0, n_wavenumbers=8, n_dir=4) if model.Prepared._fields else sea_state("jonswap")
    )
    surface = calm(WaveSurface.sample(sea, 2, seed=0, dtype=F64))
    tx, rx = ends(offset, 2)
    point = flat_sea_point(tx, rx, OPTICS.n_water, OPTICS.n_air)
    path = solve_path(surface, tx, rx, 0.0)
    prepared = model.prepare(tx, rx, surface.unresolved)
    assert type(prepared) is model.Prepared
    time = torch.zeros(2, dtype=F64)
    light = model.light(surface.harmonics, path, LinkEnds(tx, rx, point), time, prepared)
    reception = model.receive(light, unit_vector(point - tx), unit_vector(point - rx))
    ratio = reception.gain / model.reference_gain(tx, rx)
    tolerance = 5e-3 if model.Prepared._fields else 1e-9
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

    sea = (
        sea_state("elfouhaily", wind=12.0, n_wavenumbers=8, n_dir=4) if model.Prepared._fields else sea_state("jonswap")
    )
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
