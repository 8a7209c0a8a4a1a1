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
compiled graphs. An evaluation decides for each group of policies from the channel's ``evaluation_frames``,
warm only where that group's graphs are noted in the cache (:func:`graphs_kept`,
:mod:`waterair.evaluation.compiling`).
"""

from __future__ import annotations

import functools
import hashlib
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Protocol

CHOICES = ("auto", "true", "false")


class Compiles(Protocol):
    """What :func:`compiling_pays` reads of a channel: its name and the frames from which compiling pays, in a
    training run and in an evaluation's group."""

    name: str
    compile_frames: Mapping[str, int]
    evaluation_frames: Mapping[str, int]


def compiling_pays(frames: int, cache: str | None, channel: Compiles, use: str = "training") -> tuple[bool, str]:
    """Whether ``frames`` env-steps on ``channel`` repay a compile, and a clause saying why (``cache``: warm or
    cold; None: :func:`cache_state`; ``use``: ``training``, else an evaluation's group)."""
    cache = cache or cache_state()
    least = (channel.compile_frames if use == "training" else channel.evaluation_frames)[cache]
    pays = frames >= least
    sign = "≥" if pays else "<"
    where = f"on the {channel.name} channel with torch's compile cache {cache}"
    return pays, f"auto: {frames:,} frames to go {sign} {least:,} {where}"


def cache_state() -> str:
    """``warm`` if torch's compile cache holds compiled graphs (of any program), else ``cold``."""
    graphs = cache_folder() / "fxgraph"
    return "warm" if graphs.is_dir() and any(graphs.iterdir()) else "cold"


def cache_folder() -> Path:
    """The folder of torch's compile cache (``TORCHINDUCTOR_CACHE_DIR``, else torch's default)."""
    # The folder torch would use, found as torch finds it (its cache_dir() would also create it).
    from torch._inductor.runtime.cache_dir_utils import default_cache_dir

    return Path(os.environ.get("TORCHINDUCTOR_CACHE_DIR") or default_cache_dir())


# A ledger beside torch's cache of the graphs a program compiled, by a name of what they were compiled for: whether
# *these* graphs are cached, which cache_state (any graph at all) cannot say. After training, for one, the cache is
# warm, yet none of an evaluation's groups has its graphs there. A name that no longer matches its graphs (the
# cache cleared by hand) costs one compile; a name is never wrong about the code, which it includes.


def graphs_name(*structure: object) -> str:
    """A name for the graphs compiled for ``structure`` (reprs that fix the graphs) by this code and this torch."""
    import torch

    digest = hashlib.sha256(f"{torch.__version__}\n{_source_digest()}\n".encode())
    for part in structure:
        digest.update(repr(part).encode())
    return digest.hexdigest()[:32]


def graphs_kept(name: str) -> bool:
    """Whether graphs named ``name`` were compiled into torch's compile cache (:func:`keep_graphs`)."""
    return cache_state() == "warm" and (cache_folder() / "waterair" / name).is_file()


def keep_graphs(name: str) -> None:
    """Note that graphs named ``name`` are now in torch's compile cache (where the folder cannot be written, the
    next program compiles them again: the note only saves time)."""
    folder = cache_folder() / "waterair"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        (folder / name).touch()
    except OSError:
        pass


@functools.cache
def _source_digest() -> str:
    """The package's Python sources, hashed: a change to the code is a change to every graph's name."""
    root = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()
