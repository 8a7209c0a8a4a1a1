"""Parameter validation shared by every layer.

Every check raises :class:`ValueError` whose message names the parameter, the value it got and
the allowed range, so that a config typo reads as one line rather than a traceback wall.
"""

from __future__ import annotations

import math
from collections.abc import Iterable


def check_range(
    name: str,
    value: float,
    low: float = -math.inf,
    high: float = math.inf,
    *,
    low_open: bool = False,
    high_open: bool = False,
    unit: str = "",
) -> float:
    """Return ``value`` if it lies in the interval, else raise a one-line ``ValueError``.

    Args:
        name: the parameter or config key, e.g. ``"env.sea.wind"``.
        value: the value to check (a real number; NaN is always rejected).
        low, high: interval bounds.
        low_open, high_open: whether each bound is excluded.
        unit: unit appended to the message, e.g. ``"m/s"``.
    """
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {value!r} is not a number") from None
    below = number <= low if low_open else number < low
    above = number >= high if high_open else number > high
    if math.isnan(number) or below or above:
        left = "(" if low_open else "["
        right = ")" if high_open else "]"
        suffix = f" {unit}" if unit else ""
        raise ValueError(f"{name} = {value!r} is out of range; allowed {left}{_fmt(low)}, {_fmt(high)}{right}{suffix}")
    return number


def check_int(name: str, value: int, low: int = 1, high: float = math.inf) -> int:
    """Return ``value`` if it is an integer in ``[low, high]``, else raise ``ValueError``."""
    if isinstance(value, bool) or not isinstance(value, int | float) or int(value) != value:
        raise ValueError(f"{name} = {value!r} is not an integer; allowed [{low}, {_fmt(high)}]")
    check_range(name, value, low, high)
    return int(value)


def check_choice(name: str, value: str, choices: Iterable[str]) -> str:
    """Return ``value`` if it is one of ``choices``, else raise ``ValueError``."""
    options = tuple(choices)
    if value not in options:
        raise ValueError(f"{name} = {value!r} is not allowed; choose one of {', '.join(options)}")
    return value


def _fmt(bound: float) -> str:
    if math.isinf(bound):
        return "inf" if bound > 0 else "-inf"
    return f"{bound:g}"
