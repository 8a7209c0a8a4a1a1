"""waterair: learning beam alignment for direct water-to-air optical wireless links.

The physics layer can be used on its own (no TorchRL needed)::

    import torch
    from waterair import SeaState, WaveSurface, LinkGeometry, Transceiver, solve_path, channel_gain

    surface = WaveSurface.sample(SeaState(wind=12.0), batch_size=1024, seed=0)
    tx, rx = LinkGeometry().positions()
    path = solve_path(surface, tx, rx, t=0.0)
"""

from waterair.channel import (
    ChannelGain,
    LinkGeometry,
    Transceiver,
    calm_sea_gain,
    channel_gain,
    gain_upper_bound,
    pointing,
)
from waterair.paths import CentroidOptions, NewtonOptions, PathSolution, flat_sea_point, solve_path
from waterair.sea import SeaState, jonswap, spreading
from waterair.surface import SurfaceSample, WaveSurface

__all__ = [
    "CentroidOptions",
    "ChannelGain",
    "LinkGeometry",
    "NewtonOptions",
    "PathSolution",
    "SeaState",
    "SurfaceSample",
    "Transceiver",
    "WaveSurface",
    "calm_sea_gain",
    "channel_gain",
    "flat_sea_point",
    "gain_upper_bound",
    "jonswap",
    "pointing",
    "solve_path",
    "spreading",
]
__version__ = "0.1.0"
