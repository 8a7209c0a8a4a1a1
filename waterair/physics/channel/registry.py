"""The channel models as a configuration chooses them (``env/channel=NAME``, docs/environment.md, "Channel").

Each option of the ``env/channel`` group is one frozen dataclass here holding only its own settings
(``env.channel.nodes``, ``env.channel.rays``, ...), registered in :data:`CHANNELS` by its ``name``, and
it builds its :class:`~.model.ChannelModel` for a sea and the optics:

* ``full`` (:class:`FullChannel`): every refraction point with its lensing, the unresolved slopes and the
  aperture: :class:`~.lattice.TwoScale` on a sea that carries unresolved slopes, :class:`~.ray_tube.RayTube`
  (its limit without them) on one that does not;
* ``single_path`` (:class:`SinglePathChannel`): :class:`~.single_path.SinglePath`, the paper's one path;
* ``montecarlo`` (:class:`MonteCarloChannel`): the reference (slow; for evaluation): the local estimate
  (:class:`~.local_estimate.LocalEstimate`) on a sea that carries unresolved slopes, the hit-counting
  tracer on one that does not (its facets are then the resolved surface itself);
* ``counting`` (:class:`CountingChannel`): :class:`~.montecarlo.MonteCarlo`, the hit-counting tracer on any
  sea: the local estimate's own check where counting is precise (a large aperture, a wide beam).

A new model is one module and one class here with its entry in :data:`CHANNELS`; ``make docs`` writes its option
in ``conf/env/channel/`` from the class's defaults.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import ClassVar

from waterair.core.validation import check_choice
from waterair.physics.channel.geometry import Transceiver
from waterair.physics.channel.lattice import LATTICE_NODES, LATTICE_SPAN, TwoScale
from waterair.physics.channel.local_estimate import LocalEstimate
from waterair.physics.channel.model import ChannelModel
from waterair.physics.channel.montecarlo import MonteCarlo
from waterair.physics.channel.ray_tube import RayTube
from waterair.physics.channel.single_path import SinglePath


@dataclass(frozen=True)
class Channel:
    """One option of ``env/channel``: its settings, its traits, and the model it builds. The settings are
    validated once, by the model as it is built (those the model for this sea does not use, beside it)."""

    name: ClassVar[str]
    compile_frames: ClassVar[Mapping[str, int]] = MappingProxyType({"warm": 50_000, "cold": 300_000})
    """Frames of a run from which compiling its step repays the compile, with torch's compile cache warm or cold
    (the one-path channel's, measured in docs/benchmarks.md, "Training")."""
    evaluation_frames: ClassVar[Mapping[str, int]] = compile_frames
    """The same for a group of an evaluation, its graphs in torch's cache (warm) or not (cold): an evaluation's
    batches are wider than training's, so an eager frame costs less there (the one path's: not measured apart)."""
    centroid_solver: ClassVar[bool] = False
    """Whether the paper's centroid path solver (``env.solver=centroid``) can serve it."""

    def model(self, optics: Transceiver, two_scale_sea: bool) -> ChannelModel:
        """The channel model for ``optics`` on a sea that does (``two_scale_sea``) or does not carry unresolved
        slopes."""
        raise NotImplementedError


@dataclass(frozen=True)
class FullChannel(Channel):
    """Every refraction point, lensing, unresolved slopes and aperture (the default): ``nodes`` × ``nodes``
    lattice nodes of half-width ``span`` standard deviations, in each of the two-scale model's two lattices."""

    name = "full"
    compile_frames = MappingProxyType({"warm": 25_000, "cold": 100_000})  # 13 s or 65 s over 0.63 ms a frame
    # a group's graphs: about 12 s to load or 100-220 s to compile, over 0.35 ms a frame (docs/benchmarks.md)
    evaluation_frames = MappingProxyType({"warm": 35_000, "cold": 500_000})
    nodes: int = LATTICE_NODES
    span: float = LATTICE_SPAN

    def model(self, optics: Transceiver, two_scale_sea: bool) -> ChannelModel:
        if two_scale_sea:
            return TwoScale(optics, nodes=self.nodes, span=self.span)
        TwoScale.check_settings(nodes=self.nodes, span=self.span)
        return RayTube(optics)


@dataclass(frozen=True)
class SinglePathChannel(Channel):
    """The paper's one refracted path with its flat-sea power law (``+experiment=paper``)."""

    name = "single_path"
    centroid_solver = True

    def model(self, optics: Transceiver, two_scale_sea: bool) -> ChannelModel:
        return SinglePath(optics)


@dataclass(frozen=True)
class MonteCarloChannel(Channel):
    """The Monte Carlo reference (slow; for evaluation): ``rays`` surface rays per link and step, each lighting
    ``points`` points of the aperture (the local estimate; the counting tracer on a sea without unresolved
    slopes, with its own facets)."""

    name = "montecarlo"
    rays: int = LocalEstimate.rays
    points: int = LocalEstimate.points

    def model(self, optics: Transceiver, two_scale_sea: bool) -> ChannelModel:
        if two_scale_sea:
            return LocalEstimate(optics, rays=self.rays, points=self.points)
        LocalEstimate.check_settings(points=self.points)
        return MonteCarlo(optics, rays=self.rays)


@dataclass(frozen=True)
class CountingChannel(Channel):
    """The hit-counting ray tracer (slow; for evaluation): ``rays`` surface rays per link and step, ``facets``
    unresolved-slope draws each."""

    name = "counting"
    rays: int = MonteCarlo.rays
    facets: int = MonteCarlo.facets

    def model(self, optics: Transceiver, two_scale_sea: bool) -> ChannelModel:
        return MonteCarlo(optics, rays=self.rays, facets=self.facets)


CHANNELS: dict[str, type[Channel]] = {
    kind.name: kind for kind in (FullChannel, SinglePathChannel, MonteCarloChannel, CountingChannel)
}
"""The options of ``env/channel`` by name."""


def channel(name: str = "full", **keys) -> Channel:
    """The channel ``name`` with ``keys``; a key it does not have is an error naming it and its keys."""
    check_choice("name", name, CHANNELS)
    kind = CHANNELS[name]
    known = [field.name for field in dataclasses.fields(kind)]
    unknown = sorted(set(keys) - set(known))
    if unknown:
        own = f"its keys: {', '.join(known)}" if known else "it has no keys"
        raise ValueError(f"{unknown[0]} is not a key of the {name} channel; {own}")
    return kind(**keys)


def channel_model(name: str, optics: Transceiver, two_scale_sea: bool, **keys) -> ChannelModel:
    """The model of the channel ``name`` (with its ``keys``) for ``optics`` on a sea that does or does not
    carry unresolved slopes (:meth:`Channel.model`)."""
    return channel(name, **keys).model(optics, two_scale_sea)
