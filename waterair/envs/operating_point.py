"""The operating point: the quantities each link may draw at a reset (``env.<name>_range``, ``env.<name>_values``),
and ``env.<name>``, one value of it for every link, written into the group's key that holds it
(docs/environment.md, "The operating point").

:func:`fixed` checks a config's operating point and gives what it writes into the groups; :func:`followed` makes
a ``replace`` keep the point and its group's key together.
"""

from __future__ import annotations

from collections.abc import Mapping

from waterair.core.validation import check_range
from waterair.envs.groups import as_mapping

PER_LINK = {
    "wind": (0.0, 60.0, "m/s"),
    "offset": (0.0, 10.0, ""),
    "offset_azimuth": (-360.0, 360.0, "deg"),
    "wind_direction": (-360.0, 360.0, "deg"),
    "divergence": (0.0, 1.5, "rad"),
}
"""Quantities each link may draw from ``<name>_range`` or take from ``<name>_values``: (low, high, unit)."""
LOW_OPEN = ("wind", "divergence")
"""The :data:`PER_LINK` quantities whose lower bound is excluded."""
FIXED = {
    "wind": ("sea", "wind"),
    "wind_direction": ("sea", "wind_direction_deg"),
    "offset": ("geometry", "offset_ratio"),
    "offset_azimuth": ("geometry", "offset_azimuth_deg"),
    "divergence": ("optics", "divergence"),
}
"""Each :data:`PER_LINK` quantity → the group's key that holds its one value. ``env.<name>`` gives every link that
value: it sets the group's key and leaves the draws off."""


def fixed(config, defaults: Mapping) -> dict:
    """What ``config``'s operating point writes: each ``env.<name>`` given, in range and as a float, and each group
    it names as a mapping with its key set (a group given as an object is left as it is). ``defaults``: each
    group's default object, which a group not given still is. Raises ``ValueError`` where a point is given with its
    own range or values, or with its group's key at another value."""
    writes: dict = {}
    for name, (group, key) in FIXED.items():
        value = getattr(config, name)
        if value is None:
            continue
        low, high, unit = PER_LINK[name]
        value = writes[name] = float(check_range(f"env.{name}", value, low, high, low_open=name in LOW_OPEN, unit=unit))
        for draw in (f"{name}_range", f"{name}_values"):
            if getattr(config, draw) is not None:
                raise ValueError(
                    f"env.{name} = {value:g} and env.{draw} = {list(getattr(config, draw))} are both set; env.{name} "
                    f"gives every link one value, env.{draw} gives each its own: set one (env.{draw}=null)"
                )
        given = writes.get(group, getattr(config, group))
        if getattr(config, group) is defaults[group]:  # the group was not given: its default, with this value
            given = given if isinstance(given, Mapping) else as_mapping(given)
        elif (stated := given.get(key) if isinstance(given, Mapping) else getattr(given, key)) not in (None, value):
            raise ValueError(
                f"env.{name} = {value:g} and env.{group}.{key} = {stated:g} disagree; env.{name} sets "
                f"env.{group}.{key}: give one of them"
            )
        if isinstance(given, Mapping):
            writes[group] = {**given, key: value}
    return writes


def followed(changes: Mapping) -> dict:
    """``changes`` of a ``replace`` with the operating point and its group's key kept together: a point given sets
    its group's key (where the change does not state it), and a quantity set another way (its range, its values,
    its group's key) is no longer the point's."""
    changes = dict(changes)
    for name, (group, key) in FIXED.items():
        given = changes.get(group)
        if changes.get(name) is not None:
            if given is None or (isinstance(given, Mapping) and key not in given):
                changes[group] = {**(given or {}), key: changes[name]}
        elif name not in changes and (
            changes.get(f"{name}_range") is not None
            or changes.get(f"{name}_values") is not None
            or (given is not None and (not isinstance(given, Mapping) or key in given))
        ):
            changes[name] = None
    return changes
