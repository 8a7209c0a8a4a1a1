"""Physics benchmark: ``python -m waterair.bench physics`` (see :mod:`waterair.bench`).

Path-solve time per batch (Newton cold and warm start, centroid), surface evaluations per
second, the "sin+cos floor" (one ``sin`` and one ``cos`` over ``[B, K]``) and the ratio of a Newton
solve to (evaluations per solve × floor). Beside the paper's sea, one order-2 evaluation of the
measured-slope sea (``env/spectrum=elfouhaily``, its defaults at the suite's wind) is timed in the same run.
"""

from __future__ import annotations

import torch

from waterair.bench.common import machine, sincos_floor, timed
from waterair.physics import LinkGeometry, SeaState, WaveSurface, sea_state, solve_path

DT = 0.05
"""Time between a cold solve and the warm-started one (s), the environment's step."""


def bench_physics(
    sizes: list[int],
    centroid_sizes: list[int],
    repeats: int,
    device: torch.device,
    dtype: torch.dtype,
    sea: SeaState,
    compiled: bool = False,
) -> dict:
    """Run the physics benchmark and return its JSON-ready record; ``compiled`` uses the compiled kernel."""
    tx, rx = LinkGeometry().positions(dtype, device)

    def solve(t, **kwargs):
        return solve_path(surface, tx, rx, t, compiled=compiled, **kwargs)  # noqa: B023 (the loop's surface)

    ocean = sea_state("elfouhaily", wind=sea.wind, fetch=sea.fetch)  # env/spectrum=elfouhaily at the suite's wind
    harmonics = sea.n_freq * sea.n_dir
    rows = []
    for batch in sizes:
        surface = WaveSurface.sample(sea, batch, seed=0, device=device, dtype=dtype)
        ocean_surface = WaveSurface.sample(ocean, batch, seed=0, device=device, dtype=dtype)
        floor = sincos_floor(batch, harmonics, repeats, device, dtype)
        x = torch.zeros(batch, device=device, dtype=dtype)
        evaluate = timed(lambda: surface.evaluate(x, x, 1.0, order=2, compiled=compiled), repeats, device)  # noqa: B023
        evaluate_ocean = timed(
            lambda: ocean_surface.evaluate(x, x, 1.0, order=2, compiled=compiled),  # noqa: B023
            repeats,
            device,
        )
        cold = solve(1.0)
        start = cold.point[:, :2]
        warm = solve(1.0 + DT, init=start)
        row = {
            "batch": batch,
            "sincos_floor_s": floor,
            "surface_eval_s": evaluate,
            "surface_evals_per_s": batch / evaluate,
            "ocean_eval_s": evaluate_ocean,
            "ocean_to_paper_eval": evaluate_ocean / evaluate,
            "newton_cold_s": timed(lambda: solve(1.0), repeats, device),
            "newton_cold_iterations": cold.iterations.float().mean().item(),
            "newton_cold_valid": cold.valid.float().mean().item(),
            "newton_warm_s": timed(lambda: solve(1.0 + DT, init=start), repeats, device),  # noqa: B023
            "newton_warm_iterations": warm.iterations.float().mean().item(),
            "newton_warm_valid": warm.valid.float().mean().item(),
        }
        # One evaluation per iteration plus the initial one; backtracking adds a few on some rows.
        for start_kind in ("cold", "warm"):
            evaluations = 1.0 + row[f"newton_{start_kind}_iterations"]
            row[f"newton_{start_kind}_floor_ratio"] = row[f"newton_{start_kind}_s"] / (evaluations * floor)
        if batch in centroid_sizes:
            centroid = solve(1.0, method="centroid")
            row["centroid_s"] = timed(lambda: solve(1.0, method="centroid"), 1, device)
            row["centroid_valid"] = centroid.valid.float().mean().item()
            agree = torch.linalg.vector_norm(centroid.point - cold.point, dim=-1) < 0.01
            row["centroid_within_1cm_of_newton"] = agree.float().mean().item()
        rows.append(row)
    return {
        "benchmark": "physics",
        **machine(device, dtype),
        "harmonics": harmonics,
        "ocean_harmonics": ocean.n_wavenumbers * ocean.n_dir,
        "wind": sea.wind,
        "compiled_kernel": compiled,
        "rows": rows,
    }


def physics_table(record: dict) -> str:
    """A Markdown table of a physics record."""
    lines = [
        f"physics benchmark: {record['device_name']}, {record['dtype']}, K = {record['harmonics']} harmonics, "
        f"{record['threads']} threads, {'compiled' if record.get('compiled_kernel') else 'eager'} surface kernel",
        "",
        "| B | sin+cos floor (ms) | surface evals/s | ocean eval / paper eval | Newton cold (ms) | iters | ratio "
        "| Newton warm (ms) | iters | ratio | centroid (s) | centroid ≤ 1 cm |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in record["rows"]:
        centroid = (
            f"{r['centroid_s']:.2f} | {100 * r['centroid_within_1cm_of_newton']:.1f} %"
            if "centroid_s" in r
            else "– | –"
        )
        newton = " | ".join(
            f"{1e3 * r[f'newton_{kind}_s']:.2f} | {r[f'newton_{kind}_iterations']:.2f} "
            f"| {r[f'newton_{kind}_floor_ratio']:.2f}"
            for kind in ("cold", "warm")
        )
        floor = f"{1e3 * r['sincos_floor_s']:.3f} | {r['surface_evals_per_s']:.3g} | {r['ocean_to_paper_eval']:.2f}"
        lines.append(f"| {r['batch']} | {floor} | {newton} | {centroid} |")
    return "\n".join(lines)
