"""A process of ours: its imported objects kept out of Python's cyclic garbage collector, and the memory it frees
kept for its next allocations.

Importing torch, tensordict (which imports torch's compiler) and the rest creates about 600,000 objects that
live as long as the process. Python's collector walks all of them in every full collection, several times
while they are imported and once more as the interpreter exits: 0.6 s of a refused ``train.py``'s 3.6 and
0.65 s of every process's exit (docs/benchmarks.md, "Tests"). The entry points turn the collector off
before their imports (``gc.disable()`` under ``if __name__ == "__main__"``) and call :func:`imports_done`
after them; a spawned worker calls it once it has imported what it runs. Objects made later are collected
as always. What the imports left as cyclic garbage (about 8 MB) stays until the process ends.

A compiled graph allocates its intermediate buffers anew at every call. glibc's malloc gives a large block
memory the kernel must map and zero page by page (``mmap``), and hands memory freed at the top of its heap
back to the kernel (``trim``), so a compiled step at B = 1024 faulted in about 230 MB of fresh pages each
step: a 112 MB buffer costs 52 ms to allocate, fill and free, 10 ms from memory kept (docs/benchmarks.md,
"Lattice sums"). :func:`keep_freed_memory` keeps it; ``torch_compile`` (waterair.core.inductor) calls it.
"""

from __future__ import annotations

import ctypes
import functools
import gc

M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
"""glibc's ``mallopt`` parameters (malloc.h)."""
KEPT_BYTES = 2**31
"""Blocks up to this size come from the heap, and up to this much freed memory stays at its top."""
MMAP_THRESHOLD_MAX = 2**25
"""The largest ``M_MMAP_THRESHOLD`` that every glibc accepts (``DEFAULT_MMAP_THRESHOLD_MAX`` on 64 bits)."""


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
