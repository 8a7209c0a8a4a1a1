"""A process's start-up (waterair/core/process.py): the imports' objects frozen, the collector on again; the memory
it frees kept for its next allocations; all of it the entry points', none of it the library's."""

import ctypes
import gc
import json
import resource
import runpy
import subprocess
import sys

import pytest
from conftest import ROOT

from waterair.core.process import (
    OFF_VARIABLE,
    RECOMPILE_LIMIT,
    SWITCHES,
    imports_done,
    keep_freed_memory,
    set_up_process,
)


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


PROCESS_STATE = """
import ctypes, gc, json, resource
import torch
from torch._inductor import config as inductor
from torch._inductor.codegen import cpp

libc = ctypes.CDLL(None)
libc.malloc.restype, libc.malloc.argtypes = ctypes.c_void_p, [ctypes.c_size_t]
libc.free.argtypes = [ctypes.c_void_p]


def state():
    size = 64 << 20
    start = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(2):  # glibc's defaults map a block this large anew each time (its pages fault twice); kept, once
        block = libc.malloc(size)
        ctypes.memset(block, 1, size)
        libc.free(block)
    dynamo = torch._dynamo.config
    return {
        "collector": [gc.isenabled(), gc.get_freeze_count()],
        "allocator maps each block anew": resource.getrusage(resource.RUSAGE_SELF).ru_minflt - start > 3 * size // 8192,
        "dynamo": [dynamo.recompile_limit, dynamo.accumulated_recompile_limit, dynamo.automatic_dynamic_shapes],
        "inductor": [repr(inductor.post_grad_custom_post_pass), cpp.LoopNest.max_parallel_depth.__module__],
    }
"""


@pytest.mark.slow
def test_building_and_stepping_an_env_changes_nothing_in_the_process():
    """A fresh interpreter, as a notebook: what our entry points switch on (waterair.core.process.set_up_process)
    is as it was after importing the package, building and stepping an environment and building its compiled
    step functions (their first call compiles); the same check sees each switch once set_up_process runs."""
    code = (
        PROCESS_STATE
        + """
before = state()
from waterair.envs.env import WaterAirEnv
env = WaterAirEnv(num_envs=4, seed=0, sea={"n_dir": 8})
td = env.reset()
for _ in range(3):
    td = env.step(td.set("action", torch.zeros(4, 4)))["next"]
from waterair.envs import stepper
[stepper.compiled(name) for name in ("step", "finish", "conclude")]  # what a compiled env builds (compiles later)
after = state()
from waterair.core.process import set_up_process
on = set_up_process()
print(json.dumps([before, after, state(), on]))
"""
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    before, after, set_up, on = json.loads(done.stdout.strip().splitlines()[-1])
    assert after == before
    assert on == dict.fromkeys(SWITCHES, True)
    assert set_up["collector"][0] and set_up["collector"][1] > 100_000  # the imports frozen
    assert before["allocator maps each block anew"] and not set_up["allocator maps each block anew"]
    assert set_up["dynamo"][:2] == [RECOMPILE_LIMIT, 4 * RECOMPILE_LIMIT] != before["dynamo"][:2]
    assert "waterair" in set_up["inductor"][0] and set_up["inductor"][1] == "waterair.core.inductor"
    assert "waterair" not in " ".join(before["inductor"])


def test_a_switch_is_turned_off_by_name_and_an_unknown_name_is_refused(monkeypatch):
    monkeypatch.setenv(OFF_VARIABLE, "collector, allocator,recompile_limits,inductor_fix")
    assert set_up_process() == dict.fromkeys(SWITCHES, False)
    monkeypatch.setenv(OFF_VARIABLE, "allocater")
    with pytest.raises(ValueError, match=r"^WATERAIR_PROCESS_OFF: allocater is not a switch; the switches: coll"):
        set_up_process()
