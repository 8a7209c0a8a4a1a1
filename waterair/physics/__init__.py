"""The water-air channel model: sea state, wave surface, optics, refracted paths and channel gain.

Imports only torch and tensordict, so it can be used on its own (a notebook, another simulator)::

    from waterair.physics import SeaState, WaveSurface, LinkGeometry, solve_path, LinkBudget, link_performance

Equations and the corrections to the paper are in docs/model.md.
"""

from waterair.physics.channel import (
    CHANNELS,
    ChannelGain,
    ChannelModel,
    LightSamples,
    LinkEnds,
    LinkGeometry,
    MonteCarlo,
    MonteCarloLight,
    RayTube,
    SinglePath,
    Transceiver,
    TwoScale,
    calm_sea_gain,
    channel_gain,
    channel_model,
    pointing,
    received_gain,
    trace,
)
from waterair.physics.link import LinkBudget, LinkPerformance, Receiver, link_performance
from waterair.physics.optics import RefractiveIndices
from waterair.physics.paths import CentroidOptions, NewtonOptions, PathSolution, flat_sea_point, solve_path
from waterair.physics.paths.census import CensusOptions, RefractionPoints, refraction_points
from waterair.physics.sea import (
    ElfouhailySea,
    JonswapSea,
    MeanSquareSlope,
    SeaState,
    cox_munk,
    elevation_spectrum,
    jonswap,
    sea_state,
    spreading,
)
from waterair.physics.surface import Harmonics, SurfaceSample, WaveSurface

__all__ = [
    "CHANNELS",
    "CensusOptions",
    "CentroidOptions",
    "ChannelGain",
    "ChannelModel",
    "ElfouhailySea",
    "Harmonics",
    "JonswapSea",
    "LightSamples",
    "LinkEnds",
    "LinkBudget",
    "LinkGeometry",
    "LinkPerformance",
    "MeanSquareSlope",
    "MonteCarlo",
    "MonteCarloLight",
    "NewtonOptions",
    "PathSolution",
    "RayTube",
    "Receiver",
    "RefractionPoints",
    "RefractiveIndices",
    "SeaState",
    "SinglePath",
    "SurfaceSample",
    "Transceiver",
    "TwoScale",
    "WaveSurface",
    "calm_sea_gain",
    "channel_gain",
    "channel_model",
    "cox_munk",
    "elevation_spectrum",
    "flat_sea_point",
    "jonswap",
    "link_performance",
    "pointing",
    "received_gain",
    "sea_state",
    "refraction_points",
    "solve_path",
    "spreading",
    "trace",
]
