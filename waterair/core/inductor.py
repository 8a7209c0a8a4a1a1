"""One fix to torch's C++ code generator (inductor on the CPU), applied before anything is compiled.

Inductor shares a kernel's outer loops between threads unless they hold too few steps, in which case it
shares the inner reduction instead. It counts a loop's steps by floor division of its size by its step,
so a vectorised loop shorter than one vector (the three components of a ``[B, N, 3]`` sum over N: 3
elements, a step of 16) counts zero, the outer loops count zero steps whatever B is, and the kernel
becomes a serial loop over the B rows that opens an OpenMP thread team for each row's sum over N.
The full channel's step had 18 such sums (of 3-vectors over a lattice's nodes): 18 × B thread teams a
step. :func:`fix_parallel_depth` counts the steps by ceiling division, as
torch's own later fix does (pytorch/pytorch#190928); a kernel whose outer loops really are short still
shares its reduction. The entry points apply it (:func:`waterair.core.process.set_up_process`); the library's
compiles do not. Measured in docs/benchmarks.md ("Channels", "A thread team per row"). The fix is part of
the key of torch's compile cache (:func:`cache_key_pass`): graphs a machine compiled before it are compiled
again, not loaded with their old loops.

The replaced function is checked against the source it replaces (:data:`REPLACED_SOURCE`): under another
torch the fix is not applied, and ``tests/test_torch_internals.py`` fails, naming the function.
"""

from __future__ import annotations

import functools
import hashlib
import inspect

REPLACED = "torch._inductor.codegen.cpp.LoopNest.max_parallel_depth"
REPLACED_SOURCE = "f47e8be9b69df936"
"""The first 16 hex digits of the SHA-256 of torch 2.13.0's source of :data:`REPLACED`."""


def replaced_source_digest() -> str:
    """The digest (as :data:`REPLACED_SOURCE`) of the installed torch's :data:`REPLACED`."""
    from torch._inductor.codegen import cpp

    current = cpp.LoopNest.max_parallel_depth
    source = inspect.getsource(inspect.unwrap(getattr(current, "replaced", current)))  # torch's, fixed or not
    return hashlib.sha256(source.encode()).hexdigest()[:16]


@functools.cache
def fix_parallel_depth() -> bool:
    """Replace :data:`REPLACED` by :func:`_max_parallel_depth` (once per process); whether it was replaced (not
    under a torch whose function differs from the one this fixes)."""
    from torch._inductor import config
    from torch._inductor.codegen import cpp
    from torch._inductor.utils import cache_on_self

    if replaced_source_digest() != REPLACED_SOURCE:
        return False
    fixed = cache_on_self(_max_parallel_depth)
    fixed.replaced = cpp.LoopNest.max_parallel_depth  # type: ignore[attr-defined]  # what the tests compare with
    cpp.LoopNest.max_parallel_depth = fixed
    if config.post_grad_custom_post_pass is None:  # a pass of the user's own is left alone
        config.post_grad_custom_post_pass = cache_key_pass()
    return True


@functools.cache
def cache_key_pass():
    """A post-grad pass of inductor's that changes nothing and whose ``uuid`` names the fix: torch's compile
    cache keys its graphs on it."""
    from torch._inductor.custom_graph_pass import CustomGraphPass

    class FixedParallelDepth(CustomGraphPass):
        def __call__(self, graph) -> None:
            return None

        def uuid(self) -> str:
            return f"waterair.core.inductor: {REPLACED} by ceiling division ({REPLACED_SOURCE})"

    return FixedParallelDepth()


def _max_parallel_depth(self):
    """torch 2.13.0's ``LoopNest.max_parallel_depth`` with the outer loops' steps counted by ceiling division."""
    import sympy
    from torch._inductor.codegen import cpp
    from torch.utils._sympy.functions import CeilDiv, FloorDiv

    if self.loops is None:
        return cpp.ParallelDepth(parallel_depth=0, start_depth=0)
    start_depth, max_depth = 0, 0
    is_reduction = self.loops[0].is_reduction
    num_steps = sympy.Integer(1)
    for loop in self.loops:
        if loop.is_reduction != is_reduction:
            break
        num_steps = num_steps * CeilDiv(loop.size, loop.steps)  # torch: FloorDiv, zero for a loop under a vector
        max_depth += 1
    simd_vec_depth = next((i for i, loop in enumerate(self.loops) if loop.simd_vec), None)

    def has_scalar_kernel() -> bool:
        return any(not isinstance(kernel, cpp.CppVecKernel) for kernel in self.kernel.kernels)

    # When the first inner loop has far more steps than all outer loops, parallelise it instead (torch's rule).
    if (
        max_depth < len(self.loops)
        and isinstance(num_steps, sympy.Integer)
        and isinstance(self.loops[max_depth].size, sympy.Integer)
        and num_steps * 300 < FloorDiv(self.loops[max_depth].size, self.loops[max_depth].steps)
        and not (
            simd_vec_depth is not None
            and max_depth > simd_vec_depth
            and self.loops[max_depth].is_reduction
            and has_scalar_kernel()
        )
    ):
        start_depth, max_depth = max_depth, 0
        is_reduction = self.loops[start_depth].is_reduction
        for loop in self.loops[start_depth:]:
            if loop.is_reduction != is_reduction:
                break
            max_depth += 1
    return cpp.ParallelDepth(parallel_depth=max_depth, start_depth=start_depth)
