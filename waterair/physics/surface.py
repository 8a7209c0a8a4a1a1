"""Harmonic wave surface: a batch of independent sea realisations (docs/model.md §2, paper eq. (9)).

    η(x, y, t) = Σ_k a_k cos(ω_k t − kx_k x − ky_k y + ε_k)

with deep-water waves |k| = ω²/g for the paper's sea and capillary-gravity waves
ω² = g|k|(1 + (|k|/k_m)²) for the measured-slope sea. Each batch element carries its own jittered
frequencies (or wavenumbers) and random phases, so one tensor operation evaluates B different seas,
and its unresolved slope covariance (the waves beyond the cutoff, docs/model.md §1.3). Positions
are in metres, time in seconds.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import torch
from tensordict import TensorClass

from waterair.core.extern import written
from waterair.core.validation import check_int
from waterair.physics.sea import SeaState
from waterair.physics.sea.slopes import rotated_covariance


@dataclass
class SurfaceSample:
    """Height (m) and its derivatives at evaluation points; each tensor has the points' shape.

    ``dx, dy`` are the slopes ∂η/∂x, ∂η/∂y (dimensionless); ``dxx, dxy, dyy`` the second
    derivatives (1/m). Entries not requested by ``order`` are ``None``.
    """

    height: torch.Tensor
    dx: torch.Tensor | None = None
    dy: torch.Tensor | None = None
    dxx: torch.Tensor | None = None
    dxy: torch.Tensor | None = None
    dyy: torch.Tensor | None = None


class Harmonics(NamedTuple):
    """The resolved surface of B seas as plain tensors, each ``[B, K]``: ``omega`` (rad/s), ``phase``
    (rad), ``kx``, ``ky`` (rad/m), ``amplitude`` (m). What the surface and channel functions read, passed whole
    (``harmonic_sums(harmonics, ...)``); a compiled step passes it through its graph."""

    omega: torch.Tensor
    phase: torch.Tensor
    kx: torch.Tensor
    ky: torch.Tensor
    amplitude: torch.Tensor


EAGER_CHUNK_ELEMENTS = 2**18
"""Points × harmonics an eager :func:`harmonic_sums` evaluates at once. Rows are independent, so chunks of
seas give the same values as one pass (the evaluation's metrics bit for bit), and far faster: at B = 608
seas, 81 points and 768 harmonics (a lattice) one pass took 555 ms and 4-row chunks (2^18 elements) 88 ms, on
2 threads (docs/benchmarks.md, "Eager surface sums")."""


def harmonic_sums(sea: Harmonics, x, y, t, order: int):
    """Σ a cos ψ and its derivatives, ψ = ω t + ε − kx x − ky y, reduced over harmonics K.

    Args: ``sea``'s components ``[B, K]``; points ``x, y`` ``[B, P]`` (m); ``t`` ``[B]`` (s); ``order`` 0-2.
    Returns a tuple of ``[B, P]`` tensors: (η,), (η, η_x, η_y) or (η, η_x, η_y, η_xx, η_xy, η_yy).

    One elementwise expression, so that ``torch.compile`` fuses it into a single pass over the
    harmonics (see :func:`compiled_harmonic_sums`); eager PyTorch runs it in chunks of seas of about
    :data:`EAGER_CHUNK_ELEMENTS` points × harmonics (rows are independent: the same values).
    """
    rows = max(1, EAGER_CHUNK_ELEMENTS // max(1, x[0].numel() * sea.omega.shape[-1]))
    return _in_chunks(functools.partial(_harmonic_sums, order=order), (*sea, x, y, t), rows)


def _in_chunks(sums, inputs: Sequence[torch.Tensor], rows: int):
    """``sums(inputs)`` eagerly in chunks of ``rows`` seas (rows are independent: the same values), in one pass when
    compiling or when the inputs do not all have one row per sea."""
    batch = inputs[0].shape[0]
    if torch.compiler.is_compiling() or rows >= batch or any(v.shape[0] != batch for v in inputs):
        return sums(inputs)
    parts = [sums([v[i : i + rows] for v in inputs]) for i in range(0, batch, rows)]
    return tuple(torch.cat(values) for values in zip(*parts, strict=True))


def _harmonic_sums(inputs: Sequence[torch.Tensor], order: int):
    """:func:`harmonic_sums` of ``inputs`` (the components, ``x``, ``y`` and ``t``) in one pass."""
    omega, phase, kx, ky, amplitude, x, y, t = inputs
    omega, phase, kx, ky, amplitude = (v.unsqueeze(1) for v in (omega, phase, kx, ky, amplitude))
    psi = omega * t[:, None, None] + phase - kx * x.unsqueeze(-1) - ky * y.unsqueeze(-1)
    a_cos = amplitude * torch.cos(psi)
    height = a_cos.sum(-1)
    if order == 0:
        return (height,)
    a_sin = amplitude * torch.sin(psi)
    slopes = (a_sin * kx).sum(-1), (a_sin * ky).sum(-1)
    if order == 1:
        return (height, *slopes)
    a_cos_kx = a_cos * kx
    return (height, *slopes, -(a_cos_kx * kx).sum(-1), -(a_cos_kx * ky).sum(-1), -(a_cos * ky * ky).sum(-1))


def lattice_harmonic_sums(sea: Harmonics, centre, basis, grid, t, order: int):
    """:func:`harmonic_sums` at the nodes of the affine lattices ``centre + basis · (g_i, g_j)``, without a
    sine and a cosine per node and harmonic.

    Args: ``sea``'s components ``[B, K]``; ``centre`` ``[B, 2]`` (m); ``basis`` ``[B, 2, 2]`` (m, its columns the
    lattice's steps per unit of ``grid``); ``grid`` ``[n]``, the node coordinates along each axis, evenly spaced;
    ``t`` ``[B]`` (s); ``order`` 0-2. Returns :func:`harmonic_sums`'s tuple, each ``[B, n²]``, node (i, j) at i n + j
    (``torch.meshgrid(grid, grid, indexing="ij")``).

    The phase is affine in the node: ψ(i, j) = ψ_c − g_i α − g_j β with ψ_c the centre's phase and α, β the
    wavenumber projected on the basis' columns, so that a e^{iψ(i, j)} = (a e^{iψ_c}) e^{−i g_i α} e^{−i g_j β}:
    1 + 2n complex exponentials per harmonic instead of n² (docs/model.md §4.3). Eager PyTorch takes each axis's n
    as powers of one (:func:`_power_factors`) and sums over the harmonics as a matrix product of the i-factors
    ``[n, K]`` and the j-factors ``[K, n]``, in real arithmetic and in chunks of seas, as :func:`harmonic_sums`;
    compiled on a CPU, the factors are written once and inductor sums their products in its own loop
    (:func:`_compiled_lattice_sums`); compiled on a GPU, one sine and cosine per node and harmonic
    (:func:`harmonic_sums`).
    """
    if torch.compiler.is_compiling():
        if sea.omega.device.type == "cpu":
            return _compiled_lattice_sums((*sea, centre, basis, t), grid, order)
        xy = lattice_nodes(centre, basis, grid)
        return harmonic_sums(sea, xy[..., 0], xy[..., 1], t, order)
    rows = max(1, EAGER_CHUNK_ELEMENTS // (grid.shape[0] * sea.omega.shape[-1]))
    inputs = (*sea, centre, basis, t)
    return _in_chunks(functools.partial(_lattice_sums, grid=grid, order=order), inputs, rows)


def lattice_nodes(centre: torch.Tensor, basis: torch.Tensor, grid: torch.Tensor) -> torch.Tensor:
    """The nodes ``centre + basis · (g_i, g_j)`` (m) of :func:`lattice_harmonic_sums`'s lattices, ``[B, n², 2]``, node
    (i, j) at i n + j."""
    z = torch.stack(torch.meshgrid(grid, grid, indexing="ij"), dim=-1).reshape(-1, 2)  # [n², 2]
    return centre.unsqueeze(1) + torch.einsum("bij,nj->bni", basis, z)


def _node_factors(inputs: Sequence[torch.Tensor], grid: torch.Tensor):
    """The lattice's per-axis factors, each ``[B, n, K]``: the i-factors a e^{iψ_c} e^{−i g_i α} (real, imaginary)
    and the j-factors e^{−i g_j β} = cos − i sin (cos, sin), a sine and a cosine per axis, node and harmonic."""
    amplitude = inputs[4]
    projected, psi = _projection_and_phase(inputs)
    c_re, c_im = (amplitude * torch.cos(psi)).unsqueeze(1), (amplitude * torch.sin(psi)).unsqueeze(1)  # a e^{iψ_c}
    angle = projected.unsqueeze(2) * grid[:, None]  # (g_i α, g_j β) [B, 2, n, K], at each grid coordinate
    cos_a, sin_a = torch.cos(angle[:, 0]), torch.sin(angle[:, 0])
    real, imaginary = c_re * cos_a + c_im * sin_a, c_im * cos_a - c_re * sin_a
    return real, imaginary, torch.cos(angle[:, 1]), torch.sin(angle[:, 1])


def _power_factors(inputs: Sequence[torch.Tensor], grid: torch.Tensor, rows: torch.Tensor, factors: torch.Tensor):
    """:func:`_node_factors` written into ``rows`` (``[B, n, 2K]``, [real | imaginary]) and ``factors[:, 1]`` (``[B,
    n, 2K]``, [cos | sin], the matrix product's first columns), with three sines and cosines per harmonic instead of
    1 + 2n; ``factors[:, 0]`` holds the i-axis' [cos | sin] on the way.

    The grid is uniform, g_i = g_m + (i − m) h about its middle node m, so e^{−i g_i α} = e^{−i g_m α} e^{−i (i − m)
    h α}: the middle node's factors join the centre's phase, and the others are powers of e^{−i h α}
    (:func:`_powers`'s recurrences), as for β, each power written in its place for both axes at once and mirrored
    to the nodes before the middle (cos(−d x) = cos(d x), sin(−d x) = −sin(d x)). Eager, the lattice's sums at 64
    links take about 20 % less time than with :func:`_node_factors`; compiled on a CPU they are bound by writing
    the factors, not by their sines, and were no faster (docs/benchmarks.md, "Lattice sums"). Returns the
    j-factors' cos and sin, views of ``factors``."""
    amplitude = inputs[4]
    nodes, harmonics = grid.shape[0], amplitude.shape[-1]
    middle = (nodes - 1) // 2  # as many nodes before it as after it, or one more after
    projected, psi = _projection_and_phase(inputs)
    psi = psi - grid[middle] * projected.sum(1)  # the middle node's phase
    c_re, c_im = (amplitude * torch.cos(psi)).unsqueeze(1), (amplitude * torch.sin(psi)).unsqueeze(1)  # at (m, m)
    both = factors[:, :2]  # [B, 2 (i, j), n, 2K]
    cos, sin = both[..., :harmonics], both[..., harmonics:]
    _powers(projected * ((grid[-1] - grid[0]) / (nodes - 1)), cos[:, :, middle:], sin[:, :, middle:])
    cos[:, :, :middle].copy_(cos[:, :, middle + 1 : 2 * middle + 1].flip(2))
    torch.neg(sin[:, :, middle + 1 : 2 * middle + 1].flip(2), out=sin[:, :, :middle])
    real, imaginary = rows.split(harmonics, -1)
    cos_a, sin_a = cos[:, 0], sin[:, 0]
    torch.add(c_re * cos_a, c_im * sin_a, out=real)
    torch.sub(c_im * cos_a, c_re * sin_a, out=imaginary)
    return cos[:, 1], sin[:, 1]


def _projection_and_phase(inputs: Sequence[torch.Tensor]) -> tuple[torch.Tensor, torch.Tensor]:
    """The wavenumber projected on each basis column, (α, β) ``[B, 2, K]``, and the phase ψ_c at the lattice's
    centre ``[B, K]`` (:func:`lattice_harmonic_sums`)."""
    omega, phase, kx, ky, _, centre, basis, t = inputs
    projected = kx.unsqueeze(1) * basis[:, 0, :, None] + ky.unsqueeze(1) * basis[:, 1, :, None]
    return projected, omega * t.unsqueeze(-1) + phase - kx * centre[:, :1] - ky * centre[:, 1:]


def _powers(angle: torch.Tensor, cos: torch.Tensor, sin: torch.Tensor) -> None:
    """cos(d x) and sin(d x) for d = 0 … D − 1 written into ``cos[:, :, d]`` and ``sin[:, :, d]`` (each ``[B, 2, D,
    K]``) from one cosine and sine of x = ``angle`` ``[B, 2, K]``: e^{i d x} squared from e^{i d x / 2} where d is
    even (cos 2y = 1 − 2 sin² y, sin 2y = 2 sin y cos y), times e^{i x} where odd."""
    cos[:, :, 0].fill_(1.0)
    sin[:, :, 0].fill_(0.0)
    if cos.shape[2] > 1:
        cos[:, :, 1].copy_(torch.cos(angle))  # computed whole, then placed: the same rounding as a tensor of its own
        sin[:, :, 1].copy_(torch.sin(angle))
    for d in range(2, cos.shape[2]):
        if d % 2 == 0:
            half_cos, half_sin = cos[:, :, d // 2], sin[:, :, d // 2]
            torch.sub(1, 2 * half_sin * half_sin, out=cos[:, :, d])
            torch.mul(2 * half_sin, half_cos, out=sin[:, :, d])
        else:
            last_cos, last_sin, one_cos, one_sin = cos[:, :, d - 1], sin[:, :, d - 1], cos[:, :, 1], sin[:, :, 1]
            torch.sub(last_cos * one_cos, last_sin * one_sin, out=cos[:, :, d])
            torch.add(last_sin * one_cos, last_cos * one_sin, out=sin[:, :, d])


def _lattice_sums(inputs: Sequence[torch.Tensor], grid: torch.Tensor, order: int):
    """:func:`lattice_harmonic_sums` of ``inputs`` (the components, ``centre``, ``basis`` and ``t``) in one pass, each
    factor written where the matrix product reads it (no concatenation copies)."""
    kx, ky = inputs[2].unsqueeze(1), inputs[3].unsqueeze(1)
    (batch, harmonics), n, terms = kx.shape[::2], grid.shape[0], (1, 3, 6)[order]
    rows = kx.new_empty(batch, n, 2 * harmonics)  # the i-factors, [real | imaginary] over the harmonics
    # the j-factors e^{−i g_j β} as the columns that, times [re | im], give the real part (m_re cos + m_im sin)
    # and the imaginary part (m_im cos − m_re sin) of the product, each weighted per harmonic by its sum's factor:
    # η = Re Σ a e^{iψ}; η_x, η_y = Im Σ (kx, ky) a e^{iψ}; η_xx, η_xy, η_yy = −Re Σ (kx², kx ky, ky²) a e^{iψ};
    # behind a slot for the i-axis' powers (:func:`_power_factors`)
    factors = kx.new_empty(batch, 1 + terms, n, 2 * harmonics)
    columns = factors[:, 1:]
    cos_b, sin_b = _power_factors(inputs, grid, rows, factors)
    if order >= 1:
        for term, weight in ((1, kx), (2, ky)):
            torch.mul(-weight, sin_b, out=columns[:, term, :, :harmonics])  # (−w) s: exactly w (−s)
            torch.mul(weight, cos_b, out=columns[:, term, :, harmonics:])
    if order == 2:
        for term, weight in ((3, kx * kx), (4, kx * ky), (5, ky * ky)):
            torch.mul(-weight, cos_b, out=columns[:, term, :, :harmonics])
            torch.mul(-weight, sin_b, out=columns[:, term, :, harmonics:])
    sums = torch.bmm(rows, columns.reshape(batch, terms * n, 2 * harmonics).transpose(1, 2))  # [B, n (i), terms × n]
    sums = sums.reshape(batch, n, terms, n).transpose(1, 2).reshape(batch, terms, n * n)
    return tuple(sums.unbind(1))


def _compiled_lattice_sums(inputs: Sequence[torch.Tensor], grid: torch.Tensor, order: int):
    """:func:`lattice_harmonic_sums` inside ``torch.compile`` on a CPU: the factors written to memory once (an extern
    kernel reads them: :func:`written`), and each node's sums over the harmonics one reduction over their products.
    Left to itself, inductor recomputes the factors' sines in every product, which is slower than the direct sums
    (docs/benchmarks.md, "Lattice sums")."""
    kx, ky = (v[:, None, None] for v in inputs[2:4])
    factors = torch.stack(_node_factors(inputs, grid), dim=1)  # [B, 4, n, K]
    zero = written(factors)
    rows_re, rows_im, cos_b, sin_b = factors.unbind(1)
    rows_re, rows_im, cos_b, sin_b = rows_re.unsqueeze(2), rows_im.unsqueeze(2), cos_b.unsqueeze(1), sin_b.unsqueeze(1)
    # node (i, j): (m_re + i m_im)(cos − i sin) = (m_re cos + m_im sin) + i (m_im cos − m_re sin)
    real = rows_re * cos_b + rows_im * sin_b  # [B, n (i), n (j), K]
    sums = [real.sum(-1) + zero]
    if order >= 1:
        imaginary = rows_im * cos_b - rows_re * sin_b
        sums += [(kx * imaginary).sum(-1), (ky * imaginary).sum(-1)]
    if order == 2:
        sums += [-(weight * real).sum(-1) for weight in (kx * kx, kx * ky, ky * ky)]
    return tuple(v.flatten(1) for v in sums)


@functools.cache
def compiled_harmonic_sums():
    """``torch.compile(harmonic_sums)``, built on first use and shared by every caller that asks.

    Compiled, an order-2 evaluation runs at about the cost of one sin+cos pass over ``[B, K]``
    (≈ 5× faster than eager on a 2-core CPU, see docs/benchmarks.md) after a one-off compile of
    ~30-60 s per process. Shapes are dynamic, so batch-size changes do not recompile. Asking for
    it changes nothing for callers that evaluate eagerly.
    """
    return torch.compile(harmonic_sums, dynamic=True)


class WaveSurface(TensorClass):
    """B independent harmonic sea surfaces with K harmonics each.

    Components, all ``[B, K]``: ``omega`` (rad/s), ``kx``, ``ky`` (wavenumber components, rad/m),
    ``amplitude`` (m), ``phase`` (rad); and ``unresolved`` ``[B, 3]``, the slope covariance
    (σ_xx, σ_xy, σ_yy) of the waves shorter than the sea's cutoff, in the x-y frame
    (dimensionless; zero for the paper's sea). Build with :meth:`sample` or directly from tensors;
    index or assign rows like any tensorclass (``surface[mask] = other[mask]`` resets a subset).
    """

    omega: torch.Tensor
    kx: torch.Tensor
    ky: torch.Tensor
    amplitude: torch.Tensor
    phase: torch.Tensor
    unresolved: torch.Tensor

    @classmethod
    def sample(
        cls,
        sea: SeaState,
        batch_size: int,
        *,
        seed: int | None = None,
        generator: torch.Generator | None = None,
        device: torch.device | str | None = None,
        dtype: torch.dtype = torch.float32,
        wind: torch.Tensor | None = None,
        wind_direction_deg: torch.Tensor | None = None,
    ) -> WaveSurface:
        """Draw ``batch_size`` independent realisations of ``sea``.

        Each jitters every frequency (``jonswap``) or wavenumber (``elfouhaily``) uniformly inside its bin (the
        surface does not repeat within an episode; the expected variance is the band's m0) and draws phases uniform
        in [0, 2π); its ``unresolved`` slope covariance follows its wind. The numbers are ``generator``'s, else a new
        generator's seeded with ``seed`` (None: nondeterministic), drawn on its device in float64, so a seed gives the
        same sea on CPU and CUDA. ``wind`` (m/s), ``wind_direction_deg`` (from +x): each one's own ``[batch_size]``.
        """
        batch = check_int("batch_size", batch_size, 1)
        if generator is None:
            generator = torch.Generator()
            if seed is None:
                generator.seed()
            else:
                generator.manual_seed(seed)

        def uniform(role: str, count: int) -> torch.Tensor:  # the generator's next, whatever the role
            return torch.rand(batch, count, generator=generator, dtype=torch.float64, device=generator.device)

        return cls.from_uniforms(
            sea, batch, uniform, device=device, dtype=dtype, wind=wind, wind_direction_deg=wind_direction_deg
        )

    @classmethod
    def from_uniforms(
        cls,
        sea: SeaState,
        batch: int,
        uniform: Callable[[str, int], torch.Tensor],
        *,
        device: torch.device | str | None = None,
        dtype: torch.dtype = torch.float32,
        wind: torch.Tensor | None = None,
        wind_direction_deg: torch.Tensor | None = None,
    ) -> WaveSurface:
        """:meth:`sample`'s ``batch`` realisations from ``uniform`` (role, count): the draw ``role``'s (``"jitter"``,
        then ``"phase"``) uniforms on (0, 1) ``[batch, count]`` float64, built on their device (docs/model.md §10)."""
        n_dir, n_bins = sea.n_dir, sea.n_bins  # bins in frequency (the paper's sea) or in wavenumber
        jitter = uniform("jitter", n_bins)
        draw_device = jitter.device
        if wind is not None:
            wind = wind.to(device=draw_device, dtype=torch.float64).expand(batch)
        edges = sea.bin_edges(torch.float64, draw_device, wind).expand(batch, n_bins + 1)
        width = edges[:, 1:] - edges[:, :-1]
        drawn = edges[:, :-1] + jitter * width
        omega, amplitude, wavenumber = sea.harmonics(drawn, width, wind)
        theta, _ = sea.directions(torch.float64, draw_device)
        if wind_direction_deg is None:
            heading = theta + math.radians(sea.wind_direction_deg)
            direction = torch.full((batch,), sea.wind_direction_deg, dtype=torch.float64, device=draw_device)
        else:
            direction = wind_direction_deg.to(device=draw_device, dtype=torch.float64).expand(batch)
            heading = (theta + torch.deg2rad(direction).unsqueeze(-1)).unsqueeze(1)  # [batch, 1, n_dir]
        kx = wavenumber.unsqueeze(-1) * torch.cos(heading)
        ky = wavenumber.unsqueeze(-1) * torch.sin(heading)
        phase = 2.0 * math.pi * uniform("phase", n_bins * n_dir).to(draw_device)  # after the jitter, as drawn
        speed = torch.full((batch,), sea.wind, dtype=torch.float64, device=draw_device) if wind is None else wind
        unresolved = rotated_covariance(*sea.unresolved_slope_variances(speed), direction)

        def flat(values: torch.Tensor) -> torch.Tensor:
            return values.expand(batch, n_bins, n_dir).reshape(batch, -1).to(device=device, dtype=dtype)

        return cls(
            omega=flat(omega.unsqueeze(-1)),
            kx=flat(kx),
            ky=flat(ky),
            amplitude=flat(amplitude),
            phase=phase.to(device=device, dtype=dtype),
            unresolved=unresolved.to(device=device, dtype=dtype),
            batch_size=[batch],
        )

    @property
    def harmonics(self) -> Harmonics:
        """The resolved components as :class:`Harmonics`."""
        return Harmonics(self.omega, self.phase, self.kx, self.ky, self.amplitude)

    @property
    def num_harmonics(self) -> int:
        """K, the number of harmonics per realisation."""
        return self.omega.shape[-1]

    def variance(self) -> torch.Tensor:
        """Discretised variance Σ a²/2 (m²) of each realisation, ``[B]``: its share of m0."""
        return 0.5 * (self.amplitude**2).sum(-1)

    def evaluate(
        self, x: torch.Tensor, y: torch.Tensor, t: float | torch.Tensor, order: int = 2, *, compiled: bool = False
    ) -> SurfaceSample:
        """Height and derivatives up to ``order`` (0, 1 or 2) at points ``(x, y)`` and time ``t``.

        Args:
            x, y: horizontal position (m), ``[B]`` (one point per realisation) or ``[B, P]``.
            t: time (s), a float or a ``[B]`` tensor.
            order: 0 for η only (one cos pass); 1 adds the slopes; 2 adds the second derivatives.
            compiled: evaluate through :func:`compiled_harmonic_sums` instead of eagerly.
        """
        single = x.dim() == 1
        if single:
            x, y = x.unsqueeze(-1), y.unsqueeze(-1)
        time = torch.as_tensor(t, dtype=self.omega.dtype, device=self.omega.device).expand(x.shape[0])
        kernel = compiled_harmonic_sums() if compiled else harmonic_sums
        sums = kernel(self.harmonics, x, y, time, order)
        if single:
            sums = tuple(v.squeeze(-1) for v in sums)
        return SurfaceSample(*sums)

    def height(self, x: torch.Tensor, y: torch.Tensor, t: float | torch.Tensor) -> torch.Tensor:
        """η(x, y, t) in metres; shapes as in :meth:`evaluate`."""
        return self.evaluate(x, y, t, order=0).height


def directional_third_derivatives(sea: Harmonics, xy, t, axes):
    """η_vvv = −Σ a (k·v)³ sin ψ, the surface's third derivative (1/m²) along each unit ``axes`` ``[B, D, 2]``.

    Args: ``sea``'s components ``[B, K]``; one point ``xy`` ``[B, 2]`` (m) per sea; ``t`` ``[B]`` (s). Returns
    ``[B, D]``. It bounds the lensing at a caustic (docs/model.md §4.2).
    """
    omega, phase, kx, ky, amplitude = sea
    psi = omega * t.unsqueeze(-1) + phase - kx * xy[:, :1] - ky * xy[:, 1:]
    along = kx.unsqueeze(1) * axes[..., :1] + ky.unsqueeze(1) * axes[..., 1:]  # [B, D, K]
    return -(amplitude.unsqueeze(1) * along**3 * torch.sin(psi).unsqueeze(1)).sum(-1)
