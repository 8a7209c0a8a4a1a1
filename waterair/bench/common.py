"""What every benchmark shares: a median timer, the sin+cos floors and where the numbers were measured."""

from __future__ import annotations

import os
import platform
import statistics
import subprocess
import sys
import time
from collections.abc import Callable

import torch


def timed(fn: Callable[[], object], repeats: int, device: torch.device) -> float:
    """Median wall-clock seconds of ``fn()`` over ``repeats`` runs, after one warm-up run."""
    fn()
    samples = []
    for _ in range(repeats):
        _sync(device)
        start = time.perf_counter()
        fn()
        _sync(device)
        samples.append(time.perf_counter() - start)
    return statistics.median(samples)


def sincos_floor(batch: int, harmonics: int, repeats: int, device: torch.device, dtype: torch.dtype) -> float:
    """Seconds for one ``sin`` and one ``cos`` over a ``[batch, harmonics]`` tensor."""
    x = torch.rand(batch, harmonics, device=device, dtype=dtype) * 100.0
    return timed(lambda: (torch.sin(x), torch.cos(x)), repeats, device)


LATTICE_FLOOR_SHAPE = (1024, 2048)
"""The tensor the lattice floor's sin+cos is timed on (:func:`sincos_per_element`)."""


def sincos_per_element(repeats: int, device: torch.device, dtype: torch.dtype) -> float:
    """Seconds per element of one ``sin`` and one ``cos``, timed over a :data:`LATTICE_FLOOR_SHAPE` tensor: the
    unit of the full channel's lattice floor (``waterair.bench.env.lattice_floor``)."""
    rows, columns = LATTICE_FLOOR_SHAPE
    return sincos_floor(rows, columns, repeats, device, dtype) / (rows * columns)


def seconds_in_fresh_python(code: str, args: list[str], cache: str, what: str) -> float:
    """Run ``code`` (which prints seconds last) in a fresh Python with ``args`` as ``sys.argv[1:]`` and torch's
    compile cache in ``cache`` (``TORCHINDUCTOR_CACHE_DIR``); returns the seconds, or raises naming ``what``."""
    return float(last_line_of_fresh_python(code, args, what, {"TORCHINDUCTOR_CACHE_DIR": cache}))


COLLECTOR_OFF = "import gc; gc.disable(); "
"""How the program of a child that runs as an entry point starts: Python's garbage collector off until it has imported
what it runs and calls :func:`~waterair.core.process.set_up_process`, as train.py does."""


def last_line_of_fresh_python(code: str, args: list[str], what: str, environ: dict[str, str] | None = None) -> str:
    """Run ``code`` in a fresh Python with ``args`` as ``sys.argv[1:]`` (and ``environ`` over this process's
    environment); the last line it printed, or an error naming ``what`` with the end of its stderr."""
    done = subprocess.run(
        [sys.executable, "-c", code, *args],
        capture_output=True,
        text=True,
        env={**os.environ, **(environ or {})},
        check=False,
    )
    if done.returncode != 0:
        raise RuntimeError(f"{what} failed:\n{done.stderr[-3000:]}")
    return done.stdout.strip().splitlines()[-1]


def machine(device: torch.device, dtype: torch.dtype) -> dict:
    """Where the numbers were measured."""
    name = torch.cuda.get_device_name(device) if device.type == "cuda" else (platform.processor() or platform.machine())
    return {
        "device": str(device),
        "device_name": name,
        "dtype": str(dtype).removeprefix("torch."),
        "threads": torch.get_num_threads(),
        "cpu_count": os.cpu_count(),
        "torch": torch.__version__,
        "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }


def _sync(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)
