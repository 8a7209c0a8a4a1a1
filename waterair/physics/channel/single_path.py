"""The paper's channel: one refracted path and a flat-sea power law (docs/model.md §4.1, paper eq. (1)).

    G = G_p(d_water, d_air) · G_ref(θ1) · G_D(α_D) · G_A(α_A)

:class:`SinglePath` is it as a channel model (``env/channel=single_path``, ``+experiment=paper``): one
ray of weight G_p G_ref along the tracked path. Distances in metres, angles in radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from tensordict import TensorClass

from waterair.physics.channel.geometry import LinkGeometry, Transceiver
from waterair.physics.channel.light import LightSamples
from waterair.physics.channel.model import ChannelModel, LinkEnds
from waterair.physics.optics import (
    angle_between,
    arrival_gain,
    departure_gain,
    fresnel_transmittance,
    path_gain,
    peak_arrival_gain,
)
from waterair.physics.paths import PathSolution, flat_sea_point
from waterair.physics.surface import Harmonics


@dataclass(frozen=True)
class SinglePath(ChannelModel):
    """The paper's model: the tracked path's one ray, weighted G_p G_ref; its bound is the paper's G_UB
    and G_0 the paper's calm-sea gain (:func:`calm_sea_gains`)."""

    along_path = True

    def reference_gain(self, tx: torch.Tensor, rx: torch.Tensor) -> torch.Tensor:
        return calm_sea_gains(tx, rx, self.optics)

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
        g_p, g_ref = _path_terms(path, self.optics)
        weight = g_p * g_ref
        return LightSamples(
            weight=weight.unsqueeze(1),
            departure=path.departure.unsqueeze(1),
            arrival=path.arrival.unsqueeze(1),
        )


class ChannelGain(TensorClass):
    """G and its four factors for each batch element (all ``[B]``), plus the pointing errors.

    ``gain`` G (1/m²); ``departure`` G_D, ``path`` G_p (1/m²), ``refraction`` G_ref, ``arrival``
    G_A; ``alpha_d`` α_D and ``alpha_a`` α_A (rad). Invalid paths have every gain 0.
    """

    gain: torch.Tensor
    departure: torch.Tensor
    path: torch.Tensor
    refraction: torch.Tensor
    arrival: torch.Tensor
    alpha_d: torch.Tensor
    alpha_a: torch.Tensor


def channel_gain(path: PathSolution, tx_dir: torch.Tensor, rx_dir: torch.Tensor, optics: Transceiver) -> ChannelGain:
    """Channel gain of ``path`` for the given pointings (docs/model.md §4, paper eq. (1)).

    Args:
        path: the refracted path.
        tx_dir: unit transmitter pointing (upward), ``[B, 3]``.
        rx_dir: unit receiver boresight (downward), ``[B, 3]``.
        optics: transceiver parameters.

    α_D is the angle between ``tx_dir`` and u_d; α_A the angle between ``rx_dir`` and −u_a.
    """
    alpha_d = angle_between(tx_dir, path.departure)
    alpha_a = angle_between(rx_dir, -path.arrival)
    g_d = departure_gain(alpha_d, optics.divergence, optics.wavelength)
    g_a = arrival_gain(alpha_a, optics.half_fov, optics.concentrator_index)
    g_p, g_ref = _path_terms(path, optics)
    gain = g_p * g_ref * g_d * g_a  # the order of eq. (4.7): the path's weight, then the pointing's gains
    return ChannelGain(
        gain=gain,
        departure=g_d,
        path=g_p,
        refraction=g_ref,
        arrival=g_a,
        alpha_d=alpha_d,
        alpha_a=alpha_a,
        batch_size=gain.shape[:1],
    )


def calm_sea_gain(link: LinkGeometry, optics: Transceiver, dtype: torch.dtype = torch.float64) -> float:
    """G_0: the aligned gain on a flat sea for this geometry (1/m²), the intensity reference (docs/model.md §4)."""
    tx, rx = link.positions(dtype)
    return float(calm_sea_gains(tx.unsqueeze(0), rx.unsqueeze(0), optics)[0])


def calm_sea_gains(tx: torch.Tensor, rx: torch.Tensor, optics: Transceiver) -> torch.Tensor:
    """G_0 for a batch of geometries, ``tx``/``rx`` ``[B, 3]`` (m) → ``[B]`` (1/m²)."""
    point = flat_sea_point(tx, rx, optics.n_water, optics.n_air)
    d_water = torch.linalg.vector_norm(point - tx, dim=-1)
    d_air = torch.linalg.vector_norm(rx - point, dim=-1)
    theta1 = torch.acos(((point - tx)[:, 2] / d_water).clamp(-1.0, 1.0))
    g_p = path_gain(d_water, d_air, optics.attenuation_per_m)
    g_ref = fresnel_transmittance(theta1, optics.n_water, optics.n_air)
    return g_p * g_ref * peak_arrival_gain(optics.half_fov, optics.concentrator_index)


def _path_terms(path: PathSolution, optics: Transceiver) -> tuple[torch.Tensor, torch.Tensor]:
    """G_p and G_ref of a path, zero where the path is invalid."""
    g_p = path_gain(path.d_water, path.d_air, optics.attenuation_per_m)
    g_ref = fresnel_transmittance(path.theta1, optics.n_water, optics.n_air)
    zero = torch.zeros_like(g_p)
    return torch.where(path.valid, g_p, zero), torch.where(path.valid, g_ref, zero)
