"""The full channel against the Monte Carlo reference: ``python -m waterair.bench montecarlo``.

For the measured-slope sea at each wind: ``seas`` links followed for ``steps`` steps of dt, each
step estimated once by the reference, the local estimate (:class:`waterair.physics.channel.LocalEstimate`,
``reference="local"``) or the hit-counting tracer (:class:`waterair.physics.channel.MonteCarlo`,
``"counting"``), and the samples weighted for three fixed
pointings (straight facing, flat-sea Snell, and pointed at the fast model's brightest sample), and
the fast model's gain (:class:`waterair.physics.channel.TwoScale`, its lattice placed for each pointing)
for the same pointings. Per wind and pointing: mean power ratio (fast / reference) with the
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


POINTINGS = ("straight", "straight_up", "snell", "off", "brightest")
"""Straight facing (both ends vertical), straight up (the transmitter vertical, the receiver at flat-sea Snell),
flat-sea Snell, 0.05 rad beyond it (the transmitter tilted further in the incidence plane) and the bound's."""
OFF_RAD = 0.05


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
    lattices=("",),
) -> dict:
    """Rows per (wind, lattice, pointing), plus the reference's speed per wind (``facets``: the counting
    tracer's draws). ``lattices``: the full channels compared, "nodes:span" ("" the default), with ":bound"
    for the bound's lattice alone (no pointing given to :meth:`TwoScale.light`)."""
    optics = Transceiver()
    fast_models = {lattice: _lattice_model(lattice, optics) for lattice in lattices}
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
        fixed = fixed_pointings(tx, flat, rx)
        ends = LinkEnds(tx, rx, flat)
        prepared = {lattice: model.prepare(tx, rx, surface.unresolved) for lattice, (model, _) in fast_models.items()}
        generator = torch.Generator(device=device).manual_seed(int(wind * 1000))
        fast = {(lattice, name): [] for lattice in fast_models for name in POINTINGS}
        reference = {key: [] for key in fast}
        error = {key: [] for key in fast}
        point, traced_s = None, 0.0
        started = time.perf_counter()
        for step in range(steps):
            t = 10.0 + step * DT
            path = solve_path(surface, tx, rx, t, init=None if point is None else point[:, :2])
            point = path.point
            time_now = torch.full((seas,), t, dtype=dtype, device=device)
            clock = time.perf_counter()
            result = tracer.estimate(surface.harmonics, surface.unresolved, ends, t, generator)
            if device.type == "cuda":
                torch.cuda.synchronize()
            traced_s += time.perf_counter() - clock
            for lattice, (model, pointed) in fast_models.items():
                unpointed = model.light(surface.harmonics, path, ends, time_now, prepared[lattice])
                for name, (tx_dir, rx_dir) in {**fixed, "brightest": brightest(unpointed)}.items():
                    given = ends._replace(pointing=tx_dir) if pointed else ends
                    light = model.light(surface.harmonics, path, given, time_now, prepared[lattice])
                    fast[lattice, name].append(model.receive(light, tx_dir, rx_dir).gain.double().cpu())
                    gain, se = standard_error(result, tx_dir, rx_dir, optics)
                    reference[lattice, name].append(gain.double().cpu())
                    error[lattice, name].append(se.double().cpu())
        wall_s = time.perf_counter() - started
        speeds.append(
            {
                "wind": wind,
                "rays_per_s": seas * steps * rays / traced_s,
                "ray_facets_per_s": seas * steps * rays * facets / traced_s,
                "wall_s": wall_s,
            }
        )
        for lattice, name in fast:
            f, r, e = (torch.stack(values[lattice, name]) for values in (fast, reference, error))
            rows.append({"wind": wind, "lattice": lattice or "default", "pointing": name, **compare(f, r, e)})
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


def fixed_pointings(tx: torch.Tensor, flat: torch.Tensor, rx: torch.Tensor) -> dict:
    """The pointings of :data:`POINTINGS` that do not depend on the light: (tx_dir, rx_dir) each ``[B, 3]``."""
    snell = unit_vector(flat - tx), unit_vector(flat - rx)
    up = torch.zeros_like(tx)
    up[:, 2] = 1.0
    theta = torch.acos(snell[0][:, 2]) + OFF_RAD
    across = unit_vector(torch.cat((snell[0][:, :2], torch.zeros_like(tx[:, :1])), dim=-1))[:, :2]
    off = torch.cat((across * torch.sin(theta).unsqueeze(-1), torch.cos(theta).unsqueeze(-1)), dim=-1)
    return {"straight": (up, -up), "straight_up": (up, snell[1]), "snell": snell, "off": (off, snell[1])}


def _lattice_model(lattice: str, optics: Transceiver) -> tuple[TwoScale, bool]:
    """A "nodes:span[:bound]" spec as (the model, whether its light is given the pointing)."""
    parts = lattice.split(":") if lattice else []
    settings = {}
    if len(parts) >= 2 and parts[0]:
        settings = {"nodes": int(parts[0]), "span": float(parts[1])}
    return TwoScale(optics, **settings), "bound" not in parts


def scintillation_index(gains: torch.Tensor, errors: torch.Tensor) -> float:
    """The scintillation index of estimated ``gains`` with their estimates' own noise (``errors``, their standard
    errors, same shape) taken out of the variance."""
    return ((gains.var() - errors.pow(2).mean()) / gains.mean() ** 2).item()


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
        # the same with the reference's noise taken out (its variance subtracted from the squared error)
        "step_error_corrected": (((f - r).pow(2).mean() - noise).clamp(min=0).sqrt() / mean_ref).item(),
        "pooled_se": pooled.item(),
        "si_fast": (f.var() / f.mean() ** 2).item(),
        "si_reference": scintillation_index(r, error),
        "correlation": correlation.item(),
        "noise_ceiling": math.sqrt(max(0.0, 1.0 - (noise / r.var()).item())),
    }


MONTECARLO_HEADER = (
    "| U10 (m/s) | lattice | pointing | mean ratio | pooled SE | per-step error (rms) | reference SE (rms) "
    "| per-step error, noise out | SI fast | SI reference | correlation | noise ceiling |\n"
    "|---|---|---|---|---|---|---|---|---|---|---|---|"
)


def montecarlo_row(row: dict) -> str:
    return (
        f"| {row['wind']:g} | {row.get('lattice', 'default')} | {row['pointing']} | {row['ratio']:.3f} "
        f"| {100 * row['pooled_se']:.2f} % | {100 * row['step_error']:.2f} % | {100 * row['step_se']:.2f} % "
        f"| {100 * row.get('step_error_corrected', float('nan')):.2f} % "
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
