"""The compiled environment step (one graph: solve, gains, sensors, observation, reward) against eager.

Both run the same functions (:mod:`waterair.envs.kernel`), so they agree to float32 rounding. Over
100 steps rounding can move a path solve across its stopping threshold, which shifts the path
point within the solver tolerance: the comparison allows 1e-4 relative. Where the beam has all but
left the receiver (I ~ 1e-7), its Gaussian tail turns that into a per-mille change of I, which the
observed log-intensity feature shows as up to ~1e-4 absolute.

Three small graphs cover what compiles: the observation presets are subsets of one observation with
every extra (each part is built by its own code whichever preset asks for it), read through the
realistic sensor (noise, latency, saturation, gating) with residual actions on the quadrant tracker
and the training defaults' per-link draws, on the paper's sea and single path (whose exact point
needs the finishing graphs); and the full channel on each sea (the ray tube on the paper's, the
two-scale lattice on the ocean's: the defaults). Each test compiles its own graph: none relies on
another's compile, whatever the order.
"""

import pytest
import torch

from tests.conftest import preset_config
from waterair.envs.config import OBSERVATION_EXTRAS
from waterair.envs.env import WaterAirEnv
from waterair.envs.stepper import Stepper
from waterair.physics.paths import FixedNewtonOptions, solve_path
from waterair.physics.sea import sea_state
from waterair.physics.surface import WaveSurface

COMPARED = ("observation", "gain", "gain_upper_bound", "intensity", "reward", "path_valid")
OCEAN = {"spectrum": "elfouhaily", "n_wavenumbers": 24, "n_dir": 8}
PAPER = {"spectrum": "jonswap", "channel": "single_path"}  # the single path converges the tracked point: finishing
CONVERGING = {"wind_range": None, "offset_range": None, "newton_iterations": 8}
"""The ray tube needs the exact path point: at the default sea and offset, with iterations enough that
the step's graph converges, it compiles without the finishing graphs (which the first graph covers)."""
GRAPHS = {
    "every-extra": ({"observation_extras": OBSERVATION_EXTRAS, "residual_base": "aoa_tracker", **PAPER}, 8, 100),
    "ray-tube": ({"channel": "full", "spectrum": "jonswap", "n_freq": 32, "n_dir": 16, **CONVERGING}, 2, 40),
    "two-scale": ({"channel": "full", **OCEAN}, 4, 40),  # the defaults' sea and channel, a coarser sea
}
"""Each graph: its keys over the quadrant preset with the realistic sensor, its batch and its steps."""


def rollout(env: WaterAirEnv, actions: torch.Tensor) -> dict[str, torch.Tensor]:
    td, trace = env.reset(), {key: [] for key in COMPARED}
    for action in actions:
        td = env.step(td.set("action", action))["next"]
        for key in COMPARED:
            trace[key].append(td[key])
    return {key: torch.stack(values) for key, values in trace.items()}


@pytest.mark.slow
@pytest.mark.parametrize("graph", list(GRAPHS))
def test_compiled_and_eager_steps_agree_and_an_eager_env_beside_a_compiled_one_stays_eager(graph, monkeypatch):
    keys, batch, steps = GRAPHS[graph]
    config = preset_config("quadrant", "realistic", batch, **keys)
    finishes = []  # the links a fixed-iteration solve leaves unconverged, finished in a graph of their own
    finish = Stepper._finish_paths
    monkeypatch.setattr(Stepper, "_finish_paths", lambda self, *a: finishes.append(1) or finish(self, *a))
    actions = 0.3 * torch.randn(steps, batch, 4, generator=torch.Generator().manual_seed(batch))
    bypassed = torch._dynamo.utils.counters["inductor"]["fxgraph_cache_bypass"]
    compiled = rollout(WaterAirEnv(config.replace(compile_kernel=True)), actions)
    # torch's compile cache keeps the graph (no op with effects in it): a later process pays only tracing
    assert torch._dynamo.utils.counters["inductor"]["fxgraph_cache_bypass"] == bypassed
    captured = torch._dynamo.utils.counters["stats"]["calls_captured"]
    eager = rollout(WaterAirEnv(config), actions)
    assert torch._dynamo.utils.counters["stats"]["calls_captured"] == captured  # the eager env traced nothing
    assert config.compile_kernel is False and eager["observation"].shape[-1] == config.observation_size
    assert eager["gain"].abs().max() > 0 and eager["path_valid"].float().mean() > 0.95
    if graph == "every-extra":
        assert finishes, "no step left a link unconverged: the finishing graph went untested"
    for key in COMPARED:
        assert torch.isfinite(compiled[key].float()).all(), key
        atol = {"observation": 1e-4, "reward": 1e-5}.get(key, 1e-7)
        torch.testing.assert_close(compiled[key], eager[key], rtol=1e-4, atol=atol, msg=key)


@pytest.mark.slow
@pytest.mark.parametrize("dtype,bound,compiled", [(torch.float64, 1e-9, True), (torch.float32, 1e-4, False)])
def test_fixed_iteration_paths_obey_snell_and_match_the_adaptive_solver(dtype, bound, compiled, default_positions):
    """The fixed-iteration solver from cold starts (most links need the finishing stages): compiled in
    float64, where the bound is tight, and eagerly in float32 (the first graph above runs it compiled)."""
    tx, rx = (v.to(dtype) for v in default_positions)
    surface = WaveSurface.sample(sea_state(wind=12.0), 256, seed=3, dtype=dtype)
    adaptive = solve_path(surface, tx, rx, 4.0)
    fixed = solve_path(surface, tx, rx, 4.0, method="newton_fixed", compiled=compiled)
    assert fixed.valid.float().mean().item() >= 0.99
    both = fixed.valid & adaptive.valid
    cross_d = torch.linalg.cross(fixed.departure, fixed.normal, dim=-1)
    cross_a = torch.linalg.cross(fixed.arrival, fixed.normal, dim=-1)
    residual = torch.linalg.vector_norm(1.33 * cross_d - 1.0 * cross_a, dim=-1)
    assert residual[fixed.valid].max().item() < bound
    height = surface.height(fixed.point[:, 0], fixed.point[:, 1], 4.0)
    assert (height - fixed.point[:, 2])[fixed.valid].abs().max().item() < 10 * bound
    # the same stationary point as the adaptive solver for almost every link (a few find another branch)
    close = torch.linalg.vector_norm(fixed.point - adaptive.point, dim=-1) < 1e3 * bound
    assert close[both].float().mean().item() >= 0.99


def test_fixed_iteration_solver_without_finishing_flags_unconverged_links_invalid(default_positions):
    tx, rx = default_positions
    surface = WaveSurface.sample(sea_state(wind=12.0), 64, seed=7, dtype=torch.float64)
    options = FixedNewtonOptions(iterations=1, finish=False)
    path = solve_path(surface, tx, rx, 0.0, method="newton_fixed", options=options)
    finished = solve_path(surface, tx, rx, 0.0, method="newton_fixed", options=FixedNewtonOptions(iterations=1))
    assert (~path.valid).any() and finished.valid.float().mean() > (path.valid.float().mean())
    assert path.iterations.max().item() == 1 and finished.iterations.max().item() > 1
    for value in (path.point, path.departure, path.theta1, path.d_air):
        assert torch.isfinite(value).all()


EVALUATION_ENVS = (
    (4, {"optics": {"divergence": 0.05}, "replicas": 2}),
    (9, {"optics": {"divergence": 0.005}, "replicas": 3, "intensity_noise": 0.2, "spot_noise_rad": 0.01}),
    (6, {"optics": {"divergence": 0.02}, "replicas": 2, "intensity_noise_floor": 0.01, "spot_threshold": 0.05}),
    (6, {"optics": {"divergence": 0.05}, "replicas": 3, "residual_deg": 1.0}),
)
"""Environments of one structure (quadrant detector, realistic sensor, residual on the tracker, two or more
copies of each link) that differ in every number an evaluation's groups differ in: the batch, ω_D (S5), the
copies of each link (a group's policies), the sensor's noise levels and threshold, and the residual's range."""


def test_an_evaluation_compiles_one_step_graph_for_every_batch_size_and_setting(monkeypatch):
    """Inside ``varying_environments`` (what an evaluation runs in) environments of one structure share one
    step graph, whichever of them compiles first: nothing in the step fixes the batch size (a tensorclass
    sliced as a whole did), the graph reads ω_D, the sensor's noise levels and threshold and the residual's
    range as tensors and the copies of each link as a symbolic size (as constants, each new value compiled
    the step again, symbolic only once torch had seen it change: a process's graphs, and what a later
    process could load from the compile cache, depended on the order of the groups), and tensordict's
    answers remembered during a rollout do not throw the first graph away. Traced only (dynamo's counting
    backend), on the defaults' channel over a coarse sea. torch's automatic dynamic shapes are off in the
    block, so no profile of an earlier process (one that had seen these vary) makes anything symbolic."""
    from torch._dynamo.testing import CompileCounter

    from waterair.envs import kernel, stepper

    counter, traced, settings = CompileCounter(), {}, stepper.compiled

    def counted(name):  # stepper.compiled, with the counting backend instead of inductor
        settings(name)  # its settings (recompile limit, tensordict's answers)
        return traced.setdefault(name, torch.compile(getattr(kernel, name), backend=counter))

    monkeypatch.setattr(stepper, "compiled", counted)
    torch._dynamo.reset()
    gains = []
    with stepper.varying_environments():
        for batch, keys in EVALUATION_ENVS:
            config = preset_config("quadrant", "realistic", batch, channel="full", compile_kernel=True, **OCEAN)
            config = config.replace(residual_base="aoa_tracker", **keys, **CONVERGING)
            actions = torch.linspace(-1.0, 1.0, 3 * batch * 4).reshape(3, batch, 4)
            gains.append(rollout(WaterAirEnv(config), actions)["gain"][:, :2])
            eager = rollout(WaterAirEnv(config.replace(compile_kernel=False)), actions)
            torch.testing.assert_close(gains[-1], eager["gain"][:, :2], rtol=1e-4, atol=1e-7)
    assert counter.frame_count == 1
    # each environment measured its own gain (eager, which reads every setting afresh, agreed with each above)
    assert all(not torch.allclose(a, b) for a, b in zip(gains, gains[1:], strict=False))


def test_a_groups_graph_in_an_evaluation_does_not_depend_on_the_groups_before_it(monkeypatch):
    """The realistic sensor's step graph is the same whether or not an ideal-sensor group (no latency: one
    packet in flight, not two) compiled before it in the process. With torch's automatic dynamic shapes the
    second compile would make the packets' count symbolic, and the graph, which a later process looks up in
    torch's compile cache, would depend on the order of the groups. Traced only; the graphs' code compared."""
    from waterair.envs import kernel, stepper

    def realistic_graph(after_ideal: bool) -> str:
        codes = []

        def keep(graph, example_inputs):  # a backend that keeps each graph's code and runs it as traced
            codes.append(graph.code)
            return graph.forward

        torch._dynamo.reset()
        step = torch.compile(kernel.step, backend=keep)
        monkeypatch.setattr(stepper, "compiled", lambda name: step if name == "step" else getattr(kernel, name))
        with stepper.varying_environments():
            for sensor in ("ideal", "realistic") if after_ideal else ("realistic",):
                config = preset_config("quadrant", sensor, 4, channel="full", compile_kernel=True, **OCEAN)
                rollout(WaterAirEnv(config.replace(**CONVERGING)), torch.zeros(2, 4, 4))
        assert len(codes) == (2 if after_ideal else 1)
        return codes[-1]

    alone, after = realistic_graph(after_ideal=False), realistic_graph(after_ideal=True)
    assert "packets" in alone and alone == after
