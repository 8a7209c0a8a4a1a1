"""A process of ours once its modules are imported: their objects kept out of Python's cyclic garbage collector.

Importing torch, tensordict (which imports torch's compiler) and the rest creates about 600,000 objects that
live as long as the process. Python's collector walks all of them in every full collection, several times
while they are imported and once more as the interpreter exits: 0.6 s of a refused ``train.py``'s 3.6 and
0.65 s of every process's exit (docs/benchmarks.md, "Tests"). The entry points turn the collector off
before their imports (``gc.disable()`` under ``if __name__ == "__main__"``) and call :func:`imports_done`
after them; a spawned worker calls it once it has imported what it runs. Objects made later are collected
as always. What the imports left as cyclic garbage (about 8 MB) stays until the process ends.
"""

from __future__ import annotations

import gc


def imports_done() -> None:
    """Move every object alive now to the collector's permanent generation (``gc.freeze``) and turn
    collection on. Call it once, in a process's own start-up, never from a library call."""
    gc.freeze()
    gc.enable()
