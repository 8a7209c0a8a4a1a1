"""Refracted path solvers (docs/model.md §3)."""

import math

import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from waterair.physics.channel import LinkGeometry
from waterair.physics.optics import RefractiveIndices
from waterair.physics.paths import CentroidOptions, FixedNewtonOptions, NewtonOptions, solve_path
from waterair.physics.sea import sea_state
from waterair.physics.surface import WaveSurface

N_W, N_A = 1.33, 1.0


def snell_bisection(depth: float, height: float, distance: float) -> float:
    """Horizontal distance from T to the flat-sea refraction point, by bisection in float64 math."""
    low, high = 0.0, distance
    for _ in range(200):
        s = 0.5 * (low + high)
        residual = N_W * s / math.hypot(s, depth) - N_A * (distance - s) / math.hypot(distance - s, height)
        low, high = (low, s) if residual > 0 else (s, high)
    return 0.5 * (low + high)


def snell_residual(path) -> torch.Tensor:
    """|n_w (u_d × n̂) − n_a (u_a × n̂)| per element."""
    cross_d = torch.linalg.cross(path.departure, path.normal, dim=-1)
    cross_a = torch.linalg.cross(path.arrival, path.normal, dim=-1)
    return torch.linalg.vector_norm(N_W * cross_d - N_A * cross_a, dim=-1)


@pytest.mark.parametrize("method,compiled", [("newton", False), ("newton_fixed", False)])
@pytest.mark.parametrize("offset_ratio,azimuth", [(0.0, 0.0), (0.1, 0.0), (0.3, 120.0), (1.0, -45.0)])
def test_flat_sea_newton_matches_bisection(offset_ratio, azimuth, method, compiled):
    link = LinkGeometry(tx_depth=8.0, rx_height=12.0, offset_ratio=offset_ratio, offset_azimuth_deg=azimuth)
    tx, rx = link.positions(torch.float64)
    surface = WaveSurface.sample(sea_state("jonswap", flat=True), 4, seed=0, dtype=torch.float64)
    # start away from the answer so that Newton has work to do
    init = torch.tensor([[3.0, -2.0]], dtype=torch.float64).expand(4, 2)
    path = solve_path(surface, tx, rx, 0.0, method=method, init=init, compiled=compiled)
    assert path.valid.all()
    s = snell_bisection(8.0, 12.0, link.horizontal_offset)
    phi = math.radians(azimuth)
    expected = torch.tensor([s * math.cos(phi), s * math.sin(phi), 0.0], dtype=torch.float64)
    torch.testing.assert_close(path.point, expected.expand(4, 3), atol=1e-9, rtol=0)
    sines = N_W * torch.sin(path.theta1) - N_A * torch.sin(path.theta2)
    assert sines.abs().max().item() < 1e-9


@pytest.mark.parametrize("dtype,bound", [(torch.float64, 1e-9), (torch.float32, 1e-4)])
def test_wavy_sea_paths_obey_snell_and_connect_the_ends(dtype, bound, default_positions):
    tx, rx = default_positions
    surface = WaveSurface.sample(sea_state("jonswap", wind=12.0), 4096, seed=3, dtype=dtype)
    path = solve_path(surface, tx.to(dtype), rx.to(dtype), 4.0)
    valid = path.valid
    assert valid.float().mean().item() >= 0.99
    assert snell_residual(path)[valid].max().item() < bound
    # P lies on the surface, and T + d_water u_d = P, P + d_air u_a = R.
    height = surface.height(path.point[:, 0], path.point[:, 1], 4.0)
    assert (height - path.point[:, 2])[valid].abs().max().item() < 10 * bound
    reach_p = tx.to(dtype) + path.d_water.unsqueeze(-1) * path.departure
    reach_r = path.point + path.d_air.unsqueeze(-1) * path.arrival
    assert (reach_p - path.point)[valid].abs().max().item() < 1e3 * bound
    assert (reach_r - rx.to(dtype))[valid].abs().max().item() < 1e3 * bound


def test_float32_and_float64_find_the_same_point(default_positions):
    tx, rx = default_positions
    sea = sea_state("jonswap", wind=12.0)
    p64 = solve_path(WaveSurface.sample(sea, 512, seed=9, dtype=torch.float64), tx, rx, 2.0)
    p32 = solve_path(WaveSurface.sample(sea, 512, seed=9, dtype=torch.float32), tx.float(), rx.float(), 2.0)
    both = p64.valid & p32.valid
    assert both.float().mean() > 0.99
    assert (p64.point - p32.point.double())[both].abs().max().item() < 1e-3


def test_warm_start_converges_in_fewer_iterations(default_positions):
    tx, rx = default_positions
    surface = WaveSurface.sample(sea_state("jonswap", wind=12.0), 256, seed=4, dtype=torch.float64)
    first = solve_path(surface, tx, rx, 1.0)
    cold = solve_path(surface, tx, rx, 1.05)
    warm = solve_path(surface, tx, rx, 1.05, init=first.point[:, :2])
    assert warm.iterations.float().mean() < cold.iterations.float().mean() - 0.5
    assert warm.iterations.max() <= 6
    both = warm.valid & cold.valid
    assert (warm.point - cold.point)[both].abs().max().item() < 1e-8


def test_per_element_times(default_positions):
    tx, rx = default_positions
    surface = WaveSurface.sample(sea_state("jonswap", wind=12.0), 4, seed=5, dtype=torch.float64)
    t = torch.tensor([0.0, 1.0, 2.0, 3.0], dtype=torch.float64)
    together = solve_path(surface, tx, rx, t)
    for b in range(4):
        alone = solve_path(surface, tx, rx, float(t[b]))
        torch.testing.assert_close(together.point[b], alone.point[b], atol=1e-9, rtol=0)


@pytest.mark.slow
def test_centroid_agrees_with_newton_within_a_centimetre(default_positions):
    tx, rx = default_positions
    surface = WaveSurface.sample(sea_state("jonswap", wind=12.0), 32, seed=6, dtype=torch.float32)
    newton = solve_path(surface, tx.float(), rx.float(), 3.0)
    centroid = solve_path(surface, tx.float(), rx.float(), 3.0, method="centroid")
    distance = torch.linalg.vector_norm(newton.point - centroid.point, dim=-1)
    assert (distance < 0.01).float().mean().item() >= 0.95


def test_centroid_on_a_flat_sea_is_exact(default_positions):
    tx, rx = default_positions
    surface = WaveSurface.sample(sea_state("jonswap", flat=True), 2, seed=0, dtype=torch.float64)
    init = torch.tensor([[0.5, 0.5]], dtype=torch.float64).expand(2, 2)
    newton = solve_path(surface, tx, rx, 0.0)
    centroid = solve_path(surface, tx, rx, 0.0, method="centroid", init=init)
    assert centroid.valid.all()
    torch.testing.assert_close(centroid.point, newton.point, atol=1e-6, rtol=0)


def test_iteration_cap_flags_paths_invalid_never_nan(default_positions):
    tx, rx = default_positions
    surface = WaveSurface.sample(sea_state("jonswap", wind=12.0), 64, seed=7, dtype=torch.float64)
    path = solve_path(surface, tx, rx, 0.0, NewtonOptions(max_iter=1))
    assert (~path.valid).any()
    for value in (path.point, path.departure, path.theta1, path.d_air):
        assert torch.isfinite(value).all()


@settings(max_examples=25, deadline=None)
@given(
    wind=st.floats(0.5, 40.0),
    fetch=st.floats(1e3, 1e6),
    offset=st.floats(0.0, 1.0),
    seed=st.integers(0, 2**31 - 1),
    method=st.sampled_from(["newton", "newton_fixed", "centroid"]),
    spectrum=st.sampled_from(["jonswap", "elfouhaily"]),
)
def test_no_nan_or_inf_for_any_sea(wind, fetch, offset, seed, method, spectrum):
    tx, rx = LinkGeometry(offset_ratio=offset).positions(torch.float32)
    bins = {"n_freq": 16} if spectrum == "jonswap" else {"n_wavenumbers": 16}
    sea = sea_state(spectrum, wind=wind, fetch=fetch, n_dir=8, **bins)
    surface = WaveSurface.sample(sea, 16, seed=seed)
    assert torch.isfinite(surface.amplitude).all() and torch.isfinite(surface.unresolved).all()
    options = CentroidOptions(pixels=5, max_passes=6) if method == "centroid" else method
    path = solve_path(surface, tx, rx, 12.3, method=options)
    for name in ("point", "departure", "arrival", "normal", "theta1", "theta2", "d_water", "d_air"):
        assert torch.isfinite(getattr(path, name)).all(), name


def test_unknown_method_is_rejected(default_positions):
    tx, rx = default_positions
    surface = WaveSurface.sample(sea_state("jonswap"), 1, seed=0, dtype=torch.float64)
    with pytest.raises(ValueError, match="method = 'raytrace'"):
        solve_path(surface, tx, rx, 0.0, method="raytrace")


def test_solver_options_are_validated():
    with pytest.raises(ValueError, match="max_iter = 0"):
        NewtonOptions(max_iter=0)
    with pytest.raises(ValueError, match="shrink = 1"):
        CentroidOptions(shrink=1)


@pytest.mark.parametrize("kernel", ["fermat", "fixed"])
def test_a_compiled_path_kernel_keeps_one_graph_for_every_working_set(kernel, monkeypatch, default_positions):
    """The adaptive solver's working set shrinks as links converge, and a start point may be a slice of a wider
    tensor or not: called through :func:`call_compiled`, a compiled path kernel traces once for 8, 5, 3, 2 and 1
    rows, views or not (a view's base and sizes 1, 2 and 3 each compiled it again), and gives each row what it
    gives eagerly. Traced with dynamo's counting backend."""
    from torch._dynamo.testing import CompileCounter

    from waterair.physics.paths import fixed, newton

    counter = CompileCounter()
    function = newton.fermat_terms if kernel == "fermat" else fixed.fixed_newton_terms
    fixed_settings = (RefractiveIndices(N_W, N_A), FixedNewtonOptions(iterations=2, tol=1e-10))
    settings = (N_W, N_A) if kernel == "fermat" else fixed_settings
    traced = torch.compile(function, dynamic=True, backend=counter)
    torch._dynamo.reset()
    surface = WaveSurface.sample(sea_state("jonswap", wind=12.0, n_freq=16, n_dir=8), 8, seed=2, dtype=torch.float64)
    tx, rx = (v.expand(8, 3).contiguous() for v in default_positions)
    starts = torch.randn(8, 3, generator=torch.Generator().manual_seed(0), dtype=torch.float64)  # (x, y) a view
    for rows in (8, 5, 3, 2, 1):
        xy = starts[:rows, :2] if rows % 2 else starts[:rows, :2].clone()
        sea = surface[:rows].harmonics
        inputs = (xy, torch.full((rows,), 1.5, dtype=torch.float64), tx[:rows], rx[:rows])
        got = newton.call_compiled(traced, sea, inputs, *settings)
        assert type(got) is type(function(sea, *inputs, *settings))  # the kernel's named result
        for value, want in zip(got, function(sea, *inputs, *settings), strict=True):
            assert value.shape == want.shape
            torch.testing.assert_close(value, want, rtol=1e-12, atol=1e-12)
    assert counter.frame_count == 1
