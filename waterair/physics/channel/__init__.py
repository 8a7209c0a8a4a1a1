"""Channel models: how much of the beam reaches the receiver (docs/model.md §4).

Every model is a :class:`~.model.ChannelModel` (the interface, §4.7), each built by an option of
the ``env/channel`` group (:mod:`.registry`: one class per option, registered in ``CHANNELS``):

* :class:`SinglePath` (:mod:`.single_path`): the paper's model, one refracted path with a flat-sea
  power law (``env/channel=single_path``, ``+experiment=paper``).
* :class:`RayTube` (:mod:`.ray_tube`): the exact power through one refraction point, with its
  lensing (the ray-tube factor), bounded by the aperture at caustics; the calm-sea reference G_0.
* :class:`TwoScale` (:mod:`.lattice`): every point of the resolved surface blurred by the
  unresolved slopes and the aperture (``env/channel=full`` on the measured-slope sea).
* :class:`LocalEstimate` (:mod:`.local_estimate`): the Monte Carlo reference as a local estimate (every
  surface hit sends its light to points of the aperture through the facet density), on a two-scale sea.
* :class:`MonteCarlo` (:mod:`.montecarlo`): the hit-counting ray tracer, the local estimate's check where
  counting is precise, and the reference on a sea without unresolved slopes.

Around them: :mod:`.light` (the light at the receiver as weighted rays, and what a pointing makes of
it: gain, upper bound, centroid, for every model), :mod:`.facets` (the facet a ray needs and the
aperture's blur), :mod:`.geometry` (where the ends are and what optics they carry), :mod:`.beacon` (the
drone's beacon, read at the transmitter through the same light reversed).
"""

from waterair.physics.channel.beacon import BEACON_POINTINGS, Beacon, BeaconReading, read_beacon
from waterair.physics.channel.geometry import LinkGeometry, Transceiver, pointing
from waterair.physics.channel.lattice import (
    LATTICE_NODES,
    LATTICE_SPAN,
    Lattice,
    TwoScale,
    lattice_shape,
    two_scale_light,
)
from waterair.physics.channel.light import (
    LightSamples,
    Reception,
    brightest,
    light_centroid,
    pointed_gains,
    receive,
    received_gain,
    upper_bound,
)
from waterair.physics.channel.local_estimate import LocalEstimate, arrival_jacobian, facet_density
from waterair.physics.channel.model import ChannelModel, LinkEnds
from waterair.physics.channel.montecarlo import MonteCarlo, MonteCarloLight, standard_error, trace
from waterair.physics.channel.ray_tube import (
    RayTube,
    calm_sea_reference,
    flat_sea_irradiance,
    hessian_eigenvectors,
    ray_tube_factor,
    ray_tube_light,
)
from waterair.physics.channel.registry import (
    CHANNELS,
    Channel,
    CountingChannel,
    FullChannel,
    MonteCarloChannel,
    SinglePathChannel,
    channel,
    channel_model,
)
from waterair.physics.channel.single_path import ChannelGain, SinglePath, calm_sea_gain, calm_sea_gains, channel_gain

__all__ = [
    "BEACON_POINTINGS",
    "CHANNELS",
    "Beacon",
    "BeaconReading",
    "LATTICE_NODES",
    "LATTICE_SPAN",
    "Channel",
    "ChannelGain",
    "ChannelModel",
    "CountingChannel",
    "FullChannel",
    "Lattice",
    "LightSamples",
    "LinkEnds",
    "LinkGeometry",
    "LocalEstimate",
    "MonteCarlo",
    "MonteCarloChannel",
    "MonteCarloLight",
    "RayTube",
    "Reception",
    "SinglePath",
    "SinglePathChannel",
    "Transceiver",
    "TwoScale",
    "brightest",
    "calm_sea_gain",
    "calm_sea_gains",
    "calm_sea_reference",
    "channel",
    "channel_gain",
    "channel_model",
    "flat_sea_irradiance",
    "hessian_eigenvectors",
    "lattice_shape",
    "light_centroid",
    "pointed_gains",
    "pointing",
    "ray_tube_factor",
    "ray_tube_light",
    "read_beacon",
    "receive",
    "received_gain",
    "standard_error",
    "arrival_jacobian",
    "facet_density",
    "trace",
    "two_scale_light",
    "upper_bound",
]
