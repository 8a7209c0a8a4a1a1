"""Refraction-point census: ``python -m waterair.bench census`` (see :mod:`waterair.bench`).

For the measured-slope sea at each wind and horizontal offset: how many refraction points one link
has at once within the beam's reach (3 ω_D around the transmitter's axis, both ends pointed along
the calm-sea path), how far apart they lie, and the share of the received power the brightest
carries under the paper's gain model (docs/model.md §4: no lensing) and with each point's ray-tube
factor (§3.4). Float64, multi-start Newton (:func:`waterair.physics.paths.census.refraction_points`).
"""

from __future__ import annotations

import math
import time

import torch

from waterair.physics import LinkGeometry, Transceiver, WaveSurface, flat_sea_point, sea_state
from waterair.physics.channel import ray_tube_factor
from waterair.physics.optics import arrival_gain, departure_gain, fresnel_transmittance, path_gain, unit_vector
from waterair.physics.paths.census import CensusOptions, refraction_points

REACH_DIVERGENCES = 3.0
"""The beam's reach around its axis, in beam divergences ω_D."""


def bench_census(
    winds: list[float], offsets: list[float], cutoffs: list[float], links: int, times: list[float], spacing: float
) -> dict:
    """Census rows for every (cutoff, wind, offset): counts, spread and the brightest point's power share.

    ``spacing`` (m) between Newton starts; 0 picks a quarter of the shortest resolved wavelength
    (at most 8 cm), so that no point lies between starts.
    """
    optics = Transceiver()
    rows = []
    for cutoff in cutoffs:
        for wind in winds:
            sea = sea_state(wind=wind, spectrum="elfouhaily", n_dir=16, wavenumber_cutoff=cutoff)
            step = spacing or min(0.08, 0.25 * 2 * math.pi / float(sea.resolved_cutoff()))
            surface = WaveSurface.sample(sea, links, seed=0, dtype=torch.float64)
            for offset in offsets:
                start = time.perf_counter()
                ends = LinkGeometry(offset_ratio=offset).positions(torch.float64)
                tx, rx = (v.expand(links, 3).contiguous() for v in ends)
                flat = flat_sea_point(tx, rx, optics.n_water, optics.n_air)
                tx_dir, rx_dir = unit_vector(flat - tx), unit_vector(flat - rx)
                counts, spreads, bright, bright_lensed = [], [], [], []
                for t in times:
                    reach = REACH_DIVERGENCES * optics.divergence
                    found = refraction_points(surface, tx, rx, t, tx_dir, reach, options=CensusOptions(spacing=step))
                    gains, lensed = _point_gains(found, tx, rx, tx_dir, rx_dir, optics)
                    counts.append(found.count)
                    spreads.append(_spread(found))
                    bright.append(gains.max(-1).values / gains.sum(-1).clamp(min=1e-300))
                    bright_lensed.append(lensed.max(-1).values / lensed.sum(-1).clamp(min=1e-300))
                count = torch.cat(counts).double()
                spread = torch.cat(spreads)
                many = count > 1
                rows.append(
                    {
                        "cutoff": cutoff,
                        "spacing_m": step,
                        "wind": wind,
                        "offset": offset,
                        "links": int(count.numel()),
                        "mean_points": count.mean().item(),
                        "share_more_than_one": many.double().mean().item(),
                        "max_points": int(count.max().item()),
                        "spread_m": spread[many].mean().item() if bool(many.any()) else 0.0,
                        "brightest_share": torch.cat(bright).mean().item(),
                        "brightest_share_lensed": torch.cat(bright_lensed).mean().item(),
                        "seconds": time.perf_counter() - start,
                    }
                )
                print(census_row(rows[-1]), flush=True)
    return {"times_s": times, "reach_rad": REACH_DIVERGENCES * optics.divergence, "rows": rows}


CENSUS_HEADER = (
    "| k_c (rad/m) | U10 (m/s) | offset | links | points per link | share > 1 | max | spread (m) "
    "| brightest share | with lensing |\n|---|---|---|---|---|---|---|---|---|---|"
)


def census_row(row: dict) -> str:
    return (
        f"| {row['cutoff']:g} | {row['wind']:g} | {row['offset']:.0%} | {row['links']} | {row['mean_points']:.2f} "
        f"| {row['share_more_than_one']:.0%} | {row['max_points']} | {row['spread_m']:.2f} "
        f"| {row['brightest_share']:.3f} | {row['brightest_share_lensed']:.3f} |"
    )


def census_table(record: dict) -> str:
    return "\n".join([CENSUS_HEADER, *(census_row(row) for row in record["rows"])])


def _point_gains(found, tx, rx, tx_dir, rx_dir, optics: Transceiver) -> tuple[torch.Tensor, torch.Tensor]:
    """Each point's gain under the paper's model ``[B, P]`` (1/m²), and with its ray-tube factor instead of G_p."""
    point = found.point
    d1, d2 = point - tx.unsqueeze(1), rx.unsqueeze(1) - point
    r1, r2 = torch.linalg.vector_norm(d1, dim=-1), torch.linalg.vector_norm(d2, dim=-1)
    u1, u2 = d1 / r1.unsqueeze(-1), d2 / r2.unsqueeze(-1)
    alpha_d = torch.acos((u1 * tx_dir.unsqueeze(1)).sum(-1).clamp(-1.0, 1.0))
    alpha_a = torch.acos((-u2 * rx_dir.unsqueeze(1)).sum(-1).clamp(-1.0, 1.0))
    angular = departure_gain(alpha_d, optics.divergence, optics.wavelength) * arrival_gain(
        alpha_a, optics.half_fov, optics.concentrator_index
    )
    transmission = fresnel_transmittance(found.theta1, optics.n_water, optics.n_air)
    paper = angular * transmission * path_gain(r1, r2, optics.attenuation_per_m)
    lensed = angular * ray_tube_factor(point, found.slope, found.hessian, tx.unsqueeze(1), rx.unsqueeze(1), optics)
    zero = torch.zeros_like(paper)
    return torch.where(found.valid, paper, zero), torch.where(found.valid, lensed, zero)


def _spread(found) -> torch.Tensor:
    """The largest distance (m) between two of a link's points, ``[B]`` (0 with one point)."""
    xy = found.point[..., :2]
    distance = torch.linalg.vector_norm(xy.unsqueeze(1) - xy.unsqueeze(2), dim=-1)
    both = found.valid.unsqueeze(1) & found.valid.unsqueeze(2)
    return torch.where(both, distance, torch.zeros_like(distance)).flatten(1).max(-1).values
