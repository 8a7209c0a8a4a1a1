"""The full channel against the Monte Carlo reference: ``python -m waterair.bench montecarlo``.

For the measured-slope sea at each wind: ``seas`` links followed for ``steps`` steps of dt, each
step estimated once by the reference, the local estimate (:class:`waterair.physics.channel.LocalEstimate`,
``reference="local"``) or the hit-counting tracer (:class:`waterair.physics.channel.MonteCarlo`,
``"counting"``), and the samples weighted for three fixed
pointings (straight facing, flat-sea Snell, and pointed at the fast model's brightest sample), and
the fast model's gain (:class:`waterair.physics.channel.TwoScale` around the tracked point) for the
same pointings. Per wind and pointing: mean power ratio (fast / reference) with the
reference's pooled standard error, scintillation index of each, per-step correlation; and the
tracer's speed (surface rays and ray-facet pairs per second) and the comparison's wall time.
"""

from __future__ import annotations

import math
import time

import torch

from waterair.physics import LinkGeometry, Transceiver, WaveSurface, flat_sea_point, sea_state, solve_path
from waterair.physics.channel import (
    LinkEnds,
    LocalEstimate,
    MonteCarlo,
    TwoScale,
    brightest,
    received_gain,
    standard_error,
)
from waterair.physics.optics import unit_vector

DT = 0.05
"""Seconds between steps (the environment's dt)."""
PROPOSAL_BEAMS = {"counting": 2.0, "local": 0.5}
"""The reference's proposal: this many beam widths around the calm-sea departure. The counting tracer needs 2
to cover straight facing; the local estimate is as precise there with the beam's own profile (0.5), and more
precise at the other pointings (its variance comes from the resolved surface, not the proposal: a second
component around the tracked path's departure, tried, did not lower it)."""


def bench_montecarlo(
    winds: list[float],
    seas: int,
    steps: int,
    rays: int,
    facets: int,
    offset: float,
    device: torch.device,
    dtype,
    reference_model: str = "local",
) -> dict:
    """Rows per (wind, pointing), plus the reference's speed per wind (``facets``: the counting tracer's draws)."""
    optics = Transceiver()
    fast_model = TwoScale(optics)
    beams = PROPOSAL_BEAMS[reference_model]
    if reference_model == "local":
        tracer, facets = LocalEstimate(optics, rays=rays, points=1, proposal_beams=beams), 1
    else:
        tracer = MonteCarlo(optics, rays=rays, facets=facets, proposal_beams=beams)
    rows, speeds = [], []
    for wind in winds:
        sea = sea_state(wind=wind, spectrum="elfouhaily", n_dir=16)
        surface = WaveSurface.sample(sea, seas, seed=0, dtype=dtype, device=device)
        tx, rx = (v.to(device).expand(seas, 3).contiguous() for v in LinkGeometry(offset_ratio=offset).positions(dtype))
        flat = flat_sea_point(tx, rx, optics.n_water, optics.n_air)
        snell = unit_vector(flat - tx), unit_vector(flat - rx)
        straight = torch.zeros_like(tx), torch.zeros_like(tx)
        straight[0][:, 2], straight[1][:, 2] = 1.0, -1.0
        ends = LinkEnds(tx, rx, flat)
        prepared = fast_model.prepare(tx, rx, surface.unresolved)
        generator = torch.Generator(device=device).manual_seed(int(wind * 1000))
        fast = {name: [] for name in ("straight", "snell", "brightest")}
        reference = {name: [] for name in fast}
        error = {name: [] for name in fast}
        point, traced_s = None, 0.0
        started = time.perf_counter()
        for step in range(steps):
            t = 10.0 + step * DT
            path = solve_path(surface, tx, rx, t, init=None if point is None else point[:, :2])
            point = path.point
            time_now = torch.full((seas,), t, dtype=dtype, device=device)
            light = fast_model.light(surface.harmonics, path, ends, time_now, prepared)
            clock = time.perf_counter()
            result = tracer.estimate(surface.harmonics, surface.unresolved, ends, t, generator)
            if device.type == "cuda":
                torch.cuda.synchronize()
            traced_s += time.perf_counter() - clock
            pointings = (("straight", straight), ("snell", snell), ("brightest", brightest(light)))
            for name, (tx_dir, rx_dir) in pointings:
                fast[name].append(received_gain(light, tx_dir, rx_dir, optics).double().cpu())
                gain, se = standard_error(result, tx_dir, rx_dir, optics)
                reference[name].append(gain.double().cpu())
                error[name].append(se.double().cpu())
        wall_s = time.perf_counter() - started
        speeds.append(
            {
                "wind": wind,
                "rays_per_s": seas * steps * rays / traced_s,
                "ray_facets_per_s": seas * steps * rays * facets / traced_s,
                "wall_s": wall_s,
            }
        )
        for name in fast:
            f, r, e = (torch.stack(values) for values in (fast[name], reference[name], error[name]))
            rows.append({"wind": wind, "pointing": name, **compare(f, r, e)})
            print(montecarlo_row(rows[-1]), flush=True)
    return {
        "seas": seas,
        "steps": steps,
        "reference": reference_model,
        "rays": rays,
        "facets": facets,
        "offset": offset,
        "dtype": str(dtype).removeprefix("torch."),
        "rows": rows,
        "speed": speeds,
    }


def compare(fast: torch.Tensor, reference: torch.Tensor, error: torch.Tensor) -> dict:
    """Statistics of ``[steps, seas]`` gains: the fast model against the reference with its errors."""
    mean_ref = reference.mean()
    pooled = error.pow(2).sum().sqrt() / reference.numel() / mean_ref
    f, r = fast.flatten(), reference.flatten()
    correlation = torch.corrcoef(torch.stack((f, r)))[0, 1]
    noise = error.pow(2).mean()  # the reference's own variance, taken out of its scintillation index
    return {
        "ratio": (fast.mean() / mean_ref).item(),
        # each step's error relative to the reference's mean, and the reference's own noise in the same units
        "step_error": ((f - r).pow(2).mean().sqrt() / mean_ref).item(),
        "step_se": (error.pow(2).mean().sqrt() / mean_ref).item(),
        "pooled_se": pooled.item(),
        "si_fast": (f.var() / f.mean() ** 2).item(),
        "si_reference": ((r.var() - noise) / r.mean() ** 2).item(),
        "correlation": correlation.item(),
        "noise_ceiling": math.sqrt(max(0.0, 1.0 - (noise / r.var()).item())),
    }


MONTECARLO_HEADER = (
    "| U10 (m/s) | pointing | mean ratio | pooled SE | per-step error (rms) | reference SE (rms) | SI fast "
    "| SI reference | correlation | noise ceiling |\n"
    "|---|---|---|---|---|---|---|---|---|---|"
)


def montecarlo_row(row: dict) -> str:
    return (
        f"| {row['wind']:g} | {row['pointing']} | {row['ratio']:.3f} | {100 * row['pooled_se']:.2f} % "
        f"| {100 * row['step_error']:.2f} % | {100 * row['step_se']:.2f} % "
        f"| {row['si_fast']:.3f} | {row['si_reference']:.3f} | {row['correlation']:.3f} | {row['noise_ceiling']:.3f} |"
    )


def montecarlo_table(record: dict) -> str:
    lines = [MONTECARLO_HEADER, *(montecarlo_row(row) for row in record["rows"])]
    lines.append("")
    lines += [
        f"U10 {s['wind']:g} m/s: {s['rays_per_s']:,.0f} rays/s ({s['ray_facets_per_s']:,.0f} ray-facets/s), "
        f"wall {s['wall_s']:.0f} s"
        for s in record["speed"]
    ]
    return "\n".join(lines)
