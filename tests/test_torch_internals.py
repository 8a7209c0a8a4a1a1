"""The torch and tensordict internals the compiled step relies on, each guarded by a test whose failure names it,
so that a release which changes one is found by ``make test`` and not by a slow run (an evaluation that compiles
a graph per batch, a step that runs eagerly after a wall of warnings). Traced with dynamo's counting backend
or AOT autograd's eager one; one test compiles two small kernels to C++ (inductor's loops,
:mod:`waterair.core.inductor`).

The tests that depend on the CPU's instruction set are marked ``capability`` and ``make test-portable`` runs them
under each one the CPU has (``ATEN_CPU_CAPABILITY``; inductor's vector width follows it): the inductor fix's
below (the fault appears in 512-bit loops alone, :data:`FAULT_WIDTH`), the channel recordings of
tests/test_channel_reference.py and the short training runs' of tests/test_training.py (each exact on the recording
machine's identity, which names the capability; within its tolerance elsewhere, the training runs' not under scalar
kernels: ``SCALAR_KERNELS``)."""

import re
from collections.abc import Callable

import pytest
import torch
from tensordict import TensorDict
from torch._dynamo.testing import CompileCounter
from torchrl.modules import MLP, MultiAgentMLP

from tests.conftest import paper_physics
from waterair.core import inductor
from waterair.core.process import RECOMPILE_LIMIT, set_up_process
from waterair.envs import stepper
from waterair.envs.env import WaterAirEnv
from waterair.envs.sensors import TRACED_SETTINGS
from waterair.envs.stepper import BATCH_SOURCES, MEMO_TYPES, varying_environments
from waterair.physics.optics import traced
from waterair.physics.surface import lattice_harmonic_sums


def frames(function, calls) -> int:
    """How many graphs dynamo traces for ``function`` over ``calls`` (each a tuple of arguments)."""
    counter = CompileCounter()
    compiled = torch.compile(function, backend=counter)
    torch._dynamo.reset()
    for arguments in calls:
        compiled(*arguments)
    return counter.frame_count


def aot_eager_counted(counter: CompileCounter):
    """AOT autograd with eager kernels (its passes run, nothing is compiled to code), counting graphs in
    ``counter``."""
    from torch._dynamo.backends.debugging import aot_eager

    def backend(graph, example_inputs):
        counter(graph, example_inputs)
        return aot_eager(graph, example_inputs)

    return backend


def step(state):  # named as the kernel's input, so that BATCH_SOURCES names it
    return state["x"] * 2.0


def other(values):  # an input BATCH_SOURCES does not name
    return values * 2.0


def test_dynamic_sources_make_the_step_inputs_batch_symbolic_and_nothing_else():
    name = "torch.compiler.config.dynamic_sources"
    assert hasattr(torch.compiler.config, "dynamic_sources"), f"{name} is gone (waterair.envs.stepper.BATCH_SOURCES)"
    batches = [({"x": torch.ones(n)},) for n in (3, 5, 7)]
    with varying_environments():
        assert frames(step, batches) == 1, (
            f"{name} = {BATCH_SOURCES!r} no longer makes L['state']'s first dimension symbolic: an evaluation "
            "would compile a graph for every batch size"
        )
        sizes = [(torch.ones(n),) for n in (3, 5, 7)]
        assert frames(other, sizes) == 3, (
            "torch._dynamo.config.automatic_dynamic_shapes = False no longer keeps other inputs static inside "
            "waterair.envs.stepper.varying_environments: graphs would depend on what ran before them"
        )
    assert frames(other, [(torch.ones(n),) for n in (3, 5, 7)]) == 2  # outside: torch's automatic dynamic shapes


def test_the_recompile_limits_are_raised_by_the_process_set_up_not_by_compiling_a_step():
    dynamo = torch._dynamo.config
    for key in ("recompile_limit", "accumulated_recompile_limit"):
        assert isinstance(getattr(dynamo, key, None), int), f"torch._dynamo.config.{key} is gone (set_up_process)"
    with dynamo.patch(recompile_limit=8, accumulated_recompile_limit=256):
        stepper.compiled.cache_clear()
        stepper.compiled("conclude")
        assert (dynamo.recompile_limit, dynamo.accumulated_recompile_limit) == (8, 256)
        assert set_up_process(off=("collector", "allocator", "inductor_fix"))["recompile_limits"]
        assert dynamo.recompile_limit == RECOMPILE_LIMIT and dynamo.accumulated_recompile_limit == 4 * RECOMPILE_LIMIT
    stepper.compiled.cache_clear()


def test_the_tensorclass_memo_is_filled_before_the_first_compile():
    from tensordict import utils

    name = "tensordict.utils._TENSORCLASS_MEMO"
    memo = getattr(utils, "_TENSORCLASS_MEMO", None)
    assert isinstance(memo, dict), f"{name} is gone: see waterair.envs.stepper.MEMO_TYPES"
    for kind in MEMO_TYPES:
        memo.pop(kind, None)
    stepper.compiled.cache_clear()
    stepper.compiled("conclude")
    stepper.compiled.cache_clear()
    missing = [kind.__name__ for kind in MEMO_TYPES if kind not in memo]
    assert not missing, f"{name} no longer remembers {missing} when asked (waterair.envs.stepper.MEMO_TYPES)"


def test_is_compiling_tells_the_surface_sums_that_they_run_in_a_graph():
    def where(x):
        return x + (1.0 if torch.compiler.is_compiling() else 0.0)

    counter = CompileCounter()
    assert torch.compile(where, backend=counter, fullgraph=True)(torch.zeros(1)).item() == 1.0, (
        "torch.compiler.is_compiling() is False while tracing: a compiled step would take the factorised "
        "lattice sums, 3.7x slower under inductor (waterair.physics.surface)"
    )


def test_the_inductor_cache_folder_is_where_the_compile_thresholds_look(monkeypatch, tmp_path):
    name = "torch._inductor.runtime.cache_dir_utils"
    try:
        from torch._inductor.runtime.cache_dir_utils import cache_dir, default_cache_dir
    except ImportError as error:  # pragma: no cover - what the test is for
        pytest.fail(f"{name}.default_cache_dir is gone (waterair.core.compiling.cache_state): {error}")
    monkeypatch.delenv("TORCHINDUCTOR_CACHE_DIR", raising=False)
    assert cache_dir() == default_cache_dir(), f"{name}: torch's cache is no longer its default_cache_dir()"
    monkeypatch.setenv("TORCHINDUCTOR_CACHE_DIR", str(tmp_path))
    assert cache_dir() == str(tmp_path), f"{name}: TORCHINDUCTOR_CACHE_DIR no longer sets torch's cache"


def test_a_setting_the_step_reads_as_a_tensor_compiles_once_without_restarting(monkeypatch):
    """A number the compiled step takes as an input (:func:`waterair.physics.optics.traced`: one element, in the
    step's dtype) is a tensor to torch.compile: one graph serves every value, traced once. A 0-dim float64 CPU
    tensor, read as a number too, made AOT's scalar pass restart the compile (the whole step traced twice);
    seen here by the pass's record of the numbers it gave up on."""
    from torch._dynamo.symbolic_convert import TensorifyState

    name = "torch._dynamo.symbolic_convert.TensorifyState.specialize"
    given_up, specialize = [], TensorifyState.specialize.__func__
    monkeypatch.setattr(
        TensorifyState, "specialize", classmethod(lambda cls, key: given_up.append(key) or specialize(cls, key))
    )

    def restarts(setting: Callable[[float], torch.Tensor]) -> tuple[int, int]:
        TensorifyState.clear()
        given_up.clear()
        counter = CompileCounter()
        compiled = torch.compile(lambda x, s: torch.where(x >= s, x * s, x), backend=aot_eager_counted(counter))
        torch._dynamo.reset()
        for value in (0.05, 0.2):
            expected = torch.where(torch.ones(4) >= value, torch.ones(4) * value, torch.ones(4))
            torch.testing.assert_close(compiled(torch.ones(4), setting(value)), expected)
        return len(given_up), counter.frame_count

    assert restarts(lambda v: traced(v, dtype=torch.float32)) == (0, 1), f"a one-element setting restarts ({name})"
    assert restarts(lambda v: traced(v, dims=0))[0] > 0, (
        f"{name} is no longer called for a 0-dim float64 input: this test no longer sees a restart (or 0-dim "
        "settings no longer restart the compile, and traced() could make them so again)"
    )


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_every_setting_the_compiled_step_reads_is_a_one_element_tensor_in_its_dtype(dtype):
    """What the test above requires, for each number the compiled step's constants carry as a tensor."""
    env = WaterAirEnv(num_envs=2, seed=0, dtype=dtype, intensity_noise=0.1, **paper_physics(n_freq=8, n_dir=4))
    constants = env.constants.traced(torch.device("cpu"), env.float_dtype)
    settings = {name: getattr(constants.sensor, name) for name in TRACED_SETTINGS}
    settings["residual"] = constants.actions.residual
    assert {name: (value.shape, value.dtype) for name, value in settings.items()} == {
        name: ((1,), env.float_dtype) for name in settings
    }
    assert settings["intensity_noise"].item() == pytest.approx(0.1)


FAULT_WIDTH = 512
"""The vector width (bits) at which torch 2.13.0's rule opens a thread team per row of a sum over nodes of 3-vectors
(AVX-512: a 3-element loop under a 16-float step counts zero steps). With 256-bit loops (AVX2: 8 floats) and
scalar ones it opens one, fixed or not (seen on AVX-512 and AVX2 machines alike)."""


def vector_width() -> int:
    """The vector width (bits) inductor emits here: that of the instruction set it picks itself (``cpp.simdlen``
    unset; under ``ATEN_CPU_CAPABILITY``, that capability's); 1, scalar loops, where it picks none. The narrower
    widths an older machine has are checked where ``make test-portable`` sets its capability."""
    from torch._inductor import config
    from torch._inductor.cpu_vec_isa import pick_vec_isa

    with config.patch({"cpp.simdlen": None}):  # the tests' own scalar loops set aside
        return pick_vec_isa().bit_width() if pick_vec_isa() else 1


@pytest.mark.capability
def test_a_sum_over_nodes_of_vectors_shares_its_rows_between_threads_not_each_rows_sum(monkeypatch):
    """The fix is applied; at the width where the fault appears (:data:`FAULT_WIDTH`) torch's own rule opens a team
    per row and the fixed one does not; at another width (this machine's own: AVX2's 256 bits, or scalar loops) the
    fixed rule answers every loop nest as torch's. ``make test-portable`` runs it at each width the CPU has."""
    from torch._inductor import config
    from torch._inductor.codegen import cpp
    from torch._inductor.utils import fresh_cache, run_and_get_cpp_code

    assert inductor.replaced_source_digest() == inductor.REPLACED_SOURCE, (
        f"{inductor.REPLACED} is no longer torch 2.13.0's: waterair.core.inductor does not fix it; see whether this "
        "torch still opens a thread team per row (this test, with the fix left out) and drop or update the fix"
    )
    assert inductor.fix_parallel_depth()
    fixed = cpp.LoopNest.max_parallel_depth
    # graphs compiled before the fix are not loaded from torch's compile cache: the fix is in its key
    assert config.post_grad_custom_post_pass is inductor.cache_key_pass()
    assert inductor.REPLACED_SOURCE in inductor.cache_key_pass().uuid()
    weight, vectors = torch.rand(64, 81), torch.rand(64, 81, 3)

    def sums(weight, vectors):  # as the light's mean direction over a lattice's nodes
        directions = vectors / torch.linalg.vector_norm(vectors, dim=-1, keepdim=True)
        return (weight.unsqueeze(-1) * directions).sum(1) / weight.sum(1, keepdim=True)

    def compiled(depth, width) -> str:
        monkeypatch.setattr(cpp.LoopNest, "max_parallel_depth", depth)
        # loops of this width (the tests' are scalar), two threads, compiled afresh; without a precompiled header,
        # which other vector flags would make another one to build (4 s)
        patch = {"cpp.simdlen": width, "cpp.threads": 2, "fx_graph_cache": False, "cpp_cache_precompile_headers": False}
        with config.patch(patch), fresh_cache():
            torch._dynamo.reset()
            values, code = run_and_get_cpp_code(torch.compile(sums), weight, vectors)
        torch.testing.assert_close(values, sums(weight, vectors))
        return code

    width = vector_width()
    if width == FAULT_WIDTH:
        assert compiled(fixed.replaced, width).count("#pragma omp parallel") > 1, (
            f"torch's own {inductor.REPLACED} no longer opens a thread team per row of a sum over nodes of "
            f"3-vectors in {width}-bit loops: waterair.core.inductor's fix is not needed any more"
        )
        ours = compiled(fixed, width)
    else:  # one compile: each loop nest asks both rules, and takes the fixed one's answer
        asked: list = []

        def both(nest):
            asked.append((fixed(nest), fixed.replaced(nest)))
            return asked[-1][0]

        ours = compiled(both, width)
        assert asked and all(mine == theirs for mine, theirs in asked), f"the fix changes {width}-bit loops"
    assert ours.count("#pragma omp parallel") == 1, f"the fixed {inductor.REPLACED} opens a team per row ({width})"


def test_the_fix_is_judged_at_the_width_where_the_fault_appears(monkeypatch):
    """A machine without 512-bit loops (AVX2, or ATEN_CPU_CAPABILITY=avx2) checks that the fix changes nothing; one
    with them checks that the fix is needed too."""
    from torch._inductor import cpu_vec_isa

    widths = {isa.bit_width() for isa in cpu_vec_isa.valid_vec_isa_list()}
    if 256 in widths:
        monkeypatch.setenv("ATEN_CPU_CAPABILITY", "avx2")
        assert vector_width() == 256
    monkeypatch.setenv("ATEN_CPU_CAPABILITY", "default")
    assert vector_width() == 1
    if FAULT_WIDTH in widths:
        monkeypatch.setenv("ATEN_CPU_CAPABILITY", "avx512")
        assert vector_width() == FAULT_WIDTH


@pytest.mark.usefixtures("inductor")
def test_the_lattices_factors_are_written_once_and_their_products_summed_without_a_sine():
    """Compiled on a CPU, the lattice's sums read their per-axis factors from memory: inductor writes an extern
    kernel's input (``torch.ops.waterair.written``) before any other consumer reads it. Left inlined, the factors'
    sines and cosines are recomputed for every node and harmonic, slower than the direct sums. Values against the
    float64 sums written in tests/test_surface.py, every order-2 term, to 1e-10 of their scales."""
    from torch._inductor.utils import run_and_get_code

    from tests.test_surface import direct_sums, random_lattices, surface64

    surface = surface64(batch=3, seed=4, spectrum="elfouhaily", n_dir=8)
    centre, basis, grid, time, xy = random_lattices(3, 5, seed=4)
    torch._dynamo.reset()
    compiled = torch.compile(lattice_harmonic_sums, dynamic=True)
    got, codes = run_and_get_code(compiled, surface.harmonics, centre, basis, grid, time, 2)
    expected = direct_sums(surface.harmonics, xy[..., 0], xy[..., 1], time)
    k = torch.sqrt(surface.kx**2 + surface.ky**2)
    for value, want, power in zip(got, expected, (0, 1, 1, 2, 2, 2), strict=True):
        scale = (surface.amplitude * k**power).sum(-1, keepdim=True)
        assert ((value - want).abs() / scale).max().item() < 1e-10
    code = "\n".join(codes)
    assert "torch.ops.waterair.written" in code, "the compiled lattice sums no longer write their factors first"
    nests = re.split(r"for\(int64_t x0=", code)  # each loop nest of inductor's C++ kernels opens with its x0 loop
    summing = [nest for nest in nests if "tmp_acc" in nest]
    trigonometry = re.compile(r"\b(sin|cos)\(|\.(sin|cos)\(\)")  # scalar or vectorised
    assert summing and any(trigonometry.search(nest) for nest in nests)
    assert not any(trigonometry.search(nest) for nest in summing), (
        "inductor recomputes the lattice's factors (sines, cosines) in the loop that sums their products: an "
        "extern kernel's input (torch.ops.waterair.written) is no longer written to memory before its other reads"
    )


@pytest.mark.usefixtures("inductor")
def test_an_extern_kernel_between_two_computations_compiles_them_as_c_functions_of_their_own():
    """The full channel's compiled reception is cut into C++ functions of their own at extern kernels (the light's
    planes, each half-step of the bound's ascent, the bound, the pointing's shares: ``values + written(values)``
    in waterair.physics.channel.light): inductor writes every loop between two extern calls into one function,
    and the evaluation's graph (a symbolic batch) wrote one of 18,000 lines, which compiled 3× slower. Guarded:
    a computation before and after such a read is two kernel functions, one without it."""
    from torch._inductor.utils import run_and_get_code

    from waterair.core.extern import written

    def computation(values: torch.Tensor, cut: bool) -> torch.Tensor:
        middle = torch.sin(values) * 2.0 + 1.0
        if cut:
            middle = middle + written(middle)
        return (torch.cos(middle) * middle).sum(-1)

    values = torch.linspace(0.0, 1.0, 24).reshape(4, 6)
    kernels = {}
    for cut in (False, True):
        torch._dynamo.reset()
        compiled = torch.compile(computation, dynamic=True)
        got, codes = run_and_get_code(compiled, values, cut)
        torch.testing.assert_close(got, computation(values, cut))
        kernels[cut] = len(re.findall(r"^cpp_fused\w* = async_compile", "\n".join(codes), flags=re.MULTILINE))
    assert kernels[False] == 1, f"the computation without a cut compiled to {kernels[False]} kernel functions"
    assert kernels[True] == 2, (
        f"an extern kernel (torch.ops.waterair.written) between two computations no longer splits inductor's C++ "
        f"into two functions ({kernels[True]}): the compiled reception's cuts (light._apart) do nothing"
    )


def test_a_multi_agent_mlp_whose_weights_a_loss_swaps_traces_anew_at_every_call():
    """Why ``actor=per_end``'s update runs eagerly (:mod:`waterair.training.compiling`): TorchRL's ``MultiAgentMLP``
    keeps its weights in a ``TensorDictParams``; a loss swaps its own copy in at each call, and a walk over the
    modules (as tensordict's ``get_dist`` makes to build the policy's distribution) hashes that object by the
    identity of what it holds, so dynamo traces every call anew. An MLP's plain parameters trace once. When the
    first assertion fails, the per-end update can compile."""

    def traced_under_swaps(net: torch.nn.Module) -> int:
        weights = TensorDict.from_module(net, as_module=True)  # as TorchRL's losses hold an actor's weights
        x = torch.randn(3, 2, 5)
        counter = CompileCounter()
        compiled = torch.compile(lambda x: net(x).sum() * len(list(net.modules())), backend=counter)
        torch._dynamo.reset()
        for _ in range(4):
            with weights.to_module(net):
                compiled(x)
        return counter.frame_count

    agents = MultiAgentMLP(
        n_agent_inputs=5, n_agent_outputs=2, n_agents=2, centralized=False, share_params=False, num_cells=[8]
    )
    assert traced_under_swaps(agents) == 4
    assert traced_under_swaps(MLP(in_features=5, out_features=2, num_cells=[8])) == 1
