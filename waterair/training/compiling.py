"""Whether a run compiles its environment step and its update: ``env.compile_kernel`` and ``compile_update``.

Each is true, false or ``auto``. Compiling pays only when the frames still to collect save more
time than the compiles cost, and what they cost depends on torch's compile cache
(``TORCHINDUCTOR_CACHE_DIR``, per machine by default, per sweep on Slurm): measured on the 2-core
development machine (docs/benchmarks.md, "Training"), the default configuration's step and update
take about 100 s to compile into an empty cache and 9–20 s out of a warm one, and then save
0.33 ms per frame (2,568 frames/s compiled, 1,380 eager). ``auto`` compiles from
:data:`MIN_FRAMES` frames on, taking the cache as warm when it holds compiled graphs.
"""

from __future__ import annotations

import os
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from waterair.core.validation import check_choice

CHOICES = ("auto", "true", "false")
MIN_FRAMES = {"warm": 50_000, "cold": 300_000}
"""Frames from which compiling saves time: the compile time over the time it saves per frame."""


def compile_plan(cfg: DictConfig, frames_to_go: int, cache: str | None = None) -> tuple[DictConfig, str]:
    """``cfg`` with ``env.compile_kernel`` and ``compile_update`` decided (true or false), and a line saying why.

    ``cache`` is ``warm`` or ``cold`` (default: :func:`cache_state`); it is read only if a key is ``auto``.
    """
    settings = {"env.compile_kernel": cfg.env.compile_kernel, "compile_update": cfg.compile_update}
    for key, value in settings.items():
        check_choice(key, str(value).lower(), CHOICES)
    automatic = [key for key, value in settings.items() if str(value).lower() == "auto"]
    decided = {key: str(value).lower() == "true" for key, value in settings.items()}
    reason = "as configured"
    if automatic:
        cache = cache or cache_state()
        pays = frames_to_go >= MIN_FRAMES[cache]
        decided.update({key: pays for key in automatic})
        sign = "≥" if pays else "<"
        reason = f"auto: {frames_to_go:,} frames to go {sign} {MIN_FRAMES[cache]:,} with torch's compile cache {cache}"
    plan = OmegaConf.merge(
        cfg, {"env": {"compile_kernel": decided["env.compile_kernel"]}, "compile_update": decided["compile_update"]}
    )
    parts = [f"{'compiled' if decided[key] else 'eager'} {name}" for key, name in
             (("env.compile_kernel", "environment step"), ("compile_update", "update"))]  # fmt: skip
    return plan, f"{', '.join(parts)} ({reason})"


def cache_state() -> str:
    """``warm`` if torch's compile cache holds compiled graphs (of any program), else ``cold``."""
    # The folder torch would use, found as torch finds it (its cache_dir() would also create it).
    from torch._inductor.runtime.cache_dir_utils import default_cache_dir

    graphs = Path(os.environ.get("TORCHINDUCTOR_CACHE_DIR") or default_cache_dir()) / "fxgraph"
    return "warm" if graphs.is_dir() and any(graphs.iterdir()) else "cold"
