"""A process's start-up (waterair/core/process.py): the imports' objects frozen, the collector on again."""

import gc
import runpy

import pytest
from conftest import ROOT

from waterair.core.process import imports_done


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
