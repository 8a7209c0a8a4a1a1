"""Runs the environment step (:mod:`waterair.envs.kernel`): compiled or eager, and finishes slow paths.

:class:`Stepper` runs the step's stages (advance, solve, light, conclude) as the one-graph step, or, where the
``centroid`` solver or a channel whose light does not compile (the Monte Carlo tracer, with the environment's
generator) takes a stage out of the graph, the same stages with that one eager. In the rare case that some
link's fixed-iteration path solve has not converged, it continues those links and concludes the step again
(only where the channel needs the exact point: the two-scale lattice merely centres on it).
Compiled functions are built on first use and shared by every environment in the process
(``torch.compile`` guards on the configuration, so environments that differ get graphs of their own).
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Iterator

import torch
from tensordict import TensorDict, is_tensorclass

from waterair.envs import kernel
from waterair.envs.constants import StepConstants
from waterair.envs.state import Moved, StepResult, StepState
from waterair.physics.channel import LightSamples
from waterair.physics.paths import FixedNewtonOptions, Iterate, PathProblem, finish_path, solve_path
from waterair.physics.paths.fixed import finish_unconverged
from waterair.physics.surface import WaveSurface

FINISH_ITERATIONS = 8
"""Masked Newton iterations of the links a step's fixed-iteration solve leaves unconverged."""
DENSE_FINISH_BATCH = 64
"""Up to this batch size those iterations run densely over the batch (cheaper than gathering)."""


MEMO_TYPES = (torch.Tensor, TensorDict, dict, list, tuple, int, float)
"""Types tensordict is asked about (``is_tensorclass``) around a step. It remembers the answers in a dict whose
size a compiled step's guards check, so the first answers given after a graph was compiled (in a rollout:
``Tensor`` after the first step) threw that graph away: asked before the first compile, they cost nothing."""
BATCH_SOURCES = r"L\['(state|moved|solution|action|noise)'\].*:0,L\['c'\]\.replicas"
"""The step functions' inputs whose first dimension is the batch, and the batch's copies of its links (torch's
source names, regular expressions, comma-separated): symbolic from the first graph of an evaluation."""


@contextlib.contextmanager
def varying_environments() -> Iterator[None]:
    """Compiles inside the block for many environments of a few structures (an evaluation): the step's batch
    size and the copies of each link are symbolic from the first graph (one copy, a learned policy's group, is
    a structure of its own), and nothing else ever is.

    Outside it a graph is specialised to its environment (training: one batch, one configuration). The
    numbers an evaluation's groups differ in (ω_D, which S5 sweeps and the state holds per link, the sensor's
    noise levels and threshold, the residual's range) are never constants of the graph
    (:meth:`StepConstants.traced`). torch's automatic
    dynamic shapes are off in the block: they would make symbolic whatever a process, or an earlier process
    on the machine, had seen change (the latency's packets, the harmonics of another sea), so a graph would
    depend on what ran before it, and a later process (evaluate.py after training's closing evaluation, the
    next evaluation) would compile it again instead of loading it from torch's compile cache.
    """
    with (
        torch.compiler.config.patch(dynamic_sources=BATCH_SOURCES),
        torch._dynamo.config.patch(automatic_dynamic_shapes=False),
    ):
        yield


@functools.cache
def compiled(name: str):
    """``torch.compile`` of the kernel function ``name`` (``step``, ``finish`` or ``conclude``). How many graphs
    a process may compile of it is torch's limit, raised by our entry points
    (:data:`waterair.core.process.RECOMPILE_LIMIT`)."""
    for kind in MEMO_TYPES:  # see MEMO_TYPES
        is_tensorclass(kind)
    return torch.compile(getattr(kernel, name))


class Stepper:
    """The step of one environment: ``constants``, its solver, whether to run compiled, and the
    generator of a channel that draws random numbers (the Monte Carlo tracer).

    A step is one sequence of kernel functions: advance the gimbals, solve the path, the channel's light,
    conclude (:func:`kernel.step` runs them as one graph). Where a stage cannot run in that graph it runs on its
    own, eagerly, and the others around it as they would: the ``centroid`` solver's solve, and the light of a
    channel that does not compile (with the environment's generator). Which stages, and compiled or eager, is
    decided here, once."""

    def __init__(
        self,
        constants: StepConstants,
        solver: str,
        compile_kernel: bool,
        generator: torch.Generator | None = None,
        device: torch.device | str = "cpu",
        *,
        dtype: torch.dtype,
    ):
        self.constants, self.solver, self.generator = constants, solver, generator
        self.compile_kernel = compile_kernel and constants.channel.compiles
        pick = compiled if self.compile_kernel else functools.partial(getattr, kernel)
        self._step, self._finish, self._conclude = pick("step"), pick("finish"), pick("conclude")
        # what the compiled functions get: the numbers that vary between environments as tensors (one graph)
        self.traced = constants.traced(torch.device(device), dtype) if self.compile_kernel else constants
        self._solve = self._centroid_solve if solver == "centroid" else self._fixed_solve
        self._light = None if constants.channel.compiles else self._drawn_light
        self._one_graph = solver != "centroid" and constants.channel.compiles
        self.finishing = FixedNewtonOptions(
            iterations=FINISH_ITERATIONS,
            tol=constants.tolerance,
            armijo=constants.solver.armijo,
            max_step=constants.solver.max_step,
        )

    def __call__(self, surface: WaveSurface, state: StepState, action: torch.Tensor, noise) -> StepResult:
        """One step of the links of ``state`` (whose seas are ``surface``'s)."""
        if self._one_graph:
            result = self._step(self.traced, state, action, noise)
        else:  # the same stages, the solve or the light eager
            moved = kernel.advance(self.constants, state, action, noise)
            at = state.placed(moved)  # the ends where they are at the step (where they move)
            solution = self._solve(surface, at, moved)
            light = None if self._light is None else self._light(at, moved, solution)
            result = self._conclude(self.traced, state, moved, solution, noise, light)
        finished = self.solver == "centroid" or not self.constants.channel.needs_exact_point
        if finished or bool(result.solution.converged.all()):  # the step's one host sync
            return result
        return self._finish_paths(surface, state, result, noise)

    def _fixed_solve(self, surface: WaveSurface, state: StepState, moved: Moved) -> Iterate:
        """The step's fixed-iteration solve (:func:`kernel.solve`), outside the one graph."""
        return kernel.solve(self.constants, state, moved.time)

    def _centroid_solve(self, surface: WaveSurface, state: StepState, moved: Moved) -> Iterate:
        """The paper's centroid solve of the step's path, eagerly, from the last path point."""
        path = solve_path(
            surface,
            state.tx_position,
            state.rx_position,
            moved.time,
            "centroid",
            init=state.point[:, :2],
            indices=self.constants.optics.indices,
            compiled=self.compile_kernel,
        )
        slope = -path.normal[:, :2] / path.normal[:, 2:]
        return Iterate(path.point, slope, path.point[:, :2], path.valid, path.iterations)

    def _drawn_light(self, state: StepState, moved: Moved, solution: Iterate) -> LightSamples:
        """The light of a channel that does not compile (it draws, from :attr:`generator`), eagerly."""
        c = self.constants.for_links(state.divergence)
        path = finish_path(solution, state.tx_position, state.rx_position, c.optics.indices)
        return kernel.channel_light(c, state, path, moved, self.generator)

    def _finish_paths(self, surface: WaveSurface, state: StepState, result: StepResult, noise) -> StepResult:
        """Finish the links whose fixed-iteration solve of the step ``result`` has not converged, then conclude the
        step again.

        A few per cent of links at 12 m/s, where the path point moves fast (near a caustic) or jumps
        between branches. They take :data:`FINISH_ITERATIONS` more masked iterations: compiled and
        up to :data:`DENSE_FINISH_BATCH` links in a dense pass over the batch, otherwise gathered
        (the same iterations, so the same result). The very few still left finish with the
        adaptive solver.
        """
        c, moved = self.constants, result.moved
        at = state.placed(moved)  # where the step's ends are, for the adaptive solve
        if self.compile_kernel and state.time.shape[0] <= DENSE_FINISH_BATCH:
            result = self._finish(self.traced, state, moved, result.solution, noise, self.finishing)
            if bool(result.solution.converged.all()):
                return result
        problem = PathProblem(surface, at.tx_position, at.rx_position, moved.time, c.optics.indices)
        solution = finish_unconverged(problem, result.solution, self.finishing, self.compile_kernel)
        return self._conclude(self.traced, state, moved, solution, noise)
