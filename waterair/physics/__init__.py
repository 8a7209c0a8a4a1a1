"""The water-air channel model: sea state, wave surface, optics, refracted paths and channel gain.

Imports only torch and tensordict, so it can be used on its own (a notebook, another simulator)::

    from waterair.physics import SeaState, WaveSurface, LinkGeometry, solve_path, LinkBudget, link_performance

Equations and the corrections to the paper are in docs/model.md.
"""

from waterair.physics.channel import (
    ChannelGain,
    LinkGeometry,
    Transceiver,
    calm_sea_gain,
    calm_sea_gains,
    channel_gain,
    gain_upper_bound,
    pointing,
)
from waterair.physics.link import LinkBudget, LinkPerformance, Receiver, link_performance
from waterair.physics.paths import CentroidOptions, NewtonOptions, PathSolution, flat_sea_point, solve_path
from waterair.physics.sea import SeaState, jonswap, spreading
from waterair.physics.surface import SurfaceSample, WaveSurface

__all__ = [
    "CentroidOptions",
    "ChannelGain",
    "LinkBudget",
    "LinkGeometry",
    "LinkPerformance",
    "NewtonOptions",
    "PathSolution",
    "Receiver",
    "SeaState",
    "SurfaceSample",
    "Transceiver",
    "WaveSurface",
    "calm_sea_gain",
    "calm_sea_gains",
    "channel_gain",
    "flat_sea_point",
    "gain_upper_bound",
    "jonswap",
    "link_performance",
    "pointing",
    "solve_path",
    "spreading",
]
