"""The water-air channel model: sea state, wave surface, optics, refracted paths and channel gain.

Imports only torch and tensordict, so it can be used on its own (a notebook, another simulator)::

    from waterair.physics import SeaState, WaveSurface, LinkGeometry, solve_path, LinkBudget, link_performance

Equations and the corrections to the paper are in docs/model.md.
"""

from waterair.physics.channel import (
    ChannelGain,
    LightSamples,
    LinkGeometry,
    Transceiver,
    calm_sea_gain,
    calm_sea_gains,
    channel_gain,
    gain_upper_bound,
    pointing,
    received_gain,
    two_scale_light,
    upper_bound,
)
from waterair.physics.link import LinkBudget, LinkPerformance, Receiver, link_performance
from waterair.physics.montecarlo import MonteCarloLight, trace
from waterair.physics.paths import CentroidOptions, NewtonOptions, PathSolution, flat_sea_point, solve_path
from waterair.physics.paths.census import RefractionPoints, refraction_points
from waterair.physics.sea import MeanSquareSlope, SeaState, cox_munk, elevation_spectrum, jonswap, spreading
from waterair.physics.surface import SurfaceSample, WaveSurface

__all__ = [
    "CentroidOptions",
    "ChannelGain",
    "LightSamples",
    "LinkBudget",
    "LinkGeometry",
    "LinkPerformance",
    "MeanSquareSlope",
    "MonteCarloLight",
    "NewtonOptions",
    "PathSolution",
    "Receiver",
    "RefractionPoints",
    "SeaState",
    "SurfaceSample",
    "Transceiver",
    "WaveSurface",
    "calm_sea_gain",
    "calm_sea_gains",
    "channel_gain",
    "cox_munk",
    "elevation_spectrum",
    "flat_sea_point",
    "gain_upper_bound",
    "jonswap",
    "link_performance",
    "pointing",
    "received_gain",
    "refraction_points",
    "solve_path",
    "spreading",
    "trace",
    "two_scale_light",
    "upper_bound",
]
