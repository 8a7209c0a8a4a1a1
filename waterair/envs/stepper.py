"""Runs the environment step (:mod:`waterair.envs.kernel`): compiled or eager, and finishes slow paths.

:class:`Stepper` calls the one-graph step, and in the rare case that some link's fixed-iteration
path solve has not converged, continues those links and concludes the step again (only where the
channel needs the exact point: the two-scale lattice merely centres on it); with the ``centroid``
solver it solves eagerly and concludes in the graph; with the Monte Carlo channel it traces eagerly.
Compiled functions are built on first use and shared by every environment in the process
(``torch.compile`` guards on the configuration, so environments that differ get graphs of their own).
"""

from __future__ import annotations

import functools

import torch

from waterair.envs import kernel
from waterair.envs.kernel import SURFACE_KEYS, StepConstants
from waterair.physics.montecarlo import trace
from waterair.physics.optics import beam_divergence, unit_vector
from waterair.physics.paths import FixedNewtonOptions, solve_path
from waterair.physics.paths.fixed import finish_unconverged
from waterair.physics.surface import WaveSurface

FINISH_ITERATIONS = 8
"""Masked Newton iterations of the links a step's fixed-iteration solve leaves unconverged."""
DENSE_FINISH_BATCH = 64
"""Up to this batch size those iterations run densely over the batch (cheaper than gathering)."""


@functools.cache
def compiled(name: str):
    """``torch.compile`` of the kernel function ``name`` (``step``, ``finish`` or ``conclude``)."""
    return torch.compile(getattr(kernel, name))


class Stepper:
    """The step of one environment: ``constants``, its solver, and whether to run compiled."""

    def __init__(
        self,
        constants: StepConstants,
        solver: str,
        compile_kernel: bool,
        montecarlo: tuple[int, int, torch.Generator] | None = None,
    ):
        self.constants, self.solver, self.compile_kernel = constants, solver, compile_kernel
        self.montecarlo = montecarlo  # (rays, facets, generator) of env.channel=montecarlo
        pick = compiled if compile_kernel else functools.partial(getattr, kernel)
        self._step, self._finish, self._conclude = pick("step"), pick("finish"), pick("conclude")

    def __call__(self, surface: WaveSurface, state: dict, action: torch.Tensor, noise):
        """(new state entries, outputs) of one step; ``state`` includes the surface's components."""
        c = self.constants
        if c.channel == "montecarlo":
            moved = kernel.advance(c, state, action)
            point, slope, _, converged, taken = kernel.solve(c, state, moved["time"])
            tx, rx = state["tx_position"], state["rx_position"]
            light = self.montecarlo_light(surface, tx, rx, moved["time"], state["flat_point"])
            return kernel.conclude(c, state, moved, (point, slope, converged, taken), noise, light)
        if self.solver == "centroid":
            moved = kernel.advance(c, state, action)
            path = solve_path(
                surface,
                state["tx_position"],
                state["rx_position"],
                moved["time"],
                "centroid",
                init=state["point"][:, :2],
                n_water=c.optics.n_water,
                n_air=c.optics.n_air,
                compiled=self.compile_kernel,
            )
            slope = -path.normal[:, :2] / path.normal[:, 2:]
            return self._conclude(c, state, moved, (path.point, slope, path.valid, path.iterations), noise)
        new, outputs, moved, solution = self._step(c, state, action, noise)
        if not c.tracks_exactly or bool(solution[3].all()):  # the one host synchronisation of a step
            return new, outputs
        return self._finish_paths(surface, state, moved, solution, noise)

    def reset_light(self, surface: WaveSurface, ends: dict, path, time: torch.Tensor):
        """The light of freshly reset links (their ``surface`` rows, ``ends``: flat point, positions,
        lattice), or None for ``single_path``."""
        c = self.constants
        if c.channel == "full":
            state = {**ends, **{key: getattr(surface, key) for key in SURFACE_KEYS}}
            return kernel.full_light(c, state, path, time)
        if c.channel == "montecarlo":
            tx, rx, flat = ends["tx_position"], ends["rx_position"], ends["flat_point"]
            return self.montecarlo_light(surface, tx, rx, time, flat)
        return None

    def montecarlo_light(self, surface: WaveSurface, tx, rx, time: torch.Tensor, flat_point: torch.Tensor):
        """The Monte Carlo tracer's hits for links ``[n]`` (eager): rays from each transmitter around
        its calm-sea direction, twice as wide as the beam, counted across the calm-sea arrival."""
        assert self.montecarlo is not None
        rays, facets, generator = self.montecarlo
        optics = self.constants.optics
        axis, reference = unit_vector(flat_point - tx), unit_vector(rx - flat_point)
        result = trace(
            surface,
            tx,
            rx,
            time,
            optics,
            axis=axis,
            reference=reference,
            width=beam_divergence(optics.divergence, optics.wavelength),
            rays=rays,
            facets=facets,
            generator=generator,
        )
        return result.light

    def _finish_paths(self, surface: WaveSurface, state: dict, moved: dict, solution: tuple, noise):
        """Finish the links whose fixed-iteration solve has not converged, then conclude the step again.

        A few per cent of links at 12 m/s, where the path point moves fast (near a caustic) or jumps
        between branches. They take :data:`FINISH_ITERATIONS` more masked iterations: compiled and
        up to :data:`DENSE_FINISH_BATCH` links in a dense pass over the batch, otherwise gathered
        (the same iterations, so the same result). The very few still left finish with the
        adaptive solver.
        """
        c = self.constants
        if self.compile_kernel and state["time"].shape[0] <= DENSE_FINISH_BATCH:
            new, outputs, solution = self._finish(c, state, moved, solution, noise, FINISH_ITERATIONS)
            if bool(solution[3].all()):
                return new, outputs
        options = FixedNewtonOptions(
            iterations=FINISH_ITERATIONS, tol=c.tolerance, armijo=c.solver.armijo, max_step=c.solver.max_step
        )
        point, slope, xy, converged, taken = solution
        finished = finish_unconverged(
            point,
            slope,
            xy,
            converged,
            taken,
            surface,
            state["tx_position"],
            state["rx_position"],
            moved["time"],
            c.optics.n_water,
            c.optics.n_air,
            options,
            self.compile_kernel,
        )
        return self._conclude(c, state, moved, finished, noise)
