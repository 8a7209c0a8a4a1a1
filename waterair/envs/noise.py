"""Sensor noise in streams: what a link's sensor draws depends on its link and the reading, never on which links
run beside it or how many (docs/environment.md, "Sensing").

Each row of a batch has a *stream key*, its distinct link's: the replicas of a link, the controllers an
evaluation compares side by side, share it, so that they read common noise as they sail common seas. Each
reading draws one 62-bit *nonce* from the sensor's generator, one whatever the batch's size, and a row's
standard normals are a counter-based hash of (key, nonce, column) (:mod:`waterair.core.hashing`), then
Box–Muller. So a controller scores the same alone, beside others and under any name, and a
seed still replays a run bit for bit.
"""

from __future__ import annotations

import math

import torch

from waterair.core.hashing import mix, uniforms

NONCE_BITS = 62
"""Each reading's nonce is uniform on [0, 2^62)."""


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
    return box_muller(uniforms(keys ^ nonce, columns))


def box_muller(uniform: torch.Tensor) -> torch.Tensor:
    """Standard normals ``[n, columns]`` from uniforms on (0, 1) ``[n, columns]`` (``columns`` even), a pair of each
    pair."""
    first, second = uniform[:, 0::2], uniform[:, 1::2]
    radius = torch.sqrt(-2.0 * torch.log(first))
    angle = 2.0 * math.pi * second
    return torch.stack((radius * torch.cos(angle), radius * torch.sin(angle)), dim=-1).reshape(uniform.shape)
