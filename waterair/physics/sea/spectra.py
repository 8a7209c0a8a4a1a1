"""The seas by the names a configuration gives them (``env.sea.spectrum``, chosen by ``env/spectrum=``)."""

from __future__ import annotations

import dataclasses

from waterair.core.validation import check_choice
from waterair.physics.sea.elfouhaily_sea import ElfouhailySea
from waterair.physics.sea.jonswap_sea import JonswapSea
from waterair.physics.sea.state import SeaState

SPECTRA: dict[str, type[SeaState]] = {"jonswap": JonswapSea, "elfouhaily": ElfouhailySea}
"""The seas by name: the paper's JONSWAP band and the measured-slope Elfouhaily sea (docs/model.md §1)."""


def sea_state(spectrum: str, **keys) -> SeaState:
    """The sea ``spectrum`` names (no default: a config's default sea is ``EnvConfig``'s), with ``keys``; a key the sea
    does not have is an error naming it."""
    check_choice("spectrum", spectrum, SPECTRA)
    kind = SPECTRA[spectrum]
    known = {field.name for field in dataclasses.fields(kind)}
    unknown = sorted(set(keys) - known)
    if unknown:
        raise ValueError(f"{unknown[0]} is not a key of the {spectrum} sea; its keys: {', '.join(sorted(known))}")
    return kind(**keys)
