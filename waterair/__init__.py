"""waterair: learning beam alignment for direct water-to-air optical wireless links.

The physics layer can be used on its own (no TorchRL needed)::

    from waterair import sea_state, WaveSurface, LinkGeometry, Transceiver, solve_path, channel_model

    surface = WaveSurface.sample(sea_state("jonswap", wind=12.0), batch_size=1024, seed=0)
    tx, rx = LinkGeometry().positions()
    path = solve_path(surface, tx, rx, t=0.0)
    model = channel_model("full", Transceiver(), two_scale_sea=False)   # README, "A short tour"
"""

from waterair import physics
from waterair.physics import *  # noqa: F403  (the physics API, re-exported)

__all__ = physics.__all__

__version__ = "0.1.0"
