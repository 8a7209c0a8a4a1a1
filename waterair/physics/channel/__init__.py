"""Channel models: how much of the beam reaches the receiver (docs/model.md §4).

* :mod:`.single_path`: the paper's model, one refracted path with a flat-sea power law
  (``env.channel=single_path``, ``+experiment=paper``).
* :mod:`.ray_tube`: the exact power through one refraction point, with its lensing (the
  ray-tube factor), bounded by the aperture at caustics; the calm-sea reference G_0.
* :mod:`.lattice`: the two-scale channel, every point of the resolved surface blurred by the
  unresolved slopes and the aperture (``env.channel=full`` on the measured-slope sea).
* :mod:`.light`: the light at the receiver as weighted rays, the gain of a pointing, the upper bound
  and the light's centroid on the detector, shared by both and by the Monte Carlo tracer.
* :mod:`.geometry`: where the ends are and what optics they carry.
"""

from waterair.physics.channel.geometry import LinkGeometry, Transceiver, pointing
from waterair.physics.channel.lattice import LATTICE_NODES, LATTICE_SPAN, lattice_shape, two_scale_light
from waterair.physics.channel.light import LightSamples, light_centroid, pointed_gains, received_gain, upper_bound
from waterair.physics.channel.ray_tube import (
    calm_sea_reference,
    flat_sea_irradiance,
    hessian_eigenvectors,
    ray_tube_factor,
    ray_tube_light,
)
from waterair.physics.channel.single_path import (
    ChannelGain,
    calm_sea_gain,
    calm_sea_gains,
    channel_gain,
    gain_upper_bound,
)

__all__ = [
    "LATTICE_NODES",
    "LATTICE_SPAN",
    "ChannelGain",
    "LightSamples",
    "LinkGeometry",
    "Transceiver",
    "calm_sea_gain",
    "calm_sea_gains",
    "calm_sea_reference",
    "channel_gain",
    "flat_sea_irradiance",
    "gain_upper_bound",
    "hessian_eigenvectors",
    "lattice_shape",
    "light_centroid",
    "pointed_gains",
    "pointing",
    "ray_tube_factor",
    "ray_tube_light",
    "received_gain",
    "two_scale_light",
    "upper_bound",
]
