"""An extern kernel that reads a tensor, for code compiled by ``torch.compile`` on a CPU.

Inductor fuses the operations between two extern kernels (calls it does not generate code for) into C++
functions, recomputing a cheap value in every loop that reads it. ``v + written(v)`` keeps ``v``'s value and
changes two things: ``v`` is written to memory once, as the extern kernel's input, so that its other readers
load it instead of recomputing it (the lattice's factors, docs/model.md §4.3), and what is computed from the
sum runs after the extern kernel, in C++ functions of its own (the full channel's reception: as one function
its graph with a symbolic batch compiled 3× slower, docs/benchmarks.md "Evaluation").

The op ``waterair::written`` is defined with ``torch.library.Library`` rather than ``torch.library.custom_op``:
a compiled step of the full channel calls it 22 times, at 2.8 µs a call against a ``custom_op``'s 7.
``tests/test_torch_internals.py`` checks both effects on inductor's code.
"""

from __future__ import annotations

import torch

_LIBRARY = torch.library.Library("waterair", "DEF")
_LIBRARY.define("written(Tensor values) -> Tensor")


def written(values: torch.Tensor) -> torch.Tensor:
    """A zero (0-dim, ``values``' dtype) computed by an extern kernel that reads ``values``."""
    return torch.ops.waterair.written(values)


def _zero(values: torch.Tensor) -> torch.Tensor:
    return values.new_zeros(())


_LIBRARY.impl("written", _zero, "CompositeExplicitAutograd")
torch.library.register_fake("waterair::written", lambda values: values.new_empty(()), lib=_LIBRARY)
