"""What every channel model is: an object that turns a sea, a tracked path and the link's ends into
light at the receiver (docs/model.md §4.7, "Adding a channel model").

A model is a frozen dataclass holding the transceiver and its own settings, and it answers four
questions:

* :meth:`~ChannelModel.reference_gain`: G_0, the aligned gain on a calm sea, the intensity reference;
* :meth:`~ChannelModel.prepare`: per-link constants of an episode (the two-scale lattice's shape, the
  unresolved slopes the Monte Carlo tracer draws facets from), computed once at each reset;
* :meth:`~ChannelModel.light`: the light reaching each receiver as :class:`LightSamples`;
* :meth:`~ChannelModel.receive`: what pointings make of that light (gain, bound, best pointing, the
  quadrant detector's reading), the same code for every model (:func:`~.light.receive`).

Two flags tell the environment how to call it: ``needs_exact_point`` (the step must converge the
tracked refraction point, or only follow it near the calm-sea point) and ``compiles`` (its light can
be computed inside the step's compiled graph). Units: m, s, rad; gains in 1/m².
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar, NamedTuple

import torch

from waterair.physics.channel.geometry import Transceiver
from waterair.physics.channel.light import LightSamples, Reception, receive
from waterair.physics.paths import PathSolution
from waterair.physics.surface import Harmonics


class NoConstants(NamedTuple):
    """What :meth:`ChannelModel.prepare` gives a model without per-episode constants: nothing."""


class LinkEnds(NamedTuple):
    """Where each link's ends are: ``tx`` T and ``rx`` R, and the calm-sea refraction point between them,
    each ``[B, 3]`` (m); and, where it is known, the transmitter's ``pointing`` (unit, up, ``[B, 3]``), for
    a model that places its samples where the beam goes (the two-scale lattice)."""

    tx: torch.Tensor
    rx: torch.Tensor
    calm_point: torch.Tensor
    pointing: torch.Tensor | None = None


@dataclass(frozen=True)
class ChannelModel:
    """The interface every channel model implements (see the module docstring); ``optics`` are the ends'."""

    optics: Transceiver = field(default_factory=Transceiver)

    needs_exact_point: ClassVar[bool] = True
    """Whether :meth:`light` needs the tracked refraction point converged (else it is followed where near)."""
    compiles: ClassVar[bool] = True
    """Whether :meth:`light` is a pure tensor function that compiles into the step's graph."""
    along_path: ClassVar[bool] = False
    """Whether the light is the tracked path's one ray, read as the paper reads it (:func:`.light.receive`)."""
    Prepared: ClassVar[type[tuple]] = NoConstants
    """The named tuple :meth:`prepare` returns (its fields the constants' names)."""

    def reference_gain(self, tx: torch.Tensor, rx: torch.Tensor) -> torch.Tensor:
        """G_0 ``[B]`` (1/m²) for ends ``tx``, ``rx`` ``[B, 3]`` (m): both ends aligned on a calm sea."""
        raise NotImplementedError

    def prepare(self, tx: torch.Tensor, rx: torch.Tensor, unresolved: torch.Tensor) -> tuple:
        """Per-link constants of an episode (a :attr:`Prepared`), each ``[B, ...]`` in ``tx``'s dtype, from the
        ends ``[B, 3]`` (m) and the sea's unresolved slope covariance ``[B, 3]``; none by default."""
        return NoConstants()

    def light(
        self,
        sea: Harmonics,
        path: PathSolution,
        ends: LinkEnds,
        time: torch.Tensor,
        prepared: tuple,
        generator: torch.Generator | None = None,
        copies: int = 1,
    ) -> LightSamples:
        """The light at each receiver ``[B, N]`` for the resolved ``sea`` at ``time`` ``[B]`` (s), the tracked
        ``path``, the ``ends`` and what :meth:`prepare` gave; ``generator`` for a model that draws.

        ``copies`` = k says that the batch is k copies of B / k links, link i the same as link i + B / k in
        everything but the pointing (an evaluation's policies side by side on the same seas): a model may
        compute what does not depend on the pointing once per link (the two-scale lattice does)."""
        raise NotImplementedError

    def unpointed_light(self, light: LightSamples) -> LightSamples:
        """The samples of :meth:`light` placed whatever the transmitter points at (all of them, unless a model
        also places samples where the beam goes): what the beacon's reading reverses (:mod:`.beacon`), since
        the beacon's light reaches the transmitter wherever its laser points."""
        return light

    def receive(self, light: LightSamples, tx_dir: torch.Tensor, rx_dir: torch.Tensor, copies: int = 1) -> Reception:
        """What pointings ``tx_dir`` (up) and ``rx_dir`` (down) ``[B, 3]`` receive of ``light`` (``copies`` as in
        :meth:`light`)."""
        return receive(light, tx_dir, rx_dir, self.optics, along_path=self.along_path)
