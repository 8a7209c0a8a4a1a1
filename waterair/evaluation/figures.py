"""Physics figures of the paper: the JONSWAP spectrum (Fig. 2) and a wave-surface snapshot (Fig. 3); on the
measured-slope sea its own wavenumber spectrum, resolved band and cutoff, and its snapshot.

python -m waterair.evaluation.figures --out outputs/figures [--wind 12 --fetch 2e4 --seed 0]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import torch  # noqa: E402

from waterair.physics.sea import ElfouhailySea, JonswapSea, SeaState, spreading  # noqa: E402
from waterair.physics.surface import WaveSurface  # noqa: E402

POINTS_PER_CHUNK = 2048
"""Surface points evaluated at once when drawing a snapshot (bounds memory at P × K floats)."""
SURFACE_TILES = 50
"""At most this many tiles along each side of a 3-D surface (matplotlib's default)."""


def even_strides(rows: int, cols: int, tiles: int = SURFACE_TILES) -> tuple[int, int]:
    """``plot_surface``'s row and column strides: the smallest giving at most ``tiles`` tiles a side whose tiles are
    all of one size. A last tile smaller than the others has fewer vertices, and matplotlib pads the ragged polygons
    with uninitialised memory that it projects before masking: a nondeterministic "overflow encountered in dot". With
    ``n − 1`` intervals divisible by 3 (121 points) the stride is 3, 40 tiles."""
    strides = []
    for n in (rows, cols):
        stride = max(math.ceil(n / tiles), 1)
        while (n - 1) % stride:
            stride += 1
        strides.append(stride)
    return strides[0], strides[1]


def plot_spectrum(sea: JonswapSea, path: Path) -> Path:
    """S(ω) against ω with the peak ω_p and the simulated band marked (paper Fig. 2a)."""
    omega = torch.linspace(0.05, 4.0 * sea.omega_p, 800, dtype=torch.float64)
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(omega, sea.frequency_spectrum(omega), color="tab:blue", label="JONSWAP S(ω)")
    ax.axvline(sea.omega_p, color="tab:red", linestyle="--", label=f"ω_p = {sea.omega_p:.2f} rad/s")
    low, high = sea.omega_band
    ax.axvspan(low, min(high, float(omega[-1])), color="tab:gray", alpha=0.12, label="simulated band")
    ax.set_xlabel("angular frequency ω (rad/s)")
    ax.set_ylabel("S(ω) (m²·s/rad)")
    ax.set_title(
        f"JONSWAP spectrum, U10 = {sea.wind:g} m/s, fetch = {sea.fetch:g} m\n"
        f"Hs = {sea.significant_wave_height:.2f} m, Tp = {2 * math.pi / sea.omega_p:.2f} s"
    )
    ax.legend()
    ax.grid(alpha=0.3)
    return _save(fig, path)


def plot_directional_spectrum(sea: JonswapSea, path: Path) -> Path:
    """S(ω, θ) = S(ω) G(ω, θ) as a 3-D surface (paper Fig. 2b)."""
    omega = torch.linspace(0.3 * sea.omega_p, 3.0 * sea.omega_p, 121, dtype=torch.float64)
    theta = torch.linspace(-math.pi / 2, math.pi / 2, 91, dtype=torch.float64)
    w, th = torch.meshgrid(omega, theta, indexing="ij")
    values = sea.frequency_spectrum(w) * spreading(w, th, sea.omega_p)
    fig = plt.figure(figsize=(7, 5))
    ax = fig.add_subplot(projection="3d")
    rstride, cstride = even_strides(*w.shape)
    ax.plot_surface(w.numpy(), torch.rad2deg(th).numpy(), values.numpy(), cmap="viridis", linewidth=0,
                    rstride=rstride, cstride=cstride)  # fmt: skip
    ax.set_xlabel("ω (rad/s)")
    ax.set_ylabel("θ from wind (deg)")
    ax.set_zlabel("S(ω, θ) (m²·s/rad²)")
    ax.set_title(f"Directional JONSWAP spectrum, U10 = {sea.wind:g} m/s, fetch = {sea.fetch:g} m")
    return _save(fig, path)


def plot_wavenumber_spectrum(sea: ElfouhailySea, path: Path) -> Path:
    """The measured-slope sea's S(k) and its slope spectrum k² S(k), with the resolved band and the cutoff
    beyond which the waves are unresolved slopes (docs/model.md §1.2-§1.3)."""
    edges = sea.wavenumber_bins(torch.float64)
    cutoff = float(sea.resolved_cutoff())
    k = torch.logspace(math.log10(float(edges[0]) / 2), math.log10(max(cutoff * 100, 1e3)), 800, dtype=torch.float64)
    spectrum = sea.wavenumber_spectrum(k)
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    top.loglog(k, spectrum, color="tab:blue", label="Elfouhaily S(k)")
    bottom.loglog(k, k**2 * spectrum, color="tab:green", label="slope spectrum k² S(k)")
    for ax in (top, bottom):
        ax.axvspan(float(edges[0]), cutoff, color="tab:gray", alpha=0.12, label="resolved harmonics")
        ax.axvline(cutoff, color="tab:red", linestyle="--", label=f"cutoff k_c = {cutoff:.3g} rad/m")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8)
        ax.set_ylim(bottom=float(ax.get_lines()[0].get_ydata().max()) * 1e-9)  # the peak's low side falls steeply
    top.set_ylabel("S(k) (m³/rad)")
    bottom.set_ylabel("k² S(k) (m/rad)")
    bottom.set_xlabel("wavenumber k (rad/m)")
    slopes = sea.mean_square_slope()
    top.set_title(
        f"Measured-slope sea, U10 = {sea.wind:g} m/s, fetch {sea.fetch:g} m, Hs {sea.significant_wave_height:.2f} m\n"
        f"mean square slope {slopes.total:.4f}: {slopes.resolved:.4f} resolved, {slopes.unresolved:.4f} beyond k_c"
    )
    return _save(fig, path)


def plot_surface_snapshot(
    sea: SeaState, path: Path, *, extent: float = 60.0, resolution: int = 121, seed: int = 0
) -> Path:
    """One realisation η(x, y, 0) over an ``extent`` × ``extent`` m square (paper Fig. 3)."""
    surface = WaveSurface.sample(sea, 1, seed=seed)
    axis = torch.linspace(-extent / 2, extent / 2, resolution)
    x, y = torch.meshgrid(axis, axis, indexing="xy")
    flat_x, flat_y = x.reshape(1, -1), y.reshape(1, -1)
    heights = [
        surface.height(flat_x[:, i : i + POINTS_PER_CHUNK], flat_y[:, i : i + POINTS_PER_CHUNK], 0.0)
        for i in range(0, flat_x.shape[1], POINTS_PER_CHUNK)
    ]
    eta = torch.cat(heights, dim=1).reshape(resolution, resolution)
    fig = plt.figure(figsize=(7, 5))
    ax = fig.add_subplot(projection="3d")
    rstride, cstride = even_strides(resolution, resolution)
    plot = ax.plot_surface(x.numpy(), y.numpy(), eta.numpy(), cmap="viridis", linewidth=0, antialiased=False,
                           rstride=rstride, cstride=cstride)  # fmt: skip
    ax.set_zlim(-4 * math.sqrt(sea.m0()), 4 * math.sqrt(sea.m0()))
    ax.set_xlabel("x, downwind (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("η (m)")
    ax.set_title(f"Wave surface at t = 0, U10 = {sea.wind:g} m/s ({sea.n_bins}×{sea.n_dir} harmonics)")
    fig.colorbar(plot, ax=ax, shrink=0.6, pad=0.12, label="η (m)")
    return _save(fig, path)


def physics_figures(out: Path, sea: SeaState | None = None, seed: int = 0) -> list[Path]:
    """Write the physics figures of ``sea`` (default: the paper's) into ``out`` and return their paths."""
    sea = sea or JonswapSea()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if isinstance(sea, JonswapSea):
        spectra = [
            plot_spectrum(sea, out / "jonswap_spectrum.png"),
            plot_directional_spectrum(sea, out / "jonswap_directional.png"),
        ]
    elif isinstance(sea, ElfouhailySea):
        spectra = [plot_wavenumber_spectrum(sea, out / "elfouhaily_spectrum.png")]
    else:
        raise TypeError(f"no spectrum figure for {type(sea).__name__}")
    return [*spectra, plot_surface_snapshot(sea, out / "wave_surface.png", seed=seed)]


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("outputs/figures"), help="output folder")
    parser.add_argument("--wind", type=float, default=12.0, help="wind speed U10 (m/s)")
    parser.add_argument("--fetch", type=float, default=2.0e4, help="fetch (m)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the surface snapshot")
    args = parser.parse_args(argv)
    try:
        sea = JonswapSea(wind=args.wind, fetch=args.fetch)
    except ValueError as error:
        parser.exit(2, f"error: {error}\n")
    for path in physics_figures(args.out, sea, args.seed):
        print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
