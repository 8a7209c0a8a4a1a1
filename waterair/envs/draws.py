"""What each link gets at a reset: its wind, wind direction, offset, azimuth and beam divergence
(docs/environment.md, "Start").

Each is drawn uniformly from ``<name>_range`` (the divergence uniformly in its logarithm), cycled from the
scenario list ``<name>_values`` (link i takes entry i mod its length), or left to the default. Replicas share
their draws: a batch of k replicas draws once per distinct link (:func:`distinct_links`) and copies to each
replica. The environment draws in a fixed order (the sea's conditions, its surface, the geometry, then the divergence),
so that a seed gives the same seas and geometry whatever else is configured.
"""

from __future__ import annotations

import math

import torch

from waterair.envs.config import EnvConfig


def distinct_links(config: EnvConfig, rows: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The distinct links ``[m]`` behind ``rows`` ``[n]`` (replicas share one), and where each row is among them."""
    return torch.unique(rows % (config.num_envs // config.replicas), return_inverse=True)


def sea_conditions(config: EnvConfig, links: torch.Tensor, generator: torch.Generator):
    """Wind speed (m/s) and wind direction (deg) ``[m]`` float64 for distinct ``links``, or None (the sea's own)."""
    wind = per_link(config.wind_range, config.wind_values, None, links, generator)
    direction = per_link(config.wind_direction_range, config.wind_direction_values, None, links, generator)
    return wind, direction


def geometry(config: EnvConfig, links: torch.Tensor, generator: torch.Generator):
    """Offset ratio ``[m]`` and offset azimuth (deg) ``[m]`` or None (the geometry's own), float64."""
    offset = per_link(config.offset_range, config.offset_values, config.geometry.offset_ratio, links, generator)
    azimuth = per_link(config.offset_azimuth_range, config.offset_azimuth_values, None, links, generator)
    return offset, azimuth


def divergence(config: EnvConfig, links: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """The beam divergence ω_D (rad) ``[m]`` float64 of distinct ``links``: log-uniform in ``divergence_range``,
    cycled from ``divergence_values``, or the optics' own."""
    return per_link(
        config.divergence_range, config.divergence_values, config.optics.divergence, links, generator, log=True
    )


def per_link(
    bounds, values, default, links: torch.Tensor, generator: torch.Generator, log: bool = False
) -> torch.Tensor | None:
    """float64 ``[m]`` values for ``links``: drawn from ``bounds`` (uniformly, or uniformly in the logarithm
    with ``log``), cycled from ``values``, or ``default``."""
    count = links.numel()
    if bounds is not None:
        low, high = (math.log(b) for b in bounds) if log else bounds
        drawn = low + (high - low) * torch.rand(count, generator=generator, dtype=torch.float64)
        return drawn.exp() if log else drawn
    if values is not None:
        return torch.tensor(values, dtype=torch.float64)[links.cpu() % len(values)]
    return None if default is None else torch.full((count,), default, dtype=torch.float64)
