"""Sensor noise in streams: what a link's sensor draws depends on its link and the reading, never on which links
run beside it or how many (docs/environment.md, "Sensing").

Each row of a batch has a *stream key*, its distinct link's: the replicas of a link, the controllers an
evaluation compares side by side, share it, so that they read common noise as they sail common seas. Each
reading draws one 62-bit *nonce* from the sensor's generator, one whatever the batch's size, and a row's
standard normals are a counter-based hash of (key, nonce, column): SplitMix64's finaliser (Steele, Lea, Flood,
OOPSLA 2014), then Box–Muller. So a controller scores the same alone, beside others and under any name, and a
seed still replays a run bit for bit.
"""

from __future__ import annotations

import math

import torch

_MIX1 = 0xBF58476D1CE4E5B9 - (1 << 64)  # SplitMix64's multipliers and increment, as signed int64
_MIX2 = 0x94D049BB133111EB - (1 << 64)
_GOLDEN = 0x9E3779B97F4A7C15 - (1 << 64)
NONCE_BITS = 62
"""Each reading's nonce is uniform on [0, 2^62)."""


def _shift_right(x: torch.Tensor, bits: int) -> torch.Tensor:
    """Logical right shift of int64 ``x`` (torch's ``>>`` keeps the sign)."""
    return (x >> bits) & ((1 << (64 - bits)) - 1)


def mix(x: torch.Tensor) -> torch.Tensor:
    """SplitMix64's finaliser on int64 ``x`` (products wrap as the unsigned ones do, modulo 2^64): a bijection
    of 64-bit words whose every output bit depends on every input bit."""
    x = (x ^ _shift_right(x, 30)) * _MIX1
    x = (x ^ _shift_right(x, 27)) * _MIX2
    return x ^ _shift_right(x, 31)


def stream_keys(rows: int, replicas: int) -> torch.Tensor:
    """Each row's stream key ``[rows]`` int64 (CPU) for a batch of ``replicas`` blocks of distinct links: row r
    is link r mod (rows / replicas), and replicas of a link share its key."""
    return mix(torch.arange(rows, dtype=torch.int64) % (rows // replicas) + 1)


def draw_nonce(generator: torch.Generator) -> int:
    """One reading's nonce from ``generator``: one draw per reading, whatever the number of rows."""
    return int(torch.randint(0, 1 << NONCE_BITS, (), generator=generator))


def normals(keys: torch.Tensor, nonce: int, columns: int) -> torch.Tensor:
    """Standard normal draws ``[n, columns]`` float64 of the streams ``keys`` ``[n]`` at ``nonce``
    (``columns`` even): Box–Muller on uniforms (0, 1) hashed from (key, nonce, column)."""
    base = mix(keys ^ nonce).unsqueeze(-1)
    counters = torch.arange(1, columns + 1, dtype=torch.int64) * _GOLDEN
    words = mix(base + counters)
    uniform = (_shift_right(words, 11).to(torch.float64) + 0.5) * 2.0**-53
    first, second = uniform[:, 0::2], uniform[:, 1::2]
    radius = torch.sqrt(-2.0 * torch.log(first))
    angle = 2.0 * math.pi * second
    return torch.stack((radius * torch.cos(angle), radius * torch.sin(angle)), dim=-1).reshape(keys.numel(), columns)
