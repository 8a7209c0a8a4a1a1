"""A process of ours: its imported objects kept out of Python's cyclic garbage collector, the memory it frees
kept for its next allocations, torch's compiler set for our graphs (:func:`set_up_process`).

Importing torch, tensordict (which imports torch's compiler) and the rest creates about 600,000 objects that
live as long as the process. Python's collector walks all of them in every full collection, several times
while they are imported and once more as the interpreter exits: 0.6 s of a refused ``train.py``'s 3.6 and
0.65 s of every process's exit (docs/benchmarks.md, "Tests"). The entry points turn the collector off
before their imports (``gc.disable()`` under ``if __name__ == "__main__"``) and call :func:`set_up_process`
after them; a spawned worker calls it once it has imported what it runs. Objects made later are collected
as always. What the imports left as cyclic garbage (about 8 MB) stays until the process ends.

A compiled graph allocates its intermediate buffers anew at every call. glibc's malloc gives a large block
memory the kernel must map and zero page by page (``mmap``), and hands memory freed at the top of its heap
back to the kernel (``trim``), so a compiled step at B = 1024 faulted in about 230 MB of fresh pages each
step: a 112 MB buffer costs 52 ms to allocate, fill and free, 10 ms from memory kept (docs/benchmarks.md,
"Lattice sums"). :func:`keep_freed_memory` keeps it.

What changes the process for speed is switched on in one place, :func:`set_up_process`, by the entry points
(train.py, evaluate.py, an evaluation's worker processes, the benchmarks), never by the library: building,
stepping or compiling an environment in a notebook changes nothing outside it.
"""

from __future__ import annotations

import ctypes
import functools
import gc
import os
from collections.abc import Collection

M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
"""glibc's ``mallopt`` parameters (malloc.h)."""
KEPT_BYTES = 2**31
"""Blocks up to this size come from the heap, and up to this much freed memory stays at its top."""
MMAP_THRESHOLD_MAX = 2**25
"""The largest ``M_MMAP_THRESHOLD`` that every glibc accepts (``DEFAULT_MMAP_THRESHOLD_MAX`` on 64 bits)."""


SWITCHES = ("collector", "allocator", "recompile_limits", "inductor_fix")
"""What :func:`set_up_process` switches on, each named as it is turned off."""
OFF_VARIABLE = "WATERAIR_PROCESS_OFF"
"""The environment variable that turns switches off in every process of ours (comma-separated names of
:data:`SWITCHES`: ``WATERAIR_PROCESS_OFF=allocator,inductor_fix python train.py``)."""
RECOMPILE_LIMIT = 128
"""Graphs torch may compile per compiled function in one process. Every environment configuration is a graph of
its own (the guards are on it), and torch's default limit of 8 is reached by one evaluation (a group of
policies per step, each on more than one batch): past it torch runs the step eagerly, 15× slower on the full
channel, after a wall of warnings."""


def set_up_process(off: Collection[str] | None = None) -> dict[str, bool]:
    """Switch on, for the whole process, what our entry points run faster with; call it once their imports are
    done. Each switch, what it buys (docs/benchmarks.md) and its name in ``off``, which turns it off (by default
    the names in :data:`OFF_VARIABLE`):

    - ``collector``: the imports' 600,000 objects frozen out of the garbage collector's walks and the collector
      on again (:func:`imports_done`): a refused ``train.py`` 2.40 s, not 3.72; test collection 8.3 s, not 12.1.
    - ``allocator``: glibc's malloc keeps freed memory for the next allocations (:func:`keep_freed_memory`): a
      compiled step's 112 MB buffer 10 ms to allocate, fill and free, not 52; the process keeps its peak memory.
    - ``recompile_limits``: dynamo may compile :data:`RECOMPILE_LIMIT` graphs per function, not 8, so that an
      evaluation's groups each keep a compiled step instead of falling back to eager (15× slower) past the 8th.
    - ``inductor_fix``: inductor's rule for sharing a kernel's loops between threads fixed
      (:func:`waterair.core.inductor.fix_parallel_depth`): the defaults' compiled step on two threads 1.12-1.22×
      faster; graphs compiled without it are compiled again, not loaded from the cache.

    Returns which switches are on (``allocator`` False where the C library has no ``mallopt``, ``inductor_fix``
    False under a torch whose rule differs from the one fixed).
    """
    if off is None:
        off = [name.strip() for name in os.environ.get(OFF_VARIABLE, "").split(",") if name.strip()]
    unknown = sorted(set(off) - set(SWITCHES))
    if unknown:
        raise ValueError(f"{OFF_VARIABLE}: {', '.join(unknown)} is not a switch; the switches: {', '.join(SWITCHES)}")
    on = dict.fromkeys(SWITCHES, False)
    if "collector" not in off:
        imports_done()
        on["collector"] = True
    if "allocator" not in off:
        on["allocator"] = keep_freed_memory()
    if "recompile_limits" not in off:
        import torch._dynamo

        dynamo = torch._dynamo.config
        dynamo.recompile_limit = max(dynamo.recompile_limit, RECOMPILE_LIMIT)
        dynamo.accumulated_recompile_limit = max(dynamo.accumulated_recompile_limit, 4 * RECOMPILE_LIMIT)
        on["recompile_limits"] = True
    if "inductor_fix" not in off:
        from waterair.core.inductor import fix_parallel_depth

        on["inductor_fix"] = fix_parallel_depth()
    return on


def imports_done() -> None:
    """Move every object alive now to the collector's permanent generation (``gc.freeze``) and turn
    collection on. Call it once, in a process's own start-up, never from a library call."""
    gc.freeze()
    gc.enable()


@functools.cache
def keep_freed_memory() -> bool:
    """Ask the C library's malloc to serve large blocks from its heap and keep what is freed there (glibc's
    ``mallopt``: ``M_MMAP_THRESHOLD``, ``M_TRIM_THRESHOLD``), so that repeated allocations of the same sizes
    reuse pages instead of faulting in new ones. Once per process; whether it took effect (False where the C
    library has no ``mallopt``, as on macOS). The process keeps its peak memory until it ends."""
    libc = ctypes.CDLL(None)
    mallopt = getattr(libc, "mallopt", None)
    if mallopt is None:
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    heap = mallopt(M_MMAP_THRESHOLD, KEPT_BYTES - 1) or mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_MAX)
    return bool(heap and mallopt(M_TRIM_THRESHOLD, KEPT_BYTES - 1))
