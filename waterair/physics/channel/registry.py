"""The channel models by the names a configuration gives them (``env.channel``, docs/environment.md, "Channel").

:func:`channel_model` is the one place a name becomes a model:

* ``single_path``: :class:`~.single_path.SinglePath`, the paper's one path;
* ``full``: every refraction point with its lensing, the unresolved slopes and the aperture:
  :class:`~.lattice.TwoScale` on a sea that carries unresolved slopes, :class:`~.ray_tube.RayTube` (its
  limit without them) on one that does not;
* ``montecarlo``: the reference (slow; for evaluation): the local estimate
  (:class:`~.local_estimate.LocalEstimate`) on a sea that carries unresolved slopes, the hit-counting
  tracer on one that does not (its facets are then the resolved surface itself);
* ``counting``: :class:`~.montecarlo.MonteCarlo`, the hit-counting tracer on any sea: the local estimate's
  own check where counting is precise (a large aperture, a wide beam).
"""

from __future__ import annotations

import dataclasses
from typing import Any

from waterair.core.validation import check_choice
from waterair.physics.channel.geometry import Transceiver
from waterair.physics.channel.lattice import LATTICE_NODES, LATTICE_SPAN, TwoScale
from waterair.physics.channel.local_estimate import LocalEstimate
from waterair.physics.channel.model import ChannelModel
from waterair.physics.channel.montecarlo import MonteCarlo
from waterair.physics.channel.ray_tube import RayTube
from waterair.physics.channel.single_path import SinglePath

CHANNELS = ("single_path", "full", "montecarlo", "counting")
"""The names of :func:`channel_model`."""
MONTECARLO_RAYS = MonteCarlo.rays
MONTECARLO_FACETS = MonteCarlo.facets
MONTECARLO_POINTS = LocalEstimate.points


def channel_model(
    name: str,
    optics: Transceiver,
    two_scale_sea: bool,
    *,
    lattice_nodes: int = LATTICE_NODES,
    lattice_span: float = LATTICE_SPAN,
    montecarlo_rays: int = MONTECARLO_RAYS,
    montecarlo_facets: int = MONTECARLO_FACETS,
    montecarlo_points: int = MONTECARLO_POINTS,
) -> ChannelModel:
    """The model ``name`` (one of :data:`CHANNELS`) for ``optics`` on a sea that does (``two_scale_sea``) or
    does not carry unresolved slopes. Every setting is validated once whichever model is chosen (by the
    chosen model, or by its own model's check); an error names the setting by its keyword here
    (``lattice_nodes = 4 is not allowed; …``)."""
    check_choice("channel", name, CHANNELS)
    given: dict[str, Any] = {
        "lattice_nodes": lattice_nodes,
        "lattice_span": lattice_span,
        "montecarlo_rays": montecarlo_rays,
        "montecarlo_facets": montecarlo_facets,
        "montecarlo_points": montecarlo_points,
    }
    kind: type[ChannelModel]
    if name == "single_path":
        kind = SinglePath
    elif name == "counting" or (name == "montecarlo" and not two_scale_sea):
        kind = MonteCarlo
    elif name == "montecarlo":
        kind = LocalEstimate
    else:
        kind = TwoScale if two_scale_sea else RayTube
    own = {field: keyword for keyword, (owner, field) in SETTINGS.items() if owner is kind or field in _fields(kind)}
    model = _renamed(lambda: kind(optics, **{field: given[keyword] for field, keyword in own.items()}), own)
    checked = set(own.values())
    for keyword, (owner, field) in SETTINGS.items():
        if keyword not in checked:
            _renamed(lambda owner=owner, field=field, keyword=keyword: owner.check_settings(**{field: given[keyword]}),
                     {field: keyword})  # fmt: skip
            checked.add(keyword)
    return model


SETTINGS = {
    "lattice_nodes": (TwoScale, "nodes"),
    "lattice_span": (TwoScale, "span"),
    "montecarlo_rays": (MonteCarlo, "rays"),
    "montecarlo_facets": (MonteCarlo, "facets"),
    "montecarlo_points": (LocalEstimate, "points"),
}
"""Each keyword of :func:`channel_model`: the model whose check validates it where the chosen model lacks it,
and its field there (the Monte Carlo models share ``rays``)."""


def _fields(kind: type) -> set[str]:
    return {field.name for field in dataclasses.fields(kind)}


def _renamed(build, names: dict[str, str]):
    """``build()``; an error naming a field is re-worded with its keyword (``nodes`` → ``lattice_nodes``)."""
    try:
        return build()
    except ValueError as error:
        message = str(error)
        for field, keyword in names.items():
            if message.startswith(f"{field} "):
                message = keyword + message[len(field) :]
        raise ValueError(message) from None
