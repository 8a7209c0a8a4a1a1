"""When compiling pays: ``auto`` for ``env.compile_kernel`` (train.py, evaluate.py) and ``compile_update``.

Compiling pays only when the frames still to collect save more time than the compiles cost, and
what they cost depends on torch's compile cache (``TORCHINDUCTOR_CACHE_DIR``, per machine by
default, per sweep on Slurm): measured on the 2-core development machine (docs/benchmarks.md,
"Training"), the default configuration's step and update take about 100 s to compile into an empty
cache and 9–20 s out of a warm one, and then save 0.33 ms per frame (2,568 frames/s compiled, 1,380
eager). ``auto`` compiles from :data:`MIN_FRAMES` frames on, taking the cache as warm when it holds
compiled graphs.
"""

from __future__ import annotations

import os
from pathlib import Path

CHOICES = ("auto", "true", "false")
MIN_FRAMES = {"warm": 50_000, "cold": 300_000}
"""Frames from which compiling saves time: the compile time over the time it saves per frame."""


def compiling_pays(frames: int, cache: str | None = None) -> tuple[bool, str]:
    """Whether ``frames`` env-steps repay a compile, and a clause saying why (``cache``: warm or cold,
    default :func:`cache_state`)."""
    cache = cache or cache_state()
    pays = frames >= MIN_FRAMES[cache]
    sign = "≥" if pays else "<"
    return pays, f"auto: {frames:,} frames to go {sign} {MIN_FRAMES[cache]:,} with torch's compile cache {cache}"


def cache_state() -> str:
    """``warm`` if torch's compile cache holds compiled graphs (of any program), else ``cold``."""
    # The folder torch would use, found as torch finds it (its cache_dir() would also create it).
    from torch._inductor.runtime.cache_dir_utils import default_cache_dir

    graphs = Path(os.environ.get("TORCHINDUCTOR_CACHE_DIR") or default_cache_dir()) / "fxgraph"
    return "warm" if graphs.is_dir() and any(graphs.iterdir()) else "cold"
