"""Sea states: the paper's JONSWAP band and the measured-slope Elfouhaily sea (docs/model.md §1).

:class:`SeaState` is what every sea shares (its discretisation, its slopes); :class:`JonswapSea` and
:class:`ElfouhailySea` are the two seas, :func:`sea_state` builds one by name; :mod:`.jonswap` and
:mod:`.elfouhaily` hold one pure function per formula; :mod:`.slopes` the mean square slopes and
the Cox-Munk fits they are checked against.
"""

from waterair.physics.sea.elfouhaily import (
    angular_frequency,
    curvature_spectrum,
    elevation_spectrum,
    elfouhaily_spreading,
    friction_velocity,
    inverse_wave_age,
    peak_wavenumber,
    phase_speed,
    spreading_ratio,
)
from waterair.physics.sea.elfouhaily_sea import ElfouhailySea
from waterair.physics.sea.jonswap import GRAVITY, jonswap, jonswap_alpha, jonswap_omega_p, spreading
from waterair.physics.sea.jonswap_sea import JonswapSea
from waterair.physics.sea.slopes import CoxMunk, MeanSquareSlope, cox_munk, elfouhaily_slope_variance
from waterair.physics.sea.spectra import SPECTRA, sea_state
from waterair.physics.sea.state import SeaState

__all__ = [
    "GRAVITY",
    "SPECTRA",
    "CoxMunk",
    "ElfouhailySea",
    "JonswapSea",
    "MeanSquareSlope",
    "SeaState",
    "angular_frequency",
    "cox_munk",
    "curvature_spectrum",
    "elevation_spectrum",
    "elfouhaily_slope_variance",
    "elfouhaily_spreading",
    "friction_velocity",
    "inverse_wave_age",
    "jonswap",
    "jonswap_alpha",
    "jonswap_omega_p",
    "peak_wavenumber",
    "phase_speed",
    "sea_state",
    "spreading",
    "spreading_ratio",
]
