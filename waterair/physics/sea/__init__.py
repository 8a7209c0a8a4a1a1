"""Sea states: the paper's JONSWAP band and the measured-slope Elfouhaily sea (docs/model.md §1).

:class:`SeaState` is the validated sea and its discretisation; :mod:`.jonswap` and
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
from waterair.physics.sea.jonswap import GRAVITY, jonswap, jonswap_alpha, jonswap_omega_p, spreading
from waterair.physics.sea.slopes import CoxMunk, MeanSquareSlope, cox_munk, elfouhaily_slope_variance
from waterair.physics.sea.state import SPECTRA, SeaState

__all__ = [
    "GRAVITY",
    "SPECTRA",
    "CoxMunk",
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
    "spreading",
    "spreading_ratio",
]
