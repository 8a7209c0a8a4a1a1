"""Which channel model the step uses, and what a pointing measures through it (docs/environment.md, "Channel").

``env.channel`` selects a model of :mod:`waterair.physics.channel` (the env holds no optics of its own):

* ``single_path``: the paper's model, one refracted path (bit for bit as the first release);
* ``full``: the light of every refraction point with its lensing, the unresolved slopes' spread and
  the aperture: the two-scale surface lattice on a sea with unresolved slopes, the aperture-bounded
  ray tube of the tracked point on a sea without (the paper's);
* ``montecarlo``: the Monte Carlo tracer, for evaluation (slow; eager, the GPU when present).

For ``full`` and ``montecarlo`` the light is a set of weighted rays; the pointing's gain, the upper
bound (the best pointing), the misalignment from it and the quadrant detector's reading (the centroid
of the light on it) all follow from those rays. Pure tensor functions, so that the step compiles.
"""

from __future__ import annotations

import torch

from waterair.physics.channel import (
    LightSamples,
    channel_gain,
    gain_upper_bound,
    hessian_eigenvectors,
    light_centroid,
    pointed_gains,
    ray_tube_light,
    two_scale_light,
    upper_bound,
)
from waterair.physics.channel.geometry import Transceiver
from waterair.physics.optics import angle_between
from waterair.physics.paths import PathSolution
from waterair.physics.paths.newton import fermat_terms
from waterair.physics.surface import directional_third_derivatives


def light(
    optics: Transceiver,
    two_scale: bool,
    nodes: int,
    span: float,
    components: tuple[torch.Tensor, ...],
    tx: torch.Tensor,
    rx: torch.Tensor,
    time: torch.Tensor,
    path: PathSolution,
    centre: torch.Tensor,
    basis: torch.Tensor,
    blur: torch.Tensor,
) -> LightSamples:
    """The full channel's light at each receiver (``[B, N]`` rays).

    Two-scale sea: the lattice of eq. (4.8) around ``centre`` (the tracked point, ``[B, 2]`` m)
    with the link's ``basis`` and ``blur`` (:func:`~waterair.physics.channel.lattice_shape`). A sea
    without unresolved slopes: the ray tube of the tracked ``path`` (eq. 4.4), bounded at caustics
    by the aperture through the surface's third derivatives along the Hessian's axes.
    """
    if two_scale:
        return two_scale_light(components, tx, rx, time, centre, basis, blur, optics, nodes, span)
    _, _, hessian, _, _ = fermat_terms(*components, path.point[:, :2], time, tx, rx, optics.n_water, optics.n_air)
    axes = hessian_eigenvectors(hessian)
    third = directional_third_derivatives(*components, path.point[:, :2], time, axes)
    return ray_tube_light(
        path.point, -path.normal[:, :2] / path.normal[:, 2:], hessian, path.valid, tx, rx, optics, third
    )


def measure(
    optics: Transceiver,
    path: PathSolution,
    light_samples: LightSamples | None,
    tx_dir: torch.Tensor,
    rx_dir: torch.Tensor,
) -> tuple[dict[str, torch.Tensor], torch.Tensor, torch.Tensor]:
    """What the step reports for pointings ``tx_dir`` (up) and ``rx_dir`` (down) ``[B, 3]``.

    Returns (the measurement: gain, gain_upper_bound, path_valid, alpha_d, alpha_a, departure,
    arrival; the arriving direction the quadrant detector reads ``[B, 3]``; whether it sees light ``[B]``).
    ``light_samples`` None: the paper's single path (its departure and arrival are the path's, α
    the angles from them). Otherwise departure and arrival are the best pointing's (the upper
    bound's), α the angles from it, and a path is "valid" when any light can reach the receiver.
    """
    if light_samples is None:
        gain = channel_gain(path, tx_dir, rx_dir, optics)
        measurement = {
            "gain": gain.gain,
            "gain_upper_bound": gain_upper_bound(path, optics),
            "path_valid": path.valid,
            "alpha_d": gain.alpha_d,
            "alpha_a": gain.alpha_a,
            "departure": path.departure,
            "arrival": path.arrival,
        }
        return measurement, path.arrival, gain.arrival > 0
    shares = pointed_gains(light_samples, tx_dir, rx_dir, optics)
    bound, best_tx, best_rx = upper_bound(light_samples, optics)
    seen_arrival, lit = light_centroid(light_samples, shares, rx_dir)
    measurement = {
        "gain": shares.sum(-1),
        "gain_upper_bound": bound,
        "path_valid": bound > 0,
        "alpha_d": angle_between(tx_dir, best_tx),
        "alpha_a": angle_between(rx_dir, best_rx),
        "departure": best_tx,
        "arrival": -best_rx,
    }
    return measurement, seen_arrival, lit
