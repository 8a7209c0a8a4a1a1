"""The flat env keys of the first releases and where each lives now (docs/environment.md, "Renamed keys").

Until the env's config was made of the physics' own configs, the sea, the link's geometry and the
optics were flat keys of the ``env`` group (``env.wind``, ``env.aperture_diameter``); they are now
``env.sea.wind``, ``env.optics.aperture_diameter`` and so on, and the sea's presets are named after
the sea they choose (``env/spectrum=jonswap|elfouhaily``, formerly ``paper|ocean``). The configs of
old runs and shipped policies, ``WaterAirEnv(wind=8)`` and old command lines still work:
:func:`nest` folds flat keys into their groups, and the command line is rewritten before Hydra
composes it (:mod:`waterair.cli.preflight`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

from waterair.physics.channel import LinkGeometry, Transceiver
from waterair.physics.sea import SPECTRA, SeaState


def _names(kind) -> tuple[str, ...]:
    return tuple(field.name for field in dataclasses.fields(kind))


GROUPS = {
    "sea": ("spectrum", *sorted({name for kind in SPECTRA.values() for name in _names(kind)} - {"flat"})),
    "geometry": _names(LinkGeometry),
    "optics": _names(Transceiver),
}
"""The env's physics groups and the keys each has (the sea's: those of every sea, and its name)."""
MOVED = {key: f"{group}.{key}" for group, keys in GROUPS.items() for key in keys}
"""Old flat key → its path under ``env`` now (``wind`` → ``sea.wind``)."""
DEFAULT_SPECTRUM = "elfouhaily"
"""The sea of a config that names none (``EnvConfig``'s default, the measured-slope sea)."""
SPECTRUM_OPTIONS = {"paper": "jonswap", "ocean": "elfouhaily"}
"""Old option of the ``env/spectrum`` group → its name now (the name of the sea it chooses)."""
SHARED_SEA_KEYS = ("wind", "fetch", "wind_direction_deg", "amplitude")
"""The conditions every sea describes: what a sea keeps when a change names another sea (which brings its own
discretisation, ``n_dir`` included)."""


def nest(values: Mapping) -> dict:
    """``values`` with every old flat key folded into its group; a flat key wins over the same nested key.

    A flat key that the named sea does not have is dropped, as the old releases ignored it (their
    configs list both seas' own keys); the same key given nested is an error where the sea is built.
    A flat ``spectrum`` that names another sea than the nested one keeps the nested sea's shared keys only.
    """
    out = {key: value for key, value in values.items() if key not in MOVED}
    flat = {key: value for key, value in values.items() if key in MOVED}
    if not flat:
        return out
    nested_sea = out.get("sea")
    if "spectrum" in flat and nested_sea is not None:
        nested_sea = dict(nested_sea) if isinstance(nested_sea, Mapping) else as_mapping(nested_sea)
        if nested_sea.get("spectrum", DEFAULT_SPECTRUM) != flat["spectrum"]:
            out["sea"] = {key: value for key, value in nested_sea.items() if key in SHARED_SEA_KEYS}
    for key, value in flat.items():
        group, name = MOVED[key].split(".")
        nested = out.get(group)
        if nested is None or isinstance(nested, Mapping):
            out[group] = {**(nested or {}), name: value}
        else:  # a physics object given whole, and a flat key beside it: the key changes that object
            out[group] = {**as_mapping(nested), name: value}
    sea = out.get("sea")
    if isinstance(sea, Mapping):
        kind = SPECTRA.get(sea.get("spectrum", DEFAULT_SPECTRUM))
        if kind is not None:
            own = {*_names(kind), "spectrum"}
            dropped = {key for key in flat if MOVED[key].startswith("sea.") and key not in own}
            out["sea"] = {key: value for key, value in sea.items() if key not in dropped}
    return out


BEFORE_THE_OCEAN = {"channel": "single_path", "spectrum": "jonswap"}
"""The defaults a saved config was written under if it does not name these keys: until the measured-slope sea
and the full channel became the defaults, a config that left them out ran the paper's sea and channel."""


def saved(values: Mapping) -> dict:
    """A saved run's env config (``config.yaml``) as :func:`nest` folds it, and with the keys whose default
    has moved since its release set to what they were then (:data:`BEFORE_THE_OCEAN`), so that it runs the
    physics it ran. Configs written since name every key, so they are unchanged."""
    values = {"channel": BEFORE_THE_OCEAN["channel"], **values}
    sea = values.get("sea")
    if "spectrum" not in values and not (isinstance(sea, Mapping) and "spectrum" in sea):
        if isinstance(sea, Mapping):
            values["sea"] = {**sea, "spectrum": BEFORE_THE_OCEAN["spectrum"]}
        else:  # flat, as the first releases wrote it
            values["spectrum"] = BEFORE_THE_OCEAN["spectrum"]
    return nest(values)


def as_mapping(physics) -> dict:
    """A sea, geometry or optics object as the keys that rebuild it (a sea's with its ``spectrum``)."""
    keys = {name: getattr(physics, name) for name in _names(physics)}
    if isinstance(physics, SeaState):
        keys = {"spectrum": physics.spectrum, **keys}
        if not keys["flat"]:
            del keys["flat"]
    return keys
