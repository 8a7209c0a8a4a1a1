"""Harmonic wave surface: a batch of independent sea realisations (SPEC §2, paper eq. (9)).

    η(x, y, t) = Σ_k a_k cos(ω_k t − kx_k x − ky_k y + ε_k),   |k| = ω² / g (deep water)

Each batch element carries its own jittered frequencies and random phases, so one tensor
operation evaluates B different seas. Positions are in metres, time in seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from tensordict import tensorclass

from waterair._validation import check_int
from waterair.sea import GRAVITY, SeaState


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


@tensorclass
class WaveSurface:
    """B independent harmonic sea surfaces with K harmonics each.

    Components, all ``[B, K]``: ``omega`` (rad/s), ``kx``, ``ky`` (wavenumber components, rad/m),
    ``amplitude`` (m), ``phase`` (rad). ``weights_cos`` ``[B, K, 4]`` and ``weights_sin``
    ``[B, K, 2]`` are the derivative weights (a, −a kx², −a kx ky, −a ky²) and (a kx, a ky), cached
    so that an evaluation is one sin/cos pass and two batched matrix products. Build with
    :meth:`sample` or :meth:`from_components`; index or assign rows like any tensorclass
    (``surface[mask] = other[mask]`` resets a subset).
    """

    omega: torch.Tensor
    kx: torch.Tensor
    ky: torch.Tensor
    amplitude: torch.Tensor
    phase: torch.Tensor
    weights_cos: torch.Tensor
    weights_sin: torch.Tensor

    @classmethod
    def from_components(cls, omega, kx, ky, amplitude, phase) -> WaveSurface:
        """Build a surface from ``[B, K]`` component tensors (units as in the class docstring)."""
        weights_cos = torch.stack(
            (amplitude, -amplitude * kx * kx, -amplitude * kx * ky, -amplitude * ky * ky), dim=-1
        )
        weights_sin = torch.stack((amplitude * kx, amplitude * ky), dim=-1)
        return cls(
            omega=omega,
            kx=kx,
            ky=ky,
            amplitude=amplitude,
            phase=phase,
            weights_cos=weights_cos,
            weights_sin=weights_sin,
            batch_size=omega.shape[:1],
        )

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
    ) -> WaveSurface:
        """Draw ``batch_size`` independent realisations of ``sea``.

        Each realisation jitters every frequency uniformly inside its bin (so the surface does not
        repeat within an episode and the expected variance is the band's m0) and draws phases
        uniform in [0, 2π). Random numbers come from ``generator`` if given, else from a new
        generator seeded with ``seed`` (nondeterministic when both are None); they are drawn on
        the generator's device in float64, so a seed gives the same sea on CPU and CUDA.
        """
        batch = check_int("batch_size", batch_size, 1)
        if generator is None:
            generator = torch.Generator()
            if seed is None:
                generator.seed()
            else:
                generator.manual_seed(seed)
        draw_device = generator.device
        n_freq, n_dir = sea.n_freq, sea.n_dir

        edges = sea.frequency_bins(torch.float64, draw_device)
        d_omega = edges[1:] - edges[:-1]
        jitter = torch.rand(batch, n_freq, generator=generator, dtype=torch.float64, device=draw_device)
        omega = edges[:-1] + jitter * d_omega
        amplitude = sea.amplitudes(omega, d_omega.expand(batch, n_freq))
        theta, _ = sea.directions(torch.float64, draw_device)
        heading = theta + math.radians(sea.wind_direction_deg)
        wavenumber = (omega**2 / GRAVITY).unsqueeze(-1)
        kx = wavenumber * torch.cos(heading)
        ky = wavenumber * torch.sin(heading)
        phase = 2.0 * math.pi * torch.rand(
            batch, n_freq * n_dir, generator=generator, dtype=torch.float64, device=draw_device
        )

        def flat(values: torch.Tensor) -> torch.Tensor:
            return values.expand(batch, n_freq, n_dir).reshape(batch, -1).to(device=device, dtype=dtype)

        return cls.from_components(
            flat(omega.unsqueeze(-1)), flat(kx), flat(ky), flat(amplitude), phase.to(device=device, dtype=dtype)
        )

    @property
    def num_harmonics(self) -> int:
        """K, the number of harmonics per realisation."""
        return self.omega.shape[-1]

    def variance(self) -> torch.Tensor:
        """Discretised variance Σ a²/2 (m²) of each realisation, ``[B]``: its share of m0."""
        return 0.5 * (self.amplitude**2).sum(-1)

    def evaluate(self, x: torch.Tensor, y: torch.Tensor, t: float | torch.Tensor, order: int = 2) -> SurfaceSample:
        """Height and derivatives up to ``order`` (0, 1 or 2) at points ``(x, y)`` and time ``t``.

        Args:
            x, y: horizontal position (m), ``[B]`` (one point per realisation) or ``[B, P]``.
            t: time (s), a float or a ``[B]`` tensor.
            order: 0 for η only (one cos pass); 1 adds the slopes; 2 adds the second derivatives.
        """
        single = x.dim() == 1
        xs = x.unsqueeze(-1) if single else x
        ys = y.unsqueeze(-1) if single else y
        psi = self._argument(xs, ys, t)
        cos = torch.cos(psi)
        if order == 0:
            height = (cos * self.amplitude.unsqueeze(1)).sum(-1)
            return SurfaceSample(height=height.squeeze(-1) if single else height)
        even = torch.bmm(cos, self.weights_cos)
        odd = torch.bmm(torch.sin(psi), self.weights_sin)
        if single:
            even, odd = even.squeeze(1), odd.squeeze(1)
        sample = SurfaceSample(height=even[..., 0], dx=odd[..., 0], dy=odd[..., 1])
        if order >= 2:
            sample.dxx, sample.dxy, sample.dyy = even[..., 1], even[..., 2], even[..., 3]
        return sample

    def height(self, x: torch.Tensor, y: torch.Tensor, t: float | torch.Tensor) -> torch.Tensor:
        """η(x, y, t) in metres; shapes as in :meth:`evaluate`."""
        return self.evaluate(x, y, t, order=0).height

    def _argument(self, x: torch.Tensor, y: torch.Tensor, t: float | torch.Tensor) -> torch.Tensor:
        """Phase argument ψ = ω t + ε − kx x − ky y, ``[B, P, K]``."""
        if isinstance(t, torch.Tensor) and t.dim() > 0:
            t = t.unsqueeze(-1)
        time = torch.as_tensor(t, dtype=self.omega.dtype, device=self.omega.device)
        base = torch.addcmul(self.phase, self.omega, time)
        points = torch.stack((x, y), dim=-1)
        wavevector = torch.stack((self.kx, self.ky), dim=1)
        return torch.baddbmm(base.unsqueeze(1), points, wavevector, alpha=-1.0)
