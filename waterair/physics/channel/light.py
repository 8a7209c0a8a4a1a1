"""The light at the receiver as weighted rays, and what a pointing makes of it (docs/model.md §4.4-§4.5).

Every channel model that sums light from many places (the ray-tube point of a sea without
unresolved slopes, the surface lattice of the two-scale sea, the Monte Carlo tracer's hits) ends in
:class:`LightSamples`: per link, N samples, each with a weight W (its irradiance per unit on-axis
radiant intensity, Fresnel and absorption included, before the angular gains), the direction it
left the transmitter (u1) and the direction it arrives at the receiver (u2). For pointings
(tx_dir, rx_dir) the received gain is

    G = Σ_n W_n G_D(∠(tx_dir, u1_n)) G_A(∠(rx_dir, −u2_n))                                (4.7)

with the paper's angular gains G_D and G_A (§4.1). The upper bound is the largest G over both
pointings (:func:`upper_bound`), and the quadrant detector reads the light's centroid
(:func:`light_centroid`). Units: W and G in 1/m², directions unit ``[..., 3]``.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import torch

from waterair.core.extern import written
from waterair.physics.channel.geometry import Transceiver
from waterair.physics.optics import (
    angle_between,
    arrival_gain,
    arrival_gain_over_cell,
    departure_gain,
    departure_gain_at,
    dot_of_components,
    peak_arrival_gain,
    sin_cos_of_components,
)

UPPER_BOUND_ITERATIONS = 4
"""Alternating ascent steps of :func:`upper_bound` from each of its two starts."""


class LightSamples(NamedTuple):
    """The light reaching each link's receiver as N weighted rays (leading shape ``[B, N]``, :attr:`shape`).

    ``weight`` W (1/m², ≥ 0; padding samples have 0), ``departure`` u1 and ``arrival`` u2 (unit,
    ``[B, N, 3]``: from T toward the surface, from the surface toward R). ``cell``: where the samples are the
    nodes of a lattice, the change of each one's arrival direction across its cell along the lattice's two axes
    ``[B, N, 2, 3]``, over which the receiver's field of view is averaged (docs/model.md §4.3); None where each
    sample is a ray.

    A named tuple, not a tensorclass: a compiled step builds several, and ``torch.compile`` traces a tensorclass's
    construction through tensordict's Python (about 60 ms each), a named tuple's for nothing. :func:`sliced`,
    :func:`repeated` and :func:`joined` do what indexing, ``repeat`` and ``torch.cat`` would.
    """

    weight: torch.Tensor
    departure: torch.Tensor
    arrival: torch.Tensor
    cell: torch.Tensor | None = None

    @property
    def shape(self) -> torch.Size:
        """The leading shape ``[B, N]``: links, samples."""
        return self.weight.shape


class Reception(NamedTuple):
    """What pointings make of the light at each receiver (:func:`receive`), each with leading shape ``[B]``.

    ``gain`` G and ``upper_bound`` G_UB (1/m²); ``valid``: light can reach the receiver (G_UB > 0);
    ``departure`` the best transmitter pointing and ``arrival`` the best arrival direction (the
    receiver's boresight reversed), unit ``[B, 3]``; ``alpha_d``, ``alpha_a`` the pointings' angles
    from them (rad); ``spot_arrival`` the arrival direction the quadrant detector reads ``[B, 3]`` and
    ``lit`` whether it reads any.
    """

    gain: torch.Tensor
    upper_bound: torch.Tensor
    valid: torch.Tensor
    departure: torch.Tensor
    arrival: torch.Tensor
    alpha_d: torch.Tensor
    alpha_a: torch.Tensor
    spot_arrival: torch.Tensor
    lit: torch.Tensor


def receive(
    light: LightSamples,
    tx_dir: torch.Tensor,
    rx_dir: torch.Tensor,
    optics: Transceiver,
    along_path: bool = False,
    bound_light: LightSamples | None = None,
    copies: int = 1,
) -> Reception:
    """Gain, upper bound, best pointing and the quadrant detector's reading for pointings ``[B, 3]``.

    Light from many places: the bound and its pointing by :func:`upper_bound`, the reading the
    light's centroid (:func:`light_centroid`). ``along_path``: the light is one ray along the tracked
    path, as in the paper (docs/model.md §4.1): the best pointing is along it, G_UB = W n_c²/sin² ω_A,
    and the detector reads the ray's arrival wherever it falls within the field of view.
    ``bound_light``: the same light sampled independently of the pointing, the one the bound is searched
    over, where ``light``'s samples were placed for the pointing (the two-scale lattice, docs/model.md §4.3);
    where the pointing received more than the search found, the bound is that gain (G_UB ≥ G always).
    ``copies`` = k: the light the bound is searched over is the same for link i and link i + B / k (k copies
    of the links, pointed differently), so the search runs on the first B / k links and is repeated.
    """
    shares = paper_gains(light, tx_dir, rx_dir, optics) if along_path else pointed_gains(light, tx_dir, rx_dir, optics)
    shares = _apart(shares)
    gain = shares.sum(-1)
    if along_path:
        departure, arrival = light.departure[:, 0], light.arrival[:, 0]
        bound = light.weight[:, 0] * peak_arrival_gain(optics.half_fov, optics.concentrator_index)
        alpha_a = angle_between(rx_dir, -arrival)
        spot_arrival, lit = arrival, arrival_gain(alpha_a, optics.half_fov, optics.concentrator_index) > 0
    else:
        searched = light if bound_light is None else bound_light
        if copies > 1:
            links = searched.weight.shape[0] // copies
            found = upper_bound(sliced(searched, slice(links)), optics.rows(slice(links)))
            bound, departure, boresight = (v.repeat(copies, *(1,) * (v.dim() - 1)) for v in found)
        else:
            bound, departure, boresight = upper_bound(searched, optics)
        if bound_light is not None:  # a second quadrature of the same light: the bound is at least its gain
            bound = torch.maximum(bound, gain)
        arrival = -boresight
        alpha_a = angle_between(rx_dir, boresight)
        spot_arrival, lit = light_centroid(light, shares, rx_dir)
    return Reception(
        gain=gain,
        upper_bound=bound,
        valid=bound > 0,
        departure=departure,
        arrival=arrival,
        alpha_d=angle_between(tx_dir, departure),
        alpha_a=alpha_a,
        spot_arrival=spot_arrival,
        lit=lit,
    )


def pointed_gains(light: LightSamples, tx_dir: torch.Tensor, rx_dir: torch.Tensor, optics: Transceiver) -> torch.Tensor:
    """Each sample's share ``[B, N]`` of eq. (4.7) (1/m²) for pointings tx_dir (up), rx_dir (down) ``[B, 3]``."""
    samples = by_component(light)
    return samples.weight * departure_gains(samples, tx_dir, optics)[1] * arrival_gains(samples, rx_dir, optics)


def paper_gains(light: LightSamples, tx_dir: torch.Tensor, rx_dir: torch.Tensor, optics: Transceiver) -> torch.Tensor:
    """:func:`pointed_gains` as the paper writes G_D and G_A, of the angles α_D and α_A (eqs. (2), (5)), rays alone:
    the paper's one path, bit for bit (:func:`~waterair.physics.channel.single_path.channel_gain`)."""
    g_d = departure_gain(angle_between(tx_dir.unsqueeze(1), light.departure), optics.divergence, optics.wavelength)
    alpha_a = angle_between(rx_dir.unsqueeze(1), -light.arrival)
    return light.weight * g_d * arrival_gain(alpha_a, optics.half_fov, optics.concentrator_index)


Components = tuple[torch.Tensor, torch.Tensor, torch.Tensor]
"""Vectors by component (x, y, z): three tensors, ``[B, N]`` for a field of samples, ``[B, 1]`` for one per link
(``[S, B, 1]`` for S per link, as the bound's ascent's starts)."""


class SamplesByComponent(NamedTuple):
    """A :class:`LightSamples` by component, each a contiguous ``[B, N]`` tensor: the layout the gains and the
    bound's ascent loop over (compiled, the ascent runs 4× faster than over ``[B, N, 3]``; docs/benchmarks.md
    "Channels"). ``incoming`` −u2 (from the receiver toward the surface); ``cells`` each axis's change of u2
    across a node's cell, and ``reach`` its length |du2| (rad: the largest change of the arrival angle across the
    cell, whatever the boresight); both None for rays."""

    weight: torch.Tensor
    departure: Components
    incoming: Components
    cells: tuple[Components, Components] | None
    reach: tuple[torch.Tensor, torch.Tensor] | None


def by_component(light: LightSamples) -> SamplesByComponent:
    """``light`` by component (:class:`SamplesByComponent`)."""
    departure, incoming = _planes(light.departure), _planes(-light.arrival)
    weight = _apart(light.weight)
    if light.cell is None:
        return SamplesByComponent(weight, departure, incoming, None, None)
    reach = torch.linalg.vector_norm(light.cell, dim=-1)
    cells = (_planes(light.cell[:, :, 0]), _planes(light.cell[:, :, 1]))
    return SamplesByComponent(weight, departure, incoming, cells, (reach[..., 0], reach[..., 1]))


def _planes(vectors: torch.Tensor) -> Components:
    """Vectors ``[B, N, 3]`` as three contiguous ``[B, N]`` planes."""
    x, y, z = _apart(vectors.permute(2, 0, 1).contiguous()).unbind(0)
    return x, y, z


def columns(direction: torch.Tensor) -> Components:
    """Directions ``[B, 3]`` (or ``[S, B, 3]``) by component, ``[B, 1]`` (``[S, B, 1]``) each, to broadcast against
    samples ``[B, N]``."""
    return direction[..., 0:1], direction[..., 1:2], direction[..., 2:3]


def departure_gains(samples: SamplesByComponent, tx_dir: torch.Tensor, optics: Transceiver):
    """cos α_D and G_D ``[B, N]`` (``[S, B, N]``) of each sample for the transmitter direction ``tx_dir`` ``[B, 3]``
    (``[S, B, 3]``)."""
    sin_d, cos_d = sin_cos_of_components(columns(tx_dir), samples.departure)
    return cos_d, departure_gain_at(sin_d, cos_d, optics.divergence, optics.wavelength)


def arrival_gains(samples: SamplesByComponent, rx_dir: torch.Tensor, optics: Transceiver) -> torch.Tensor:
    """Each sample's G_A ``[B, N]`` for the receiver boresight ``rx_dir`` ``[B, 3]``: a ray's, or averaged over a
    lattice node's cell where the samples have cells (docs/model.md §4.3, "The field of view's edge")."""
    boresight = columns(rx_dir)
    sin_a, cos_a = sin_cos_of_components(boresight, samples.incoming)
    alpha_a = torch.atan2(sin_a, cos_a)  # the field of view's margin is an angle
    if samples.cells is None or samples.reach is None:
        return arrival_gain(alpha_a, optics.half_fov, optics.concentrator_index, cos_a)
    # dα_A = (boresight · du2) / sin α_A across the cell, no more than |du2| (the angle between unit vectors)
    across = sin_a.clamp(min=1e-12)
    (cell_s, cell_t), (reach_s, reach_t) = samples.cells, samples.reach
    steps = (
        (dot_of_components(boresight, cell_s) / across).clamp(-reach_s, reach_s),
        (dot_of_components(boresight, cell_t) / across).clamp(-reach_t, reach_t),
    )
    return arrival_gain_over_cell(alpha_a, steps, optics.half_fov, optics.concentrator_index, cos_a)


def received_gain(light: LightSamples, tx_dir: torch.Tensor, rx_dir: torch.Tensor, optics: Transceiver) -> torch.Tensor:
    """G of eq. (4.7), ``[B]`` (1/m²)."""
    return pointed_gains(light, tx_dir, rx_dir, optics).sum(-1)


def upper_bound(
    light: LightSamples, optics: Transceiver, iterations: int = UPPER_BOUND_ITERATIONS
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The best received gain over both pointings, and the pointings that give it (docs/model.md §4.5).

    Returns (G_UB ``[B]`` (1/m²), transmitter direction ``[B, 3]`` (up), receiver boresight
    ``[B, 3]`` (down)). Alternating ascent from two starts, the better kept: the transmitter moves
    by a mean-shift step (the G_D-weighted mean of the departures, which climbs a Gaussian beam's
    sum monotonically), the receiver to the weighted mean arrival (which maximises Σ c cos α_A
    exactly while the light stays inside the field of view). Starts: the weighted mean of all
    samples, and the single brightest sample. With one sample it is the paper's
    G_UB = W n_c² / sin² ω_A. docs/model.md §4.5 says how close to a brute-force search it lands.
    """
    samples = by_component(light)
    mean = (
        mean_direction(samples.weight, samples.departure, light.departure[:, 0]),
        mean_direction(samples.weight, samples.incoming, -light.arrival[:, 0]),
    )
    tx, rx = (torch.stack(pair) for pair in zip(mean, brightest(light), strict=True))  # [2, B, 3] each
    gain, tx, rx = _ascend(samples, tx, rx, _per_start(optics), iterations)
    better = (gain[1] > gain[0]).unsqueeze(-1)
    bound = _apart(torch.maximum(gain[0], gain[1]))
    return bound, torch.where(better, tx[1], tx[0]), torch.where(better, rx[1], rx[0])


def sliced(light: LightSamples, rows: slice = slice(None), samples: slice = slice(None)) -> LightSamples:
    """``light[rows, samples]``: the links ``rows`` and the samples ``samples`` of each."""
    return LightSamples(
        weight=light.weight[rows, samples],
        departure=light.departure[rows, samples],
        arrival=light.arrival[rows, samples],
        cell=None if light.cell is None else light.cell[rows, samples],
    )


def repeated(light: LightSamples, copies: int) -> LightSamples:
    """``light`` ``[b, N]`` stacked ``copies`` times along the links, ``[copies · b, N]``."""
    return LightSamples(
        weight=light.weight.repeat(copies, 1),
        departure=light.departure.repeat(copies, 1, 1),
        arrival=light.arrival.repeat(copies, 1, 1),
        cell=None if light.cell is None else light.cell.repeat(copies, 1, 1, 1),
    )


def joined(*lights: LightSamples) -> LightSamples:
    """The samples of ``lights`` (each ``[B, N_i]``) side by side, ``[B, Σ N_i]``; with cells only where every one
    has them."""
    cells = [light.cell for light in lights]
    return LightSamples(
        weight=torch.cat([light.weight for light in lights], dim=1),
        departure=torch.cat([light.departure for light in lights], dim=1),
        arrival=torch.cat([light.arrival for light in lights], dim=1),
        cell=None if any(cell is None for cell in cells) else torch.cat(cells, dim=1),  # type: ignore[arg-type]
    )


def brightest(light: LightSamples) -> tuple[torch.Tensor, torch.Tensor]:
    """The pointings along each link's brightest sample: transmitter direction (up) and receiver boresight
    (down), ``[B, 3]`` each."""
    index = light.weight.argmax(-1, keepdim=True).unsqueeze(-1).expand(-1, 1, 3)
    return light.departure.gather(1, index)[:, 0], -light.arrival.gather(1, index)[:, 0]


def light_centroid(
    light: LightSamples, shares: torch.Tensor, rx_dir: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """The light's centroid on the detector as an arrival direction ``[B, 3]``, and whether any is seen ``[B]``.

    ``shares`` are the samples' contributions to G (:func:`pointed_gains`): only light within the
    field of view and the beam counts. A link with none gets the boresight's reverse (no reading).
    """
    seen = shares.sum(-1) > 0
    return weighted_direction(shares, light.arrival, -rx_dir), seen


def _ascend(samples: SamplesByComponent, tx: torch.Tensor, rx: torch.Tensor, optics: Transceiver, iterations: int):
    """Alternating ascent of eq. (4.7) from each start (tx, rx) ``[S, B, 3]``, all in one batch (half the operations
    of one start after the other, which bound an eager step at one link; ``optics`` :func:`_per_start`); returns
    (gain ``[S, B]``, tx, rx). Each transmitter direction's cosines to the samples and G_D are computed once, for
    the receiver's move after it and the transmitter's next."""
    cos_d, g_d = departure_gains(samples, tx, optics)
    for _ in range(iterations):
        shares = samples.weight * g_d * arrival_gains(samples, rx, optics)
        tx = _apart(mean_direction(shares * cos_d, samples.departure, tx))
        cos_d, g_d = departure_gains(samples, tx, optics)
        rx = _apart(mean_direction(samples.weight * g_d, samples.incoming, rx))
    return (samples.weight * g_d * arrival_gains(samples, rx, optics)).sum(-1), tx, rx  # G (eq. 4.7) at (tx, rx)


def _apart(values: torch.Tensor) -> torch.Tensor:
    """``values`` themselves; inside ``torch.compile`` on a CPU, read first by an extern kernel (:func:`written`),
    where inductor's C++ then splits: the light's planes, each half-step of the ascent, the bound and the pointing's
    shares compile as functions of their own. As one, a graph with a symbolic batch (the evaluation's) compiled
    3× slower (docs/benchmarks.md, "Evaluation"). A GPU's kernels are apart already."""
    if torch.compiler.is_compiling() and values.device.type == "cpu":
        return values + written(values)
    return values


def _per_start(optics: Transceiver) -> Transceiver:
    """``optics`` for pointings ``[S, B, 3]``: a divergence per link ``[B]`` as ``[B, 1]``."""
    if isinstance(optics.divergence, torch.Tensor) and optics.divergence.dim() == 1:
        return dataclasses.replace(optics, divergence=optics.divergence.unsqueeze(-1))
    return optics


def weighted_direction(weights: torch.Tensor, directions: torch.Tensor, fallback: torch.Tensor) -> torch.Tensor:
    """The unit weighted mean of ``directions`` ``[B, N, 3]``, or ``fallback`` ``[B, 3]`` where it vanishes."""
    return _unit_or((weights.unsqueeze(-1) * directions).sum(1), fallback)


def mean_direction(weights: torch.Tensor, directions: Components, fallback: torch.Tensor) -> torch.Tensor:
    """:func:`weighted_direction` of directions by component (``[..., N]`` each), ``[..., 3]``."""
    return _unit_or(torch.stack([(weights * component).sum(-1) for component in directions], -1), fallback)


def _unit_or(total: torch.Tensor, fallback: torch.Tensor) -> torch.Tensor:
    """``total`` ``[..., 3]`` over its length, or ``fallback`` where it vanishes."""
    norm = torch.linalg.vector_norm(total, dim=-1, keepdim=True)
    tiny = torch.finfo(total.dtype).tiny
    return torch.where(norm > math.sqrt(tiny), total / norm.clamp(min=math.sqrt(tiny)), fallback)
