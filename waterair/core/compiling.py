"""When compiling pays: ``auto`` for ``env.compile_kernel`` (train.py, evaluate.py) and ``compile_update``.

Compiling pays only when the frames still to collect save more time than the compiles cost, and
what they cost depends on torch's compile cache (``TORCHINDUCTOR_CACHE_DIR``, per machine by
default, per sweep on Slurm): measured on the 2-core development machine (docs/benchmarks.md,
"Training"), the default configuration's step and update take about 100 s to compile into an empty
cache and 9–20 s out of a warm one, and then save 0.33 ms per frame (2,568 frames/s compiled, 1,380
eager) on the paper's one-path channel. The full channel (the default) costs 4.3 ms a frame eager and
0.6 ms compiled in the same loop (160,000 frames: 11 min 25 s eager, 3 min 14 s compiled), so compiling
pays from far fewer frames there. ``auto`` compiles from the channel's ``compile_frames`` on (a trait of each
option of ``env/channel``, :mod:`waterair.physics.channel.registry`), taking the cache as warm when it holds
compiled graphs.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Protocol

CHOICES = ("auto", "true", "false")


class Compiles(Protocol):
    """What :func:`compiling_pays` reads of a channel: its name and the frames from which compiling pays."""

    name: str
    compile_frames: Mapping[str, int]


def compiling_pays(frames: int, cache: str | None, channel: Compiles) -> tuple[bool, str]:
    """Whether ``frames`` env-steps on ``channel`` repay a compile, and a clause saying why (``cache``: warm or
    cold; None: :func:`cache_state`)."""
    cache = cache or cache_state()
    least = channel.compile_frames[cache]
    pays = frames >= least
    sign = "≥" if pays else "<"
    where = f"on the {channel.name} channel with torch's compile cache {cache}"
    return pays, f"auto: {frames:,} frames to go {sign} {least:,} {where}"


def cache_state() -> str:
    """``warm`` if torch's compile cache holds compiled graphs (of any program), else ``cold``."""
    # The folder torch would use, found as torch finds it (its cache_dir() would also create it).
    from torch._inductor.runtime.cache_dir_utils import default_cache_dir

    graphs = Path(os.environ.get("TORCHINDUCTOR_CACHE_DIR") or default_cache_dir()) / "fxgraph"
    return "warm" if graphs.is_dir() and any(graphs.iterdir()) else "cold"
