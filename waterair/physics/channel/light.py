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

import math
from typing import NamedTuple

import torch
from tensordict import TensorClass

from waterair.physics.channel.geometry import Transceiver
from waterair.physics.optics import (
    angle_between,
    arrival_gain,
    arrival_gain_over_cell,
    departure_gain,
    departure_gain_at,
    peak_arrival_gain,
    sin_cos_between,
)

UPPER_BOUND_ITERATIONS = 4
"""Alternating ascent steps of :func:`upper_bound` from each of its two starts."""


class LightSamples(TensorClass):
    """The light reaching each link's receiver as N weighted rays (leading shape ``[B, N]``).

    ``weight`` W (1/m², ≥ 0; padding samples have 0), ``departure`` u1 and ``arrival`` u2 (unit,
    ``[B, N, 3]``: from T toward the surface, from the surface toward R). ``cell``: where the samples are the
    nodes of a lattice, the change of each one's arrival direction across its cell along the lattice's two axes
    ``[B, N, 2, 3]``, over which the receiver's field of view is averaged (docs/model.md §4.3); None where each
    sample is a ray.
    """

    weight: torch.Tensor
    departure: torch.Tensor
    arrival: torch.Tensor
    cell: torch.Tensor | None = None


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
    sin_d, cos_d = sin_cos_between(tx_dir.unsqueeze(1), light.departure)
    g_d = departure_gain_at(sin_d, cos_d, optics.divergence, optics.wavelength)
    return light.weight * g_d * arrival_gains(light, rx_dir, optics)


def paper_gains(light: LightSamples, tx_dir: torch.Tensor, rx_dir: torch.Tensor, optics: Transceiver) -> torch.Tensor:
    """:func:`pointed_gains` as the paper writes G_D and G_A, of the angles α_D and α_A (eqs. (2), (5)), rays alone:
    the paper's one path, bit for bit (:func:`~waterair.physics.channel.single_path.channel_gain`)."""
    g_d = departure_gain(angle_between(tx_dir.unsqueeze(1), light.departure), optics.divergence, optics.wavelength)
    alpha_a = angle_between(rx_dir.unsqueeze(1), -light.arrival)
    return light.weight * g_d * arrival_gain(alpha_a, optics.half_fov, optics.concentrator_index)


def arrival_gains(
    light: LightSamples, rx_dir: torch.Tensor, optics: Transceiver, reach: torch.Tensor | None = None
) -> torch.Tensor:
    """Each sample's G_A ``[B, N]`` for the receiver boresight ``rx_dir`` ``[B, 3]``: a ray's, or averaged over a
    lattice node's cell where ``light.cell`` is given (docs/model.md §4.3, "The field of view's edge"). ``reach``:
    :func:`cell_reach` of ``light.cell``, where the caller evaluates many boresights on one light."""
    boresight = rx_dir.unsqueeze(1)
    sin_a, cos_a = sin_cos_between(boresight, -light.arrival)
    alpha_a = torch.atan2(sin_a, cos_a)  # the field of view's margin is an angle
    if light.cell is None:
        return arrival_gain(alpha_a, optics.half_fov, optics.concentrator_index, cos_a)
    # dα_A = (boresight · du2) / sin α_A across the cell, no more than |du2| (the angle between unit vectors)
    change = (boresight.unsqueeze(-2) * light.cell).sum(-1)
    largest = cell_reach(light.cell) if reach is None else reach
    steps = (change / sin_a.unsqueeze(-1).clamp(min=1e-12)).clamp(-largest, largest)
    return arrival_gain_over_cell(alpha_a, steps, optics.half_fov, optics.concentrator_index, cos_a)


def cell_reach(cell: torch.Tensor) -> torch.Tensor:
    """The largest change of each sample's arrival angle across its ``cell`` (:class:`LightSamples`) along each
    axis, |du2| ``[B, N, 2]`` (rad), whatever the boresight."""
    return torch.linalg.vector_norm(cell, dim=-1)


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
    weight = light.weight
    mean = (
        weighted_direction(weight, light.departure, light.departure[:, 0]),
        weighted_direction(weight, -light.arrival, -light.arrival[:, 0]),
    )
    reach = None if light.cell is None else cell_reach(light.cell)
    results = [_ascend(light, tx, rx, optics, iterations, reach) for tx, rx in (mean, brightest(light))]
    (gain_a, tx_a, rx_a), (gain_b, tx_b, rx_b) = results
    better = (gain_b > gain_a).unsqueeze(-1)
    return torch.maximum(gain_a, gain_b), torch.where(better, tx_b, tx_a), torch.where(better, rx_b, rx_a)


def sliced(light: LightSamples, rows: slice = slice(None), samples: slice = slice(None)) -> LightSamples:
    """``light[rows, samples]``, sliced field by field: a compiled step's batch size stays symbolic (the
    tensorclass's own slicing evaluates it, so torch would compile a graph per batch size)."""
    weight = light.weight[rows, samples]
    return LightSamples(
        weight=weight,
        departure=light.departure[rows, samples],
        arrival=light.arrival[rows, samples],
        cell=None if light.cell is None else light.cell[rows, samples],
        batch_size=weight.shape,
    )


def repeated(light: LightSamples, copies: int) -> LightSamples:
    """``light`` ``[b, N]`` stacked ``copies`` times along the links, ``[copies · b, N]``."""
    weight = light.weight.repeat(copies, 1)
    return LightSamples(
        weight=weight,
        departure=light.departure.repeat(copies, 1, 1),
        arrival=light.arrival.repeat(copies, 1, 1),
        cell=None if light.cell is None else light.cell.repeat(copies, 1, 1, 1),
        batch_size=weight.shape,
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


def _ascend(
    light: LightSamples,
    tx: torch.Tensor,
    rx: torch.Tensor,
    optics: Transceiver,
    iterations: int,
    reach: torch.Tensor | None = None,
):
    """Alternating ascent of eq. (4.7) from (tx, rx); returns (gain, tx, rx). Each transmitter direction's cosines
    to the samples and G_D are computed once, for the receiver's move after it and the transmitter's next; the
    cells' :func:`cell_reach` once for all (``reach``)."""

    def departures(tx: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:  # cos α_D and G_D
        sin_d, cos_d = sin_cos_between(tx.unsqueeze(1), light.departure)
        return cos_d, departure_gain_at(sin_d, cos_d, optics.divergence, optics.wavelength)

    def shares(g_d: torch.Tensor, rx: torch.Tensor) -> torch.Tensor:  # as pointed_gains, with G_D already known
        return light.weight * g_d * arrival_gains(light, rx, optics, reach)

    cos_d, g_d = departures(tx)
    for _ in range(iterations):
        tx = weighted_direction(shares(g_d, rx) * cos_d, light.departure, tx)
        cos_d, g_d = departures(tx)
        rx = weighted_direction(light.weight * g_d, -light.arrival, rx)
    return shares(g_d, rx).sum(-1), tx, rx  # G (eq. 4.7) at (tx, rx)


def weighted_direction(weights: torch.Tensor, directions: torch.Tensor, fallback: torch.Tensor) -> torch.Tensor:
    """The unit weighted mean of ``directions`` ``[B, N, 3]``, or ``fallback`` ``[B, 3]`` where it vanishes."""
    total = (weights.unsqueeze(-1) * directions).sum(1)
    norm = torch.linalg.vector_norm(total, dim=-1, keepdim=True)
    tiny = torch.finfo(total.dtype).tiny
    return torch.where(norm > math.sqrt(tiny), total / norm.clamp(min=math.sqrt(tiny)), fallback)
