"""The compiled environment step (one graph: solve, gains, sensors, observation, reward) against eager.

Both run the same functions (:mod:`waterair.envs.kernel`), so they agree to float32 rounding. Over
a rollout rounding can move a path solve across its stopping threshold, which shifts the path
point within the solver tolerance: the comparison allows 1e-4 relative. Where the beam has all but
left the receiver (I ~ 1e-7), its Gaussian tail turns that into a per-mille change of I, which the
observed log-intensity feature shows as up to ~1e-4 absolute.

What inductor compiles is checked in parts, each test compiling one graph of its own (none relies on another's compile,
whatever the order), each as small as its code allows: the compile, not the rollout, is the time. One environment is
stepped compiled and eagerly, compiling in turn its step, its dense finishing and its concluding graph, the others
eager. Inductor compiles the step; the finishing (more masked iterations of the step's solve, then the step's
conclusion) and the conclusion alone are traced by dynamo and AOT autograd into one graph each and run with eager
kernels (``aot_eager``): every operation in them is in the step's graph, or in the fixed-iteration solve's that inductor
compiles below, and inductor's lowering again made those tests 20 and 15 s long on an empty cache (docs/benchmarks.md,
"Tests"). The environment: the observation presets are subsets of one observation with every extra (each part is built
by its own code whichever preset asks for it), read through the realistic sensor (noise, latency, saturation, gating)
with residual actions on the quadrant tracker, the training defaults' per-link draws and a divergence per link, on the
paper's sea and single path, whose exact point needs the finishing (one Newton iteration in the step and two at a time
in the finishing, so that links are finished on most steps). The full channel's two models (the ray tube on the paper's
sea, the two-scale lattice on the defaults') differ from it only in their light and reception, each compiled on its own;
that an environment on the defaults' channel traces into one step graph is the evaluation tests' below. The ends
move and point through their actuators, as the defaults have them; the environment compared with eager has
actuators off their resolution grids (:data:`CONTINUOUS`).
"""

import functools
from dataclasses import replace

import pytest
import torch
from torch._dynamo.testing import CompileCounter

from tests.conftest import paper_physics, preset_config
from tests.test_torch_internals import aot_eager_counted
from waterair.envs import kernel, stepper
from waterair.envs.config import OBSERVATION_EXTRAS
from waterair.envs.env import WaterAirEnv
from waterair.envs.stepper import Stepper
from waterair.physics import actuator
from waterair.physics.channel import LinkEnds, LinkGeometry, RayTube, Transceiver, TwoScale
from waterair.physics.channel import light as light_module
from waterair.physics.optics import unit_vector
from waterair.physics.paths import FixedNewtonOptions, fixed, flat_sea_point, newton, solve_path
from waterair.physics.sea import sea_state
from waterair.physics.surface import WaveSurface

COMPARED = ("observation", "gain", "gain_upper_bound", "intensity", "reward", "path_valid")
OCEAN = {"spectrum": "elfouhaily", "n_wavenumbers": 24, "n_dir": 8}
PAPER = paper_physics()  # the single path converges the tracked point: finishing
FIXED_LINK = {"wind_range": None, "offset_range": None}
"""The evaluation's environments below: every link at the default wind and offset."""
STILL = {"motion": {"kind": "static"}, "actuator": {"kind": "ideal"}}
"""Today's link before its ends moved: the step without the platforms' and actuators' parts."""
CONTINUOUS = {"actuator": {"kind": "gimbal_fsm", "gimbal_resolution": 0.0, "mirror_resolution": 0.0}}
"""The defaults' ends (hovering drone, vehicle in the sea's orbital motion, a gimbal with a fine mirror at each end)
whose actuators take any command, off their resolution grids. Rounding a command to a grid is discontinuous: where
compiled and eager code differ in a command's last bit, one takes the grid's next step (the mirror's 2 µrad), which
1.6 ω_D off a 10 mrad beam moves the intensity by 8e-4 of itself, beyond the tolerances below; the grid itself is
the actuator's tests' (tests/test_actuator.py)."""
SLOW_GIMBAL = 0.3
"""The compared environment's gimbal rate limit (rad/s; the defaults' 2.1): its random commands slew the gimbal at the
limit on most steps, so that the sub-steps a binding limit takes are compared too."""
STEP = {
    "actuator": {**CONTINUOUS["actuator"], "gimbal_rate": SLOW_GIMBAL},
    "observation_extras": OBSERVATION_EXTRAS,
    "residual_base": "aoa_tracker",
    "residual_beams": 2.0,
    "newton_iterations": 1,
    "divergence_values": (0.05, 0.01, 0.1, 0.02),
    **PAPER,
}
"""The environment whose step is compiled: every observation part, the realistic sensor, residual actions on the
quadrant tracker (the transmitter's within 2 ω_D), links with divergences of their own, the paper's single path
with one Newton iteration a step, so that links are finished on most steps, and a gimbal that slews at its limit."""


@pytest.fixture(autouse=True)
def two_substeps(monkeypatch):
    """A rate-limited axis's sub-steps (:data:`~waterair.physics.actuator.SUBSTEPS`) unrolled twice rather than 16
    times: the same code, a quarter fewer nodes in the defaults' step graph to trace and compile."""
    monkeypatch.setattr(actuator, "SUBSTEPS", 2)


@pytest.fixture
def eager_path_kernels(monkeypatch):
    """The path solves outside the step (the resets', the gathered finishing) run eagerly: for the tests that
    trace the step only, with a backend of their own."""
    monkeypatch.setattr(newton, "_compiled_fermat", lambda: newton.fermat_terms)
    monkeypatch.setattr(fixed, "compiled_fixed_newton", lambda: fixed.fixed_newton_terms)


@pytest.fixture
def one_ascent_iteration(monkeypatch):
    """The upper bound's ascent takes one iteration from each start: the same code, unrolled once rather than
    UPPER_BOUND_ITERATIONS times, a smaller graph to trace and compile."""
    monkeypatch.setattr(light_module, "upper_bound", functools.partial(light_module.upper_bound, iterations=1))


def rollout(env: WaterAirEnv, actions: torch.Tensor) -> dict[str, torch.Tensor]:
    td, trace = env.reset(), {key: [] for key in COMPARED}
    for action in actions:
        td = env.step(td.set("action", action))["next"]
        for key in COMPARED:
            trace[key].append(td[key])
    return {key: torch.stack(values) for key, values in trace.items()}


def compiling_only(monkeypatch, name: str, inductor: bool = True) -> CompileCounter:
    """Compiled environments compile only the kernel function ``name`` (``step``, ``finish`` or ``conclude``), with
    inductor or else with AOT autograd's eager kernels (``aot_eager``), whose graphs the counter returned counts; the
    others run eagerly, the same code."""
    settings, counter = stepper.compiled, CompileCounter()

    def compiled(kernel_name):
        if kernel_name != name:
            return getattr(kernel, kernel_name)
        if inductor:
            return settings(kernel_name)
        settings(kernel_name)  # its settings (recompile limit, tensordict's answers)
        return torch.compile(getattr(kernel, kernel_name), backend=aot_eager_counted(counter))

    monkeypatch.setattr(stepper, "compiled", compiled)
    torch._dynamo.reset()
    return counter


def compiled_against_eager(monkeypatch) -> None:
    """STEP's environment, compiled and eager, over the same actions: the same outputs to float32 rounding, the
    finishing reached on most steps, the graphs kept by torch's compile cache, the eager one tracing nothing."""
    batch, steps = 8, 40
    config = preset_config("quadrant", "realistic", batch, **STEP)
    finishes = []  # the links a fixed-iteration solve leaves unconverged, finished in graphs of their own
    finish = Stepper._finish_paths
    monkeypatch.setattr(Stepper, "_finish_paths", lambda self, *a: finishes.append(1) or finish(self, *a))
    monkeypatch.setattr(stepper, "FINISH_ITERATIONS", 2)  # the finishing graphs' iterations: the same code, smaller
    actions = 0.3 * torch.randn(steps, batch, 4, generator=torch.Generator().manual_seed(batch))
    bypassed = torch._dynamo.utils.counters["inductor"]["fxgraph_cache_bypass"]
    compiled = rollout(WaterAirEnv(config.replace(compile_kernel=True)), actions)
    # torch's compile cache keeps the graphs (no op with effects in them): a later process pays only tracing
    assert torch._dynamo.utils.counters["inductor"]["fxgraph_cache_bypass"] == bypassed
    captured = torch._dynamo.utils.counters["stats"]["calls_captured"]
    eager_env = WaterAirEnv(config)
    eager = rollout(eager_env, actions)
    assert torch._dynamo.utils.counters["stats"]["calls_captured"] == captured  # the eager env traced nothing
    assert eager_env.state.drive[..., 1].abs().max() == SLOW_GIMBAL, "no gimbal reached its rate limit"
    assert config.compile_kernel is False and eager["observation"].shape[-1] == config.observation_size
    assert eager["gain"].abs().max() > 0 and eager["path_valid"].float().mean() > 0.95
    assert len(finishes) > steps // 2, "few steps left a link unconverged: the finishing graphs went untested"
    for key in COMPARED:
        assert torch.isfinite(compiled[key].float()).all(), key
        atol = {"observation": 1e-4, "reward": 1e-5}.get(key, 1e-7)
        torch.testing.assert_close(compiled[key], eager[key], rtol=1e-4, atol=atol, msg=key)


@pytest.mark.slow
def test_the_compiled_step_agrees_with_eager_and_an_eager_env_beside_it_stays_eager(
    monkeypatch, inductor, eager_path_kernels
):
    """The step's graph (advance, one Newton iteration, light, reception, sensor, observation, reward); the
    finishing runs eagerly."""
    compiling_only(monkeypatch, "step")
    compiled_against_eager(monkeypatch)


@pytest.mark.slow
def test_the_dense_finishing_graph_agrees_with_eager(monkeypatch, eager_path_kernels):
    """The finishing of a small batch (at most DENSE_FINISH_BATCH links): more masked iterations over the whole
    batch and the step concluded again, one graph traced once; the step before it runs eagerly, as do the few links
    left for the gathered finishing."""
    traced = compiling_only(monkeypatch, "finish", inductor=False)
    compiled_against_eager(monkeypatch)
    assert traced.frame_count == 1, f"the finishing traced into {traced.frame_count} graphs"


@pytest.mark.slow
def test_the_concluding_graph_agrees_with_eager(monkeypatch, eager_path_kernels):
    """The finishing of a large batch (here every batch: DENSE_FINISH_BATCH 0) gathers the unconverged links for
    the fixed-iteration and adaptive solvers (their compiled kernels are the fixed-iteration test's below), then
    concludes the step in a graph of its own, traced once; the step before it runs eagerly."""
    monkeypatch.setattr(stepper, "DENSE_FINISH_BATCH", 0)
    traced = compiling_only(monkeypatch, "conclude", inductor=False)
    compiled_against_eager(monkeypatch)
    assert traced.frame_count == 1, f"the conclusion traced into {traced.frame_count} graphs"


FULL_CHANNEL = {
    "ray-tube": (RayTube, {"spectrum": "jonswap", "wind": 12.0, "n_freq": 32, "n_dir": 16}),
    "two-scale": (TwoScale, {"wind": 12.0, **OCEAN}),
}
"""The full channel's model on each sea: the ray tube on the paper's, the two-scale lattice on the measured-slope
sea (the defaults)."""


@pytest.mark.slow
@pytest.mark.parametrize("part", ["light", "reception"])
@pytest.mark.parametrize("model", list(FULL_CHANNEL))
def test_the_full_channels_light_and_reception_compile_to_what_they_measure_eagerly(
    model, part, inductor, one_ascent_iteration
):
    """An environment on the full channel steps as the ones above but for the channel's light and reception (that
    its step traces into one graph is tested below and in tests/test_channel_models.py): each, compiled by
    inductor on its own with ω_D a tensor as the step compiles them, gives on a wavy sea with both ends off the
    path what it gives eagerly, to float32 rounding. The upper bound's ascent takes one iteration from each start
    (the same code, unrolled once rather than UPPER_BOUND_ITERATIONS times)."""
    kind, sea = FULL_CHANNEL[model]
    channel, batch = kind(Transceiver()), 4
    surface = WaveSurface.sample(sea_state(**{"spectrum": "jonswap", **sea}), batch, seed=1)
    tx, rx = (v.expand(batch, 3).contiguous() for v in LinkGeometry(offset_ratio=0.2).positions())
    point = flat_sea_point(tx, rx)
    path = solve_path(surface, tx, rx, 1.0)
    tilt = torch.tensor([0.004, -0.003, 0.0])
    tx_dir, rx_dir = unit_vector(point - tx + tilt), unit_vector(point - rx - tilt)
    ends, time = LinkEnds(tx, rx, point, tx_dir), torch.ones(batch)
    prepared = channel.prepare(tx, rx, surface.unresolved)

    def light(channel):
        samples = channel.light(surface.harmonics, path, ends, time, prepared)
        return samples.weight, samples.departure, samples.arrival

    def reception(channel, samples):
        reception = channel.receive(samples, tx_dir, rx_dir)
        return reception.gain, reception.upper_bound, reception.alpha_d

    traced = replace(channel, optics=channel.optics.traced())
    if part == "light":
        eager, compiled = light(channel), torch.compile(light)(traced)
    else:
        samples = channel.light(surface.harmonics, path, ends, time, prepared)
        eager, compiled = reception(channel, samples), torch.compile(reception)(traced, samples)
    assert bool((eager[0].reshape(batch, -1).sum(-1) > 0).all())
    for got, want in zip(compiled, eager, strict=True):
        torch.testing.assert_close(got, want, rtol=1e-5, atol=1e-7)


@pytest.mark.slow
@pytest.mark.parametrize(
    "dtype,bound,compiled",
    [(torch.float64, 1e-9, None), (torch.float32, 1e-4, "fixed"), (torch.float32, 1e-4, "adaptive")],
)
def test_fixed_iteration_paths_obey_snell_and_match_the_adaptive_solver(
    dtype, bound, compiled, default_positions, inductor, monkeypatch
):
    """The fixed-iteration solver from cold starts (most links need the finishing stages): eagerly in float64,
    where the bound is tight, and compiled in float32, as environments run it to finish the links of a large
    batch (two iterations at a time, as in the tests above): its iterations' kernel (on every link, then on those
    left) or the adaptive solver's (on the few left after them), each compiled in a test of its own, the other
    eager."""
    if compiled == "fixed":
        monkeypatch.setattr(newton, "_compiled_fermat", lambda: newton.fermat_terms)
    elif compiled == "adaptive":
        monkeypatch.setattr(fixed, "compiled_fixed_newton", lambda: fixed.fixed_newton_terms)
    tx, rx = (v.to(dtype) for v in default_positions)
    surface = WaveSurface.sample(sea_state("jonswap", wind=12.0), 256, seed=3, dtype=dtype)
    adaptive = solve_path(surface, tx, rx, 4.0)
    path = solve_path(surface, tx, rx, 4.0, method="newton_fixed", compiled=compiled is not None)
    assert path.valid.float().mean().item() >= 0.99
    both = path.valid & adaptive.valid
    cross_d = torch.linalg.cross(path.departure, path.normal, dim=-1)
    cross_a = torch.linalg.cross(path.arrival, path.normal, dim=-1)
    residual = torch.linalg.vector_norm(1.33 * cross_d - 1.0 * cross_a, dim=-1)
    assert residual[path.valid].max().item() < bound
    height = surface.height(path.point[:, 0], path.point[:, 1], 4.0)
    assert (height - path.point[:, 2])[path.valid].abs().max().item() < 10 * bound
    # the same stationary point as the adaptive solver for almost every link (a few find another branch)
    close = torch.linalg.vector_norm(path.point - adaptive.point, dim=-1) < 1e3 * bound
    assert close[both].float().mean().item() >= 0.99


def test_fixed_iteration_solver_without_finishing_flags_unconverged_links_invalid(default_positions):
    tx, rx = default_positions
    surface = WaveSurface.sample(sea_state("jonswap", wind=12.0), 64, seed=7, dtype=torch.float64)
    options = FixedNewtonOptions(iterations=1, finish=False)
    path = solve_path(surface, tx, rx, 0.0, method=options)
    finished = solve_path(surface, tx, rx, 0.0, method=FixedNewtonOptions(iterations=1))
    assert (~path.valid).any() and finished.valid.float().mean() > (path.valid.float().mean())
    assert path.iterations.max().item() == 1 and finished.iterations.max().item() > 1
    for value in (path.point, path.departure, path.theta1, path.d_air):
        assert torch.isfinite(value).all()


EVALUATION_ENVS = (
    (4, {"optics": {"divergence": 0.05}, "replicas": 2}),
    (9, {"optics": {"divergence": 0.005}, "replicas": 3, "intensity_noise": 0.2, "spot_noise_rad": 0.01}),
    (6, {"optics": {"divergence": 0.02}, "replicas": 2, "intensity_noise_floor": 0.01, "spot_threshold": 0.05,
         "residual_deg": 1.0}),
)  # fmt: skip
"""Environments of one structure (quadrant detector, realistic sensor, residual on the tracker, two or more
copies of each link) that differ in every number an evaluation's groups differ in: the batch, ω_D (S5), the
copies of each link (a group's policies), the sensor's noise levels and threshold, and the residual's range."""


@pytest.mark.slow
def test_an_evaluation_compiles_one_step_graph_for_every_batch_size_and_setting(
    monkeypatch, eager_path_kernels, one_ascent_iteration
):
    """Inside ``varying_environments`` (what an evaluation runs in) environments of one structure share one
    step graph, whichever of them compiles first: nothing in the step fixes the batch size (a tensorclass
    sliced as a whole did), the graph reads ω_D, the sensor's noise levels and threshold and the residual's
    range as tensors and the copies of each link as a symbolic size (as constants, each new value compiled
    the step again, symbolic only once torch had seen it change: a process's graphs, and what a later
    process could load from the compile cache, depended on the order of the groups), and tensordict's
    answers remembered during a rollout do not throw the first graph away. Traced only (dynamo's counting
    backend), on the defaults' channel over a coarse sea, one Newton iteration a step. torch's automatic dynamic
    shapes are off in the block, so no profile of an earlier process (one that had seen these vary) makes
    anything symbolic."""
    from torch._dynamo.testing import CompileCounter

    counter, traced, settings = CompileCounter(), {}, stepper.compiled

    def counted(name):  # stepper.compiled, with the counting backend instead of inductor
        settings(name)  # its settings (recompile limit, tensordict's answers)
        return traced.setdefault(name, torch.compile(getattr(kernel, name), backend=counter))

    monkeypatch.setattr(stepper, "compiled", counted)
    torch._dynamo.reset()
    gains = []
    with stepper.varying_environments():
        for batch, keys in EVALUATION_ENVS:
            config = preset_config("quadrant", "realistic", batch, compile_kernel=True, sea=OCEAN, newton_iterations=1)
            config = config.replace(residual_base="aoa_tracker", **keys, **FIXED_LINK)
            actions = torch.linspace(-1.0, 1.0, 3 * batch * 4).reshape(3, batch, 4)
            gains.append(rollout(WaterAirEnv(config), actions)["gain"][:, :2])
            eager = rollout(WaterAirEnv(config.replace(compile_kernel=False)), actions)
            torch.testing.assert_close(gains[-1], eager["gain"][:, :2], rtol=1e-4, atol=1e-7)
    assert counter.frame_count == 1
    # each environment measured its own gain (eager, which reads every setting afresh, agreed with each above)
    assert all(not torch.allclose(a, b) for a, b in zip(gains, gains[1:], strict=False))


@pytest.mark.slow
def test_a_groups_graph_in_an_evaluation_does_not_depend_on_the_groups_before_it(monkeypatch, eager_path_kernels):
    """The realistic sensor's step graph compiled after an ideal-sensor group's (no latency: one packet in flight, not
    two) has no size symbolic but the batch's, as compiled alone. With torch's automatic dynamic shapes the second
    compile would make the packets' count symbolic, and the graph, which a later process looks up in torch's compile
    cache, would depend on the order of the groups. Traced only, on the paper's single path over a small sea between
    still ends pointed at once (the packets are the channel's whatever it is, and the ends'); each graph's inputs
    read for the sizes dynamo made symbolic."""
    graphs = []

    def keep(graph, example_inputs):  # a backend that keeps each graph and runs it as traced
        graphs.append(graph)
        return graph.forward

    def symbolic(graph) -> set[int]:  # the dimensions of the graph's tensor inputs whose size is symbolic
        shapes = [getattr(node.meta.get("example_value"), "shape", ()) for node in graph.graph.nodes
                  if node.op == "placeholder"]  # fmt: skip
        return {dim for shape in shapes for dim, size in enumerate(shape) if isinstance(size, torch.SymInt)}

    torch._dynamo.reset()
    step = torch.compile(kernel.step, backend=keep)
    monkeypatch.setattr(stepper, "compiled", lambda name: step if name == "step" else getattr(kernel, name))
    with stepper.varying_environments():
        for sensor in ("ideal", "realistic"):
            physics = {**paper_physics(n_freq=16, n_dir=8), **STILL}  # one Newton iteration a step: a smaller graph
            config = preset_config("quadrant", sensor, 4, compile_kernel=True, newton_iterations=1, **physics)
            rollout(WaterAirEnv(config.replace(**FIXED_LINK)), torch.zeros(2, 4, 4))
    assert len(graphs) == 2, f"{len(graphs)} graphs for two sensors"
    ideal, realistic = graphs
    assert "packets" in realistic.code and realistic.code != ideal.code
    assert symbolic(ideal) == symbolic(realistic) == {0}, (
        f"sizes symbolic in the realistic sensor's graph after the ideal one's: dimensions {symbolic(realistic)} of "
        "its inputs (the batch's alone, 0, is symbolic in a graph compiled first)"
    )


REALISTIC = {"latency_steps": 1, "intensity_noise": 0.05, "intensity_noise_floor": 1e-3, "intensity_saturation": 4.0,
             "spot_noise_rad": 1e-3, "spot_threshold": 0.01, "beacon_noise_rad": 1e-3,
             "beacon_threshold": 0.01}  # fmt: skip
ACTING = ({}, {"residual_base": "kalman_tracker", "residual_deg": 5.0}, {"action_mode": "delta"})
"""Three replicas acting three ways: residuals on the quadrant tracker within 1°, on the Kalman tracker within 5°
(the tracks the state keeps followed, whichever way the batch's configuration acts), slew steps."""
SENSING = ({}, REALISTIC, {"latency_steps": 2, "intensity_saturation": 0.3, "spot_threshold": 0.2})
"""Three replicas sensing three ways: ideal, realistic, two steps late with a detector that saturates and sees
little (the quadrant tracker under the residuals reads the latency too)."""


MOVING = {"motion": {"kind": "hover"}, "actuator": {"kind": "gimbal_fsm"}}
"""The link at sea: its motion draws each step's normals after the readings' (the sensor's nonce first)."""


@pytest.mark.parametrize(
    ("acting", "sensing", "compiled", "ends"),
    [
        (ACTING, None, False, {}),
        (None, SENSING, False, {}),
        (ACTING, SENSING, True, {}),
        (None, SENSING, False, MOVING),
    ],
    ids=["acting", "sensing", "both-compiled", "sensing-moving"],
)
def test_replicas_that_act_or_sense_their_own_ways_each_step_as_an_environment_of_that_way(
    acting, sensing, compiled, ends, eager_path_kernels
):
    """``env.replica_actions``, ``env.replica_sensing`` (evaluation's groups of policies that act or sense
    differently): replica k of a batch steps as replica k of a batch in which every replica acts and senses its
    way, on the same seas, actions and sensor noise; compiled (traced by dynamo, run eagerly: the graph's logic,
    not inductor's code) as eager. The paper's single path, float64. With the ends moving, the motion's draws are
    the same whatever the replicas' sensing (a noiseless sensor draws its reading's nonce too)."""
    base = preset_config("beacon", "ideal", 6, **FIXED_LINK, **PAPER, **ends)
    base = base.replace(replicas=3, residual_base="aoa_tracker", residual_deg=1.0, residual_beams=None, dtype="float64")
    ways = [{**a, **b} for a, b in zip(acting or [{}] * 3, sensing or [{}] * 3, strict=True)]
    actions = torch.linspace(-1.0, 1.0, 4 * 6 * 4, dtype=torch.float64).reshape(4, 6, 4).sin()
    alike = [rollout(WaterAirEnv(base.replace(**way)), actions) for way in ways]
    mixed = base.replace(replica_actions=acting, replica_sensing=sensing, compile_kernel=compiled)
    if compiled:
        torch._dynamo.reset()
        with stepper.varying_environments():
            stepper.compiled.cache_clear()
            env = WaterAirEnv(mixed)  # the step traced (advance is in it); its rare finishing runs eagerly
            env.stepper._step, env.stepper._finish = torch.compile(kernel.step, backend="eager"), kernel.finish
            got = rollout(env, actions)
    else:
        got = rollout(WaterAirEnv(mixed), actions)
    for k, expected in enumerate(alike):
        rows = slice(2 * k, 2 * k + 2)
        for name in COMPARED:
            torch.testing.assert_close(got[name][:, rows], expected[name][:, rows], rtol=1e-12, atol=1e-15, msg=name)
    # the ways differ: the same action points each replica elsewhere, or each reads another observation
    for name in ("gain",) * bool(acting) + ("observation",) * bool(sensing):
        assert not torch.allclose(got[name][:, 0:2], got[name][:, 2:4]), name


def test_replicas_that_all_act_one_way_act_that_way_not_the_configs(eager_path_kernels):
    """Every replica acting one way other than the config's own (evaluation's kinematic reference alone on moving
    ends: ``actuated = false``) steps as an environment configured that way, not as the config's own way."""
    base = preset_config("quadrant", "ideal", 2, **FIXED_LINK, **PAPER, **MOVING).replace(dtype="float64")
    actions = torch.linspace(-1.0, 1.0, 4 * 2 * 4, dtype=torch.float64).reshape(4, 2, 4).sin()
    way = {"actuated": False, "residual_deg": 5.0}
    expected = rollout(WaterAirEnv(base.replace(**way)), actions)
    got = rollout(WaterAirEnv(base.replace(replica_actions=(way,))), actions)
    for name in COMPARED:
        torch.testing.assert_close(got[name], expected[name], rtol=1e-12, atol=1e-15, msg=name)
    assert not torch.allclose(rollout(WaterAirEnv(base), actions)["gain"], expected["gain"])  # the way matters


def test_replica_actions_and_sensing_are_checked_naming_the_entry():
    base = preset_config("quadrant", "ideal", 4).replace(replicas=2)
    with pytest.raises(ValueError, match=r"^env.replica_actions has 1 entries for env.replicas = 2"):
        base.replace(replica_actions=[{}])
    with pytest.raises(ValueError, match=r"^env.replica_actions\[1\] = \{'frames': 2\} must map some of action_mode"):
        base.replace(replica_actions=[{}, {"frames": 2}])
    with pytest.raises(ValueError, match=r"^env.replica_actions\[0\]: env.residual_deg = 95"):
        base.replace(replica_actions=[{"residual_deg": 95.0}, {}])
    assert base.replace(replica_actions=[{}, {"action_mode": "delta"}]).replica_configs()[1].action_mode == "delta"
    with pytest.raises(ValueError, match=r"^env.replica_sensing\[1\] = \{'residual_deg': 2.0\} must map some of lat"):
        base.replace(replica_sensing=[{}, {"residual_deg": 2.0}])
    with pytest.raises(ValueError, match=r"^env.replica_sensing\[0\]: env.intensity_noise = -1"):
        base.replace(replica_sensing=[{"intensity_noise": -1.0}, {}])
    both = base.replace(replica_actions=[{"action_mode": "delta"}, {}], replica_sensing=[{}, {"latency_steps": 2}])
    assert [(c.action_mode, c.latency_steps) for c in both.replica_configs()] == [("delta", 0), (base.action_mode, 2)]
