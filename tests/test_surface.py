"""Harmonic surface: statistics, derivatives and batching (docs/model.md §1, §2)."""

import math

import pytest
import torch

from waterair.physics.sea import sea_state
from waterair.physics.surface import Harmonics, WaveSurface, harmonic_sums, lattice_harmonic_sums


def surface64(batch=8, seed=0, spectrum="jonswap", **sea):
    return WaveSurface.sample(sea_state(spectrum, **sea), batch, seed=seed, dtype=torch.float64)


@pytest.mark.parametrize("amplitude,factor", [("standard", 1.0), ("paper", 0.5)])
def test_ensemble_variance_matches_m0(amplitude, factor):
    """Var η over 512 realisations at 16 well-separated points equals the discretised m0."""
    sea = sea_state("jonswap", amplitude=amplitude)
    surface = WaveSurface.sample(sea, 512, seed=1, dtype=torch.float64)
    x = torch.linspace(0.0, 3000.0, 16, dtype=torch.float64).expand(512, 16)
    eta = surface.height(x, 0.5 * x, 7.0)
    ensemble = eta.var(dim=0).mean().item()
    # The paper's amplitude carries half of the standard one's variance, which is the band's m0.
    band_m0 = sea.m0(*sea.omega_band)
    assert surface.variance().mean().item() == pytest.approx(factor * band_m0, rel=0.03)
    assert ensemble == pytest.approx(surface.variance().mean().item(), rel=0.03)
    assert ensemble == pytest.approx(factor * band_m0, rel=0.03)


def test_height_matches_direct_double_sum():
    """η from an independent loop over (i, j) in float64 Python math."""
    sea = sea_state("jonswap", n_freq=5, n_dir=4, wind_direction_deg=30.0)
    surface = WaveSurface.sample(sea, 2, seed=3, dtype=torch.float64)
    x, y, t = 3.7, -1.2, 2.5
    got = surface.height(torch.tensor([x, x], dtype=torch.float64), torch.tensor([y, y], dtype=torch.float64), t)
    for b in range(2):
        total = 0.0
        for k in range(surface.num_harmonics):
            omega = surface.omega[b, k].item()
            kx, ky = surface.kx[b, k].item(), surface.ky[b, k].item()
            assert math.hypot(kx, ky) == pytest.approx(omega**2 / 9.81, rel=1e-12)
            total += surface.amplitude[b, k].item() * math.cos(omega * t - kx * x - ky * y + surface.phase[b, k].item())
        assert got[b].item() == pytest.approx(total, rel=1e-12, abs=1e-14)


def test_eager_sums_over_many_points_match_a_float64_double_sum_in_every_chunk():
    """Enough seas × points × harmonics that the eager kernel works in chunks of seas: every row is its own
    sea's sum (a float64 loop over harmonics), in order, and the orders agree with each other."""
    from waterair.physics.surface import EAGER_CHUNK_ELEMENTS, harmonic_sums

    sea = sea_state("jonswap", n_freq=16, n_dir=8)
    seas, points = 7, 400
    surface = WaveSurface.sample(sea, seas, seed=5)
    rows = EAGER_CHUNK_ELEMENTS // (points * surface.num_harmonics)
    assert 1 <= rows < seas  # chunked, with a short last chunk
    generator = torch.Generator().manual_seed(0)
    x, y = (20 * torch.rand(seas, points, generator=generator) - 10 for _ in range(2))
    t = torch.linspace(0.0, 6.0, seas)
    height, slope_x, slope_y = harmonic_sums(surface.harmonics, x, y, t, 1)
    (first,) = harmonic_sums(surface.harmonics, x, y, t, 0)
    torch.testing.assert_close(first, height, rtol=0, atol=0)
    c = [v.double() for v in surface.harmonics]  # omega, phase, kx, ky, amplitude
    psi = c[0][:, None] * t.double()[:, None, None] + c[1][:, None] - c[2][:, None] * x.double()[..., None]
    psi = psi - c[3][:, None] * y.double()[..., None]
    amplitude = c[4][:, None]
    expected = (
        (amplitude * torch.cos(psi)).sum(-1),
        (amplitude * torch.sin(psi) * c[2][:, None]).sum(-1),
        (amplitude * torch.sin(psi) * c[3][:, None]).sum(-1),
    )
    for got, want in zip((height, slope_x, slope_y), expected, strict=True):
        assert got.shape == (seas, points)
        torch.testing.assert_close(got.double(), want, rtol=1e-4, atol=1e-4 * want.abs().max().item())


def test_derivatives_match_central_differences():
    surface = surface64(batch=4, seed=2)
    x = torch.tensor([0.3, -2.0, 5.5, 1.0], dtype=torch.float64)
    y = torch.tensor([1.1, 0.0, -3.3, 2.0], dtype=torch.float64)
    t = torch.tensor([0.0, 1.0, 2.5, 10.0], dtype=torch.float64)
    s = surface.evaluate(x, y, t, order=2)
    h = 1e-5
    ex = surface.evaluate(x + h, y, t), surface.evaluate(x - h, y, t)
    ey = surface.evaluate(x, y + h, t), surface.evaluate(x, y - h, t)

    def fd(pair, field):
        return (getattr(pair[0], field) - getattr(pair[1], field)) / (2 * h)

    def rel(a, b):
        return ((a - b).abs() / b.abs().clamp(min=1e-3)).max().item()

    assert rel(s.dx, fd(ex, "height")) < 1e-6
    assert rel(s.dy, fd(ey, "height")) < 1e-6
    assert rel(s.dxx, fd(ex, "dx")) < 1e-6
    assert rel(s.dxy, fd(ey, "dx")) < 1e-6
    assert rel(s.dyy, fd(ey, "dy")) < 1e-6


def test_point_sets_and_single_points_agree():
    surface = surface64(batch=3)
    x = torch.rand(3, 5, dtype=torch.float64) * 10
    y = torch.rand(3, 5, dtype=torch.float64) * 10
    many = surface.evaluate(x, y, 1.5)
    for p in range(5):
        one = surface.evaluate(x[:, p], y[:, p], 1.5)
        torch.testing.assert_close(one.height, many.height[:, p])
        torch.testing.assert_close(one.dxy, many.dxy[:, p])


def test_seeds_are_reproducible_and_distinct():
    a, b, c = surface64(seed=7), surface64(seed=7), surface64(seed=8)
    torch.testing.assert_close(a.phase, b.phase)
    torch.testing.assert_close(a.omega, b.omega)
    assert not torch.allclose(a.phase, c.phase)


def test_realisations_in_a_batch_are_independent():
    surface = surface64(batch=2)
    assert not torch.allclose(surface.phase[0], surface.phase[1])
    assert not torch.allclose(surface.omega[0], surface.omega[1])


def test_frequencies_are_jittered_inside_their_bins():
    sea = sea_state("jonswap", n_freq=8, n_dir=2)
    surface = WaveSurface.sample(sea, 64, seed=4, dtype=torch.float64)
    edges = sea.frequency_bins(torch.float64)
    omega = surface.omega.reshape(64, 8, 2)[..., 0]
    assert torch.all(omega >= edges[:-1]) and torch.all(omega < edges[1:])
    assert omega.std(dim=0).min() > 0


def test_flat_sea_is_flat():
    s = surface64(flat=True).evaluate(torch.zeros(8, dtype=torch.float64), torch.zeros(8, dtype=torch.float64), 3.0)
    assert torch.all(s.height == 0) and torch.all(s.dx == 0) and torch.all(s.dyy == 0)


def test_row_assignment_resets_a_subset():
    a, b = surface64(seed=1), surface64(seed=2)
    mask = torch.tensor([True, False] * 4)
    a[mask] = b[mask]
    torch.testing.assert_close(a.phase[mask], b.phase[mask])
    assert not torch.allclose(a.phase[~mask], b.phase[~mask])
    torch.testing.assert_close(a.kx[mask], b.kx[mask])


def test_batch_size_is_validated():
    with pytest.raises(ValueError, match="batch_size = 0"):
        WaveSurface.sample(sea_state("jonswap"), 0)


@pytest.mark.slow
def test_compiled_kernel_matches_eager_and_leaves_eager_callers_eager(inductor):
    """torch.compile of the harmonic sums gives the eager values; asking for it switches nothing else."""
    sea = sea_state("jonswap", n_freq=8, n_dir=4)
    s = WaveSurface.sample(sea, 3, seed=0, dtype=torch.float64)
    x = torch.tensor([[0.1, 2.0], [3.0, -1.0], [0.0, 5.0]], dtype=torch.float64)
    eager = s.evaluate(x, -x, 1.5)
    compiled = s.evaluate(x, -x, 1.5, compiled=True)
    for field in ("height", "dx", "dy", "dxx", "dxy", "dyy"):
        torch.testing.assert_close(getattr(compiled, field), getattr(eager, field), rtol=1e-10, atol=1e-12)
    counts = torch._dynamo.utils.counters["stats"]["calls_captured"]
    s.evaluate(x, -x, 2.5)  # an eager call after a compiled one traces nothing
    assert torch._dynamo.utils.counters["stats"]["calls_captured"] == counts


def test_per_realisation_wind_matches_separate_seas():
    """A batch with winds (4, 12) equals two single-wind samples drawn with the same numbers."""
    winds = torch.tensor([4.0, 12.0], dtype=torch.float64)
    mixed = WaveSurface.sample(sea_state("jonswap"), 2, seed=5, dtype=torch.float64, wind=winds)
    for row, wind in enumerate(winds.tolist()):
        alone = WaveSurface.sample(sea_state("jonswap", wind=wind), 2, seed=5, dtype=torch.float64)
        torch.testing.assert_close(mixed.amplitude[row], alone.amplitude[row])
        torch.testing.assert_close(mixed.omega[row], alone.omega[row])
    assert mixed.variance()[1] > 3 * mixed.variance()[0]


def direct_sums(harmonics, x, y, t):
    """η, η_x, η_y, η_xx, η_xy, η_yy at points ``[B, P]`` in float64, one cos and one sin per point and harmonic."""
    omega, phase, kx, ky, amplitude = (v.double().unsqueeze(1) for v in harmonics)
    psi = omega * t.double()[:, None, None] + phase - kx * x.double().unsqueeze(-1) - ky * y.double().unsqueeze(-1)
    cos, sin = amplitude * torch.cos(psi), amplitude * torch.sin(psi)
    sums = (cos, sin * kx, sin * ky, -cos * kx * kx, -cos * kx * ky, -cos * ky * ky)
    return tuple(s.sum(-1) for s in sums)


def random_lattices(batch: int, nodes: int, seed: int):
    """Random affine lattices: centres within 20 m, bases of any orientation, scale (2-30 cm a step) and shear."""
    generator = torch.Generator().manual_seed(seed)
    centre = 20.0 * (2.0 * torch.rand(batch, 2, generator=generator, dtype=torch.float64) - 1.0)
    basis = 0.02 + 0.28 * torch.rand(batch, 2, 2, generator=generator, dtype=torch.float64)
    basis = basis * torch.sign(torch.randn(batch, 2, 2, generator=generator, dtype=torch.float64))
    span = 1.0 + 4.0 * torch.rand((), generator=generator, dtype=torch.float64).item()
    grid = torch.linspace(-span, span, nodes, dtype=torch.float64)
    time = 30.0 * torch.rand(batch, generator=generator, dtype=torch.float64)
    z = torch.stack(torch.meshgrid(grid, grid, indexing="ij"), dim=-1).reshape(-1, 2)
    xy = centre.unsqueeze(1) + torch.einsum("bij,nj->bni", basis, z)
    return centre, basis, grid, time, xy


@pytest.mark.parametrize(
    "sea,nodes,seed",
    [({"spectrum": "jonswap", "n_freq": 64, "n_dir": 16}, 9, 0), ({"spectrum": "elfouhaily"}, 5, 1),
     ({"spectrum": "elfouhaily", "wind": 4.0}, 15, 2), ({"spectrum": "jonswap", "wind": 20.0}, 3, 3),
     ({"spectrum": "elfouhaily", "wind": 12.0}, 4, 4)],
)  # fmt: skip
@pytest.mark.parametrize("order", [0, 1, 2])
def test_lattice_sums_equal_the_direct_sums_at_every_node(sea, nodes, seed, order):
    """The lattice's factorised sums (eager: three exponentials per harmonic and their powers; an even number of
    nodes has no node at the centre) against one cos and sin per node and harmonic in float64, written here: to
    1e-10 of the sums' scale (Σ a |k|^p over the harmonics) in float64; in float32 to 1e-5 of it, and no further
    from the float64 sums than the direct float32 sums are (twice their largest error): the centre's phase is
    rounded once, as the direct sum rounds each node's (ωt + ε − kx x − ky y), and a power's error grows with
    the node's distance from the middle as a direct phase's rounding grows with it."""
    batch = 6
    surface = WaveSurface.sample(sea_state(**{"spectrum": "jonswap", **sea}), batch, seed=seed, dtype=torch.float64)
    centre, basis, grid, time, xy = random_lattices(batch, nodes, seed)
    expected = direct_sums(surface.harmonics, xy[..., 0], xy[..., 1], time)[: (1, 3, 6)[order]]
    k = torch.sqrt(surface.kx**2 + surface.ky**2)
    scales = [(surface.amplitude * k**power).sum(-1, keepdim=True) for power in (0, 1, 1, 2, 2, 2)]
    got = lattice_harmonic_sums(surface.harmonics, centre, basis, grid, time, order)
    assert len(got) == len(expected)
    for value, want, scale in zip(got, expected, scales, strict=False):
        assert value.shape == (batch, nodes * nodes)
        assert ((value - want).abs() / scale).max().item() < 1e-10
    sea32 = Harmonics(*(v.float() for v in surface.harmonics))
    single = [v.float() for v in (centre, basis, grid, time)]
    got32 = lattice_harmonic_sums(sea32, *single, order)
    direct32 = harmonic_sums(sea32, xy[..., 0].float(), xy[..., 1].float(), single[-1], order)
    for value, direct, want, scale in zip(got32, direct32, expected, scales, strict=False):
        error = (value.double() - want).abs() / scale
        assert error.max().item() < 1e-5
        assert error.max().item() <= 2.0 * ((direct.double() - want).abs() / scale).max().item()
