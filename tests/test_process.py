"""A process's start-up (waterair/core/process.py): the imports' objects frozen, the collector on again; the memory
it frees kept for its next allocations."""

import ctypes
import gc
import resource
import runpy
import sys

import pytest
from conftest import ROOT

from waterair.core.process import imports_done, keep_freed_memory


def test_imports_done_freezes_what_is_alive_and_turns_the_collector_on():
    gc.disable()
    try:
        alive = [[] for _ in range(1000)]  # containers the collector tracks
        before = gc.get_freeze_count()
        imports_done()
        assert gc.isenabled()
        assert gc.get_freeze_count() >= before + len(alive)
    finally:
        gc.enable()


@pytest.mark.parametrize("script", ["train.py", "evaluate.py"])
def test_an_entry_point_imported_as_a_module_leaves_the_collector_as_it_was(script):
    frozen = gc.get_freeze_count()
    runpy.run_path(str(ROOT / script), run_name="imported")
    assert gc.isenabled() and gc.get_freeze_count() <= frozen  # frozen objects may die; none is added


def test_the_tests_run_with_the_collector_on_and_the_collected_modules_frozen():
    assert gc.isenabled() and gc.get_freeze_count() > 100_000


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc, whose settings are tested")
def test_memory_freed_is_kept_so_that_allocating_the_same_size_again_maps_no_new_pages():
    """64 MB allocated, written and freed four times: with glibc's defaults each round maps it anew (16,384 page
    faults); kept, the rounds after the first reuse the same pages."""
    libc = ctypes.CDLL(None)
    libc.malloc.restype, libc.malloc.argtypes = ctypes.c_void_p, [ctypes.c_size_t]
    libc.free.argtypes = [ctypes.c_void_p]
    size = 64 << 20

    def page_faults(rounds: int) -> int:
        start = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
        for _ in range(rounds):
            block = libc.malloc(size)
            ctypes.memset(block, 1, size)
            libc.free(block)
        return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - start

    assert keep_freed_memory()
    page_faults(1)  # the heap grows to hold the block once
    assert page_faults(4) < size // 4096 // 16
