"""The channel models by the names a configuration gives them (``env.channel``, docs/environment.md, "Channel").

:func:`channel_model` is the one place a name becomes a model:

* ``single_path``: :class:`~.single_path.SinglePath`, the paper's one path;
* ``full``: every refraction point with its lensing, the unresolved slopes and the aperture:
  :class:`~.lattice.TwoScale` on a sea that carries unresolved slopes, :class:`~.ray_tube.RayTube` (its
  limit without them) on one that does not;
* ``montecarlo``: :class:`~.montecarlo.MonteCarlo`, the tracer (slow; for evaluation).
"""

from __future__ import annotations

from waterair.core.validation import check_choice
from waterair.physics.channel.geometry import Transceiver
from waterair.physics.channel.lattice import LATTICE_NODES, LATTICE_SPAN, TwoScale
from waterair.physics.channel.model import ChannelModel
from waterair.physics.channel.montecarlo import MonteCarlo
from waterair.physics.channel.ray_tube import RayTube
from waterair.physics.channel.single_path import SinglePath

CHANNELS = ("single_path", "full", "montecarlo")
"""The names of :func:`channel_model`."""
MONTECARLO_RAYS = MonteCarlo.rays
MONTECARLO_FACETS = MonteCarlo.facets


def channel_model(
    name: str,
    optics: Transceiver,
    two_scale_sea: bool,
    *,
    lattice_nodes: int = LATTICE_NODES,
    lattice_span: float = LATTICE_SPAN,
    montecarlo_rays: int = MONTECARLO_RAYS,
    montecarlo_facets: int = MONTECARLO_FACETS,
) -> ChannelModel:
    """The model ``name`` (one of :data:`CHANNELS`) for ``optics`` on a sea that does (``two_scale_sea``) or
    does not carry unresolved slopes. Every setting is validated whichever model is chosen; an error
    names the setting by its keyword here (``lattice_nodes = 4 is not allowed; …``)."""
    check_choice("channel", name, CHANNELS)
    lattice = _build(
        TwoScale, {"nodes": ("lattice_nodes", lattice_nodes), "span": ("lattice_span", lattice_span)}, optics
    )
    tracer = _build(
        MonteCarlo,
        {"rays": ("montecarlo_rays", montecarlo_rays), "facets": ("montecarlo_facets", montecarlo_facets)},
        optics,
    )
    if name == "single_path":
        return SinglePath(optics)
    if name == "montecarlo":
        return tracer
    return lattice if two_scale_sea else RayTube(optics)


def _build(kind: type, settings: dict[str, tuple[str, object]], optics: Transceiver):
    """``kind(optics, **fields)`` from ``{field: (keyword, value)}``; an error names the keyword, not the field."""
    try:
        return kind(optics, **{name: value for name, (_, value) in settings.items()})
    except ValueError as error:
        message = str(error)
        for name, (keyword, _) in settings.items():
            if message.startswith(f"{name} "):
                message = keyword + message[len(name) :]
        raise ValueError(message) from None
