"""When compiling pays: ``auto`` for ``env.compile_kernel`` (train.py, evaluate.py) and ``compile_update``.

Compiling pays only when the frames still to collect save more time than the compiles cost, and
what they cost depends on torch's compile cache (``TORCHINDUCTOR_CACHE_DIR``, per machine by
default, per sweep on Slurm): measured on the 2-core development machine (docs/benchmarks.md,
"Training"), the default configuration's step and update take about 100 s to compile into an empty
cache and 9–20 s out of a warm one, and then save 0.33 ms per frame (2,568 frames/s compiled, 1,380
eager) on the paper's one-path channel. The full channel (the default) costs 4.3 ms a frame eager and
0.6 ms compiled in the same loop (160,000 frames: 11 min 25 s eager, 3 min 14 s compiled), so compiling
pays from far fewer frames there. ``auto`` compiles from :data:`MIN_FRAMES` frames on, for the channel,
taking the cache as warm when it holds compiled graphs.
"""

from __future__ import annotations

import os
from pathlib import Path

CHOICES = ("auto", "true", "false")
MIN_FRAMES = {"warm": 50_000, "cold": 300_000}
"""Frames from which compiling saves time on the one-path channel: the compile time over the time it saves
per frame."""
MIN_FRAMES_FULL = {"warm": 30_000, "cold": 40_000}
"""The same for the full channel: about 100–130 s of compiling over 3.7 ms saved a frame."""


def compiling_pays(frames: int, cache: str | None = None, channel: str = "single_path") -> tuple[bool, str]:
    """Whether ``frames`` env-steps on ``channel`` repay a compile, and a clause saying why (``cache``: warm or
    cold, default :func:`cache_state`)."""
    cache = cache or cache_state()
    least = (MIN_FRAMES_FULL if channel == "full" else MIN_FRAMES)[cache]
    pays = frames >= least
    sign = "≥" if pays else "<"
    where = f"on the {channel} channel with torch's compile cache {cache}"
    return pays, f"auto: {frames:,} frames to go {sign} {least:,} {where}"


def cache_state() -> str:
    """``warm`` if torch's compile cache holds compiled graphs (of any program), else ``cold``."""
    # The folder torch would use, found as torch finds it (its cache_dir() would also create it).
    from torch._inductor.runtime.cache_dir_utils import default_cache_dir

    graphs = Path(os.environ.get("TORCHINDUCTOR_CACHE_DIR") or default_cache_dir()) / "fxgraph"
    return "warm" if graphs.is_dir() and any(graphs.iterdir()) else "cold"
