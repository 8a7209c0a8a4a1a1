"""Where the two-scale model stops: ``python -m waterair.bench cutoff``.

The same measured-slope sea resolved to several wavenumber cutoffs k_c (the rest carried as unresolved
slopes, docs/model.md §1.3), the light at the 5 cm aperture estimated by the local estimate
(:class:`waterair.physics.channel.local_estimate.LocalEstimate`) at flat-sea Snell. Per wind and cutoff: the
mean power (with its sea-to-sea standard error, by bootstrap over seas), the scintillation index with the
estimate's own noise taken out (and its 5-95 % bootstrap interval), and the unresolved mean square slope. The
mean must not move with k_c (the same sea); a rise of the scintillation index is what the band's moving
ripples add, which the two-scale channel averages over (docs/model.md §4.8).
"""

from __future__ import annotations

import math
import time

import torch

from waterair.bench.montecarlo import scintillation_index
from waterair.physics import LinkGeometry, Transceiver, WaveSurface, flat_sea_point, sea_state
from waterair.physics.channel import LinkEnds, standard_error
from waterair.physics.channel.local_estimate import LocalEstimate
from waterair.physics.optics import unit_vector

DEFAULT_CUTOFF = 10.0
"""The default sea's k_c (rad/m), whose 48 wavenumber bins set the bins per decade kept at every cutoff."""
RESAMPLES = 400


def bench_cutoff(winds, cutoffs, seas: int, times, rays: int, device: torch.device) -> dict:
    """Rows per (wind, cutoff): 16 directions, the default's wavenumber bins per decade, float64."""
    optics, rows = Transceiver(), []
    tx, rx = (
        v.to(device).expand(seas, 3).contiguous() for v in LinkGeometry(offset_ratio=0.1).positions(torch.float64)
    )
    flat = flat_sea_point(tx, rx, optics.n_water, optics.n_air)
    snell, ends = (unit_vector(flat - tx), unit_vector(flat - rx)), LinkEnds(tx, rx, flat)
    tracer = LocalEstimate(optics, rays=rays, points=1, proposal_beams=0.5)
    for wind in winds:
        for cutoff in cutoffs:
            bins = round(48 * math.log(cutoff / 0.4) / math.log(DEFAULT_CUTOFF / 0.4))
            sea = sea_state(wind=wind, spectrum="elfouhaily", n_dir=16, wavenumber_cutoff=cutoff, n_wavenumbers=bins)
            surface = WaveSurface.sample(sea, seas, seed=31, dtype=torch.float64, device=device)
            generator = torch.Generator(device=device).manual_seed(int(wind * 100 + cutoff))
            started, gains, errors = time.perf_counter(), [], []
            for t in times:
                light = tracer.estimate(surface.harmonics, surface.unresolved, ends, t, generator)
                gain, error = standard_error(light, *snell, optics)
                gains.append(gain.cpu())
                errors.append(error.cpu())
            rows.append({"wind": wind, "cutoff": cutoff, "harmonics": surface.num_harmonics,
                         "unresolved_mss": surface.unresolved[:, [0, 2]].sum(-1).mean().item(),
                         **statistics(torch.stack(gains), torch.stack(errors)),
                         "seconds": time.perf_counter() - started})  # fmt: skip
            print(cutoff_row(rows[-1]), flush=True)
    return {"seas": seas, "times": list(times), "rays": rays, "rows": rows}


def statistics(gains: torch.Tensor, errors: torch.Tensor) -> dict:
    """Mean, its sea-to-sea standard error, and the scintillation index of ``[times, seas]`` gains."""
    generator = torch.Generator().manual_seed(0)
    means, indices = [], []
    for _ in range(RESAMPLES):
        rows = torch.randint(0, gains.shape[1], (gains.shape[1],), generator=generator)
        means.append(gains[:, rows].mean().item())
        indices.append(scintillation_index(gains[:, rows], errors[:, rows]))
    mean, bootstrapped = gains.mean().item(), torch.tensor(indices)
    return {
        "mean": mean,
        "mean_se": torch.tensor(means).std().item() / mean,
        "si": scintillation_index(gains, errors),
        "si_low": bootstrapped.quantile(0.05).item(),
        "si_high": bootstrapped.quantile(0.95).item(),
    }


CUTOFF_HEADER = (
    "| U10 (m/s) | k_c (rad/m) | harmonics | unresolved mss | mean G (1/m²) | scintillation index [5-95 %] |\n"
    "|---|---|---|---|---|---|"
)


def cutoff_row(row: dict) -> str:
    return (
        f"| {row['wind']:g} | {row['cutoff']:g} | {row['harmonics']} | {row['unresolved_mss']:.4f} "
        f"| {row['mean']:.3e} ± {100 * row['mean_se']:.1f} % "
        f"| {row['si']:.3f} [{row['si_low']:.3f}, {row['si_high']:.3f}] |"
    )
