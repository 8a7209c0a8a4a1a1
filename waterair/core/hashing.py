"""Counter-based random numbers: a draw is a hash of what it is for, never of where it sits in a stream.

SplitMix64's finaliser (Steele, Lea, Flood, OOPSLA 2014) in int64 tensor ops: :func:`key` folds the parts of a
key (a seed, a realisation, a role) into one 64-bit word, :func:`uniforms` turns each key into a row of uniforms
on (0, 1). Computed on the CPU, so CPU and CUDA draw the same numbers (docs/model.md §10).
"""

from __future__ import annotations

import torch

_MIX1 = 0xBF58476D1CE4E5B9 - (1 << 64)  # SplitMix64's multipliers and increment, as signed int64
_MIX2 = 0x94D049BB133111EB - (1 << 64)
GOLDEN = 0x9E3779B97F4A7C15 - (1 << 64)
"""SplitMix64's increment (the golden ratio's 64 bits), as signed int64: what a counter steps by."""


def shift_right(x: torch.Tensor, bits: int) -> torch.Tensor:
    """Logical right shift of int64 ``x`` (torch's ``>>`` keeps the sign)."""
    return (x >> bits) & ((1 << (64 - bits)) - 1)


def mix(x: torch.Tensor) -> torch.Tensor:
    """SplitMix64's finaliser on int64 ``x`` (products wrap as the unsigned ones do, modulo 2^64): a bijection
    of 64-bit words whose every output bit depends on every input bit."""
    x = (x ^ shift_right(x, 30)) * _MIX1
    x = (x ^ shift_right(x, 27)) * _MIX2
    return x ^ shift_right(x, 31)


def key(*parts: torch.Tensor | int) -> torch.Tensor:
    """One int64 key per element of the broadcast ``parts`` (ints, taken modulo 2^64 as a 64-bit seed is, or int64
    tensors): each part mixed into the key so far, so that keys of different parts, or of the same parts in another
    order, differ."""
    word = torch.zeros((), dtype=torch.int64)
    for part in parts:
        if isinstance(part, int):
            part = (part + (1 << 63)) % (1 << 64) - (1 << 63)  # the same 64 bits, as signed int64
        word = mix(word * 3 + torch.as_tensor(part, dtype=torch.int64) * GOLDEN + 1)
    return word


def words(keys: torch.Tensor, count: int) -> torch.Tensor:
    """``count`` hashed words ``[n, count]`` int64 of each of ``keys`` ``[n]``: the key's counters 1 … count."""
    counters = torch.arange(1, count + 1, dtype=torch.int64) * GOLDEN
    return mix(mix(keys).unsqueeze(-1) + counters)


def uniforms(keys: torch.Tensor, count: int) -> torch.Tensor:
    """``count`` uniforms on (0, 1) ``[n, count]`` float64 of each of ``keys`` ``[n]`` (53 bits each)."""
    return (shift_right(words(keys, count), 11).to(torch.float64) + 0.5) * 2.0**-53
