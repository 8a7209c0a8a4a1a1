"""The env's groups of physics keys: each a physics object (the sea, the geometry, the optics, the beacon, the
actuators, the ends' motion, the channel), built from a mapping of its keys, and the keys of earlier releases that
now live in them.

:class:`~waterair.envs.config.EnvConfig` holds the objects; :func:`physics_group` builds one from what a
configuration gives (an error names ``env.<group>.<key>``), :func:`as_mapping` turns one back into its keys.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

from waterair.physics.channel import Channel, LinkGeometry, Transceiver
from waterair.physics.sea import SPECTRA, SeaState, sea_state

DEFAULT_SPECTRUM = "elfouhaily"
"""The sea of a config that names none: the measured-slope sea."""
SHARED_SEA_KEYS = ("wind", "fetch", "wind_direction_deg", "amplitude")
"""The conditions every sea describes: what a sea keeps when a change names another sea (which brings its own
discretisation, ``n_dir`` included)."""
PHYSICS = ("sea", "geometry", "optics", "beacon", "actuator", "motion", "channel")
"""The env's physics groups: each a physics object, built from a mapping of its keys."""
SEA_KEYS = ("spectrum", *sorted({field.name for kind in SPECTRA.values() for field in dataclasses.fields(kind)}))
"""The keys of every sea, and its name."""
RENAMED = {
    **{name: f"sea.{name}" for name in SEA_KEYS},
    **{f.name: f"geometry.{f.name}" for f in dataclasses.fields(LinkGeometry)},
    **{f.name: f"optics.{f.name}" for f in dataclasses.fields(Transceiver)},
    "lattice_nodes": "channel.nodes",
    "lattice_span": "channel.span",
    "montecarlo_rays": "channel.rays",
    "montecarlo_facets": "channel.facets",
    "montecarlo_points": "channel.points",
}
"""The env keys of earlier releases (flat beside the interface keys) → where each lives now, under ``env``. Two of
those names are today's keys again (:data:`waterair.envs.operating_point.FIXED`): ``env.wind``, ``env.divergence``."""
MIGRATE = "python -m waterair.cli.migrate RUN rewrites an earlier release's run config"


def unknown_key(key: str, known: set[str]) -> str:
    if key in RENAMED:
        return f"env.{key} is env.{RENAMED[key]} in this version ({MIGRATE})"
    return f"env.{key} is not a known key; allowed: {', '.join(sorted(known))}"


def as_mapping(physics) -> dict:
    """A physics group's object as the keys that rebuild it (a sea's with its ``spectrum``, a channel's with its
    ``name``)."""
    keys = {field.name: getattr(physics, field.name) for field in dataclasses.fields(physics)}
    if isinstance(physics, SeaState):
        keys = {"spectrum": physics.spectrum, **keys}
        if not keys["flat"]:
            del keys["flat"]
    if isinstance(physics, Channel):
        keys = {"name": physics.name, **keys}
    return keys


def physics_group(group: str, value, kind: type, build):
    """``value`` as a ``kind``: the object, or built from a mapping of its keys; errors name ``env.<group>.<key>``."""
    if isinstance(value, kind):
        return value
    if isinstance(value, str) and group == "channel":
        raise ValueError(
            f"env.channel = {value!r} must be a mapping of its keys: choose a channel with env/channel={value} "
            f"(in Python, channel={{'name': {value!r}}})"
        )
    if not isinstance(value, Mapping):
        raise ValueError(f"env.{group} = {value!r} must be a mapping of its keys (docs/environment.md)")
    try:
        return build(**{key: plain(item) for key, item in value.items()})
    except TypeError:  # a key the object does not have
        known = [field.name for field in dataclasses.fields(kind)]
        unknown = sorted(set(value) - set(known))
        if not unknown:
            raise
        raise ValueError(f"env.{group}.{unknown[0]} is not a known key; allowed: {', '.join(known)}") from None
    except ValueError as error:
        raise ValueError(f"env.{group}.{error}") from None


def build_sea(spectrum: str = DEFAULT_SPECTRUM, **keys) -> SeaState:
    try:
        return sea_state(spectrum, **keys)
    except ValueError as error:
        if " is not a key of the " in str(error):
            raise ValueError(f"{error} (env/spectrum chooses the sea)") from None
        raise


def plain(value):
    """OmegaConf containers → tuples (the dataclass is frozen and hashable)."""
    if isinstance(value, Sequence) and not isinstance(value, str):
        return tuple(value)
    return value
