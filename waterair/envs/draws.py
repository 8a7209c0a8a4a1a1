"""What each link gets at a reset: its wind, wind direction, offset, azimuth, beam divergence and sea
(docs/environment.md, "Start"), and where the random numbers come from (docs/model.md §10).

Each is drawn uniformly from ``<name>_range`` (the divergence uniformly in its logarithm), cycled from the
scenario list ``<name>_values`` (link i takes entry i mod its length), or left to the default. Replicas share
their draws: a batch of k replicas draws once per distinct link (:func:`distinct_links`) and copies to each
replica.

With ``env.draws=keyed`` (:class:`KeyedDraws`) each draw is a hash of (seed, the link's realisation, its episode,
the draw's role): what a link gets does not depend on the links beside it, and realisation r of every scenario
point (link i is point i mod P, realisation i div P) shares its draws, so that points are paired. With
``env.draws=stream`` (:class:`StreamDraws`, the paper's) the batch draws in order from one generator (the
sea's conditions, its surface, the geometry, then the divergence).
"""

from __future__ import annotations

import math

import torch

from waterair.core.hashing import key, mix, uniforms
from waterair.envs.config import EnvConfig
from waterair.envs.noise import box_muller, draw_nonce, normals, stream_keys
from waterair.envs.operating_point import PER_LINK
from waterair.envs.sensors import SensorNoise
from waterair.physics.motion import MOTION_WIDTH
from waterair.physics.motion import motion_start as start_motion

ROLES = {
    "wind": 1,
    "wind_direction": 2,
    "jitter": 3,
    "phase": 4,
    "offset": 5,
    "offset_azimuth": 6,
    "divergence": 7,
    "motion": 8,
    "parking": 9,
}
"""Each keyed draw's role, a part of its key: a link's draws for two roles are independent."""


class StreamDraws:
    """Uniforms in order from ``generator`` for the links of one reset."""

    def __init__(self, generator: torch.Generator) -> None:
        self.generator = generator

    def uniform(self, role: str, count: int, links: int) -> torch.Tensor:
        """``count`` uniforms ``[links, count]`` float64 for the draw ``role``: the generator's next."""
        return torch.rand(links, count, generator=self.generator, dtype=torch.float64)


class KeyedDraws:
    """Uniforms hashed from each link's ``keys`` ``[m]`` (int64, :func:`link_keys`) and the draw's role."""

    def __init__(self, keys: torch.Tensor) -> None:
        self.keys = keys

    def uniform(self, role: str, count: int, links: int) -> torch.Tensor:
        """``count`` uniforms ``[links, count]`` float64 for the draw ``role`` of each link."""
        return uniforms(key(self.keys, ROLES[role]), count)


def points(config: EnvConfig) -> int:
    """The scenario points a batch's links cycle through: the length of its ``*_values`` lists (one length when
    several are given, as the config checks), or 1."""
    return next((len(values) for name in PER_LINK if (values := getattr(config, f"{name}_values")) is not None), 1)


def realisations(config: EnvConfig, links: torch.Tensor) -> torch.Tensor:
    """Each of ``links``' (distinct links' indices, ``[m]``) realisation ``[m]`` int64: ``env.link_offset`` plus
    its index over the points (link i is point i mod P, realisation i div P)."""
    return config.link_offset + links.cpu().to(torch.int64) // points(config)


def noise_keys(config: EnvConfig) -> torch.Tensor:
    """Each row's sensor-noise stream key ``[num_envs]`` (:mod:`waterair.envs.noise`): its distinct link's, or with
    keyed draws its realisation's, so that realisation r of every point reads the same noise."""
    if config.draws == "stream":
        return stream_keys(config.num_envs, config.replicas)
    return mix(realisations(config, torch.arange(config.num_envs) % (config.num_envs // config.replicas)) + 1)


def link_keys(config: EnvConfig, seed: int, links: torch.Tensor, episodes: torch.Tensor) -> torch.Tensor:
    """The keys ``[m]`` of ``links``' draws at their ``episodes`` ``[m]`` (each link's resets so far)."""
    return key(seed, realisations(config, links), episodes.cpu())


def distinct_links(config: EnvConfig, rows: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The distinct links ``[m]`` behind ``rows`` ``[n]`` (replicas share one), and where each row is among them."""
    return torch.unique(rows % (config.num_envs // config.replicas), return_inverse=True)


def sea_conditions(config: EnvConfig, links: torch.Tensor, draws):
    """Wind speed (m/s) and wind direction (deg) ``[m]`` float64 for distinct ``links``, or None (the sea's own)."""
    wind = per_link(config.wind_range, config.wind_values, None, links, draws, "wind")
    direction = per_link(
        config.wind_direction_range, config.wind_direction_values, None, links, draws, "wind_direction"
    )
    return wind, direction


def geometry(config: EnvConfig, links: torch.Tensor, draws):
    """Offset ratio ``[m]`` and offset azimuth (deg) ``[m]`` or None (the geometry's own), float64."""
    offset = per_link(config.offset_range, config.offset_values, config.geometry.offset_ratio, links, draws, "offset")
    azimuth = per_link(config.offset_azimuth_range, config.offset_azimuth_values, None, links, draws, "offset_azimuth")
    return offset, azimuth


def divergence(config: EnvConfig, links: torch.Tensor, draws) -> torch.Tensor:
    """The beam divergence ω_D (rad) ``[m]`` float64 of distinct ``links``: log-uniform in ``divergence_range``,
    cycled from ``divergence_values``, or the optics' own."""
    return per_link(
        config.divergence_range, config.divergence_values, config.optics.divergence, links, draws, "divergence", True
    )


def per_link(bounds, values, default, links: torch.Tensor, draws, role: str, log: bool = False) -> torch.Tensor | None:
    """float64 ``[m]`` values for ``links``: drawn (``draws``' uniforms for ``role``) from ``bounds`` (uniformly,
    or uniformly in the logarithm with ``log``), cycled from ``values``, or ``default``."""
    count = links.numel()
    if bounds is not None:
        low, high = (math.log(b) for b in bounds) if log else bounds
        drawn = low + (high - low) * draws.uniform(role, 1, count)[:, 0]
        return drawn.exp() if log else drawn
    if values is not None:
        return torch.tensor(values, dtype=torch.float64)[links.cpu() % len(values)]
    return None if default is None else torch.full((count,), default, dtype=torch.float64)


def motion_start(config: EnvConfig, links: torch.Tensor, draws) -> torch.Tensor:
    """The stationary start ``[m, MOTION_WIDTH]`` float64 of ``env.motion`` for distinct ``links``
    (:func:`waterair.physics.motion.motion_start`), from ``draws``' uniforms for its role, made standard normal."""
    return start_motion(config.motion, box_muller(draws.uniform("motion", MOTION_WIDTH, links.numel())))


def parking(draws, links: torch.Tensor) -> torch.Tensor:
    """Where on its crossing a ``parked`` drone stands, for distinct ``links``: a uniform ``[m]`` float64 in (0, 1)
    of the crossing's stretch (``env.motion``, :class:`~waterair.physics.motion.Motion`), from ``draws``."""
    return draws.uniform("parking", 1, links.numel())[:, 0]


def motion_normals(keys: torch.Tensor, sensed: SensorNoise | None, generator: torch.Generator, dtype, device):
    """A step's draws with the ends' motion's among them: ``sensed`` (the sensor's, or zeros where it draws none)
    with ``motion`` ``[n, MOTION_WIDTH]`` standard normals of the streams ``keys`` (:mod:`waterair.envs.noise`: a
    nonce of their own from ``generator``, the rows' keys salted with the motion's role)."""
    motion = normals(keys ^ ROLES["motion"], draw_nonce(generator), MOTION_WIDTH).to(device=device, dtype=dtype)
    if sensed is None:
        zero, pair = torch.zeros_like(motion[:, 0]), torch.zeros_like(motion[:, :2])
        sensed = SensorNoise(zero, zero, pair, pair)
    return sensed._replace(motion=motion)
