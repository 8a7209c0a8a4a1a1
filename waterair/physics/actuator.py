"""Pointing actuators: a second-order axis with range, rate, acceleration and resolution limits (docs/model.md §11).

Each axis obeys

    θ̈ = ω_n² (u − θ) − 2 ζ ω_n θ̇

with the command u held over a step (zero-order hold). Over a step of Δt the state (θ − u, θ̇) moves by the
matrix exponential Φ = exp(A Δt), A = [[0, 1], [−ω_n², −2 ζ ω_n]], in closed form in float64 (Python floats):
exact at any Δt, however stiff the axis. Only where a limit binds (the rate, the
acceleration, the range) is the step split into sub-steps, each the exact response over its length, then
projected onto the limits (:func:`respond`): the state a step reports never exceeds them.

A coarse gimbal carrying a fine mirror (:func:`respond_pair`) points where the gimbal reaches plus what the mirror
adds within its range, the mirror commanded to the rest: the realistic terminal of a free-space optical link.

Angles are in radians, rates in rad/s, and every tensor ``[..., axes]``: the functions act elementwise.
:class:`Actuator` is an end's terminal as a configuration names it (``env.actuator.*``): no actuator (``ideal``), a
gimbal, a fixed mount with a mirror, or a gimbal carrying a mirror; :func:`respond_terminal` steps it.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import NamedTuple

import torch

from waterair.core.validation import check_choice, check_range

SUBSTEPS = 16
"""Sub-steps of a step where a limit binds: a slew at the rate limit is resolved to Δt / 16 (3 ms at 50 ms)."""


@dataclass(frozen=True)
class Axis:
    """One pointing axis (the presets and their sources in docs/model.md §11).

    Attributes:
        range: the largest deflection from the axis's centre |θ| (rad), in (0, π/2].
        rate: the largest angular rate |θ̇| (rad/s), in (0, inf] (inf: no limit).
        acceleration: the largest angular acceleration |θ̈| (rad/s²), in (0, inf] (inf: no limit).
        natural_frequency: f_n = ω_n / 2π of the closed loop (Hz), in (0, 1e5].
        damping: ζ, in (0, 10].
        resolution: the smallest step of the command (rad), in [0, 0.01] (0: continuous).
    """

    range: float = math.pi / 4
    rate: float = math.inf
    acceleration: float = math.inf
    natural_frequency: float = 10.0
    damping: float = 0.7
    resolution: float = 0.0

    def __post_init__(self) -> None:
        for name, low, high, unit in (
            ("range", 0.0, math.pi / 2, "rad"),
            ("rate", 0.0, math.inf, "rad/s"),
            ("acceleration", 0.0, math.inf, "rad/s²"),
            ("natural_frequency", 0.0, 1.0e5, "Hz"),
            ("damping", 0.0, 10.0, ""),
        ):
            object.__setattr__(self, name, check_range(name, getattr(self, name), low, high, low_open=True, unit=unit))
        object.__setattr__(self, "resolution", check_range("resolution", self.resolution, 0.0, 0.01, unit="rad"))

    @property
    def omega(self) -> float:
        """ω_n (rad/s)."""
        return 2.0 * math.pi * self.natural_frequency

    def transition(self, dt: float) -> tuple[tuple[float, float], tuple[float, float]]:
        """Φ = exp(A ``dt``) as two rows of floats (float64): (θ − u, θ̇) after ``dt`` is Φ · (θ − u, θ̇) before.

        In closed form, in plain Python, uncached (a compiled step traces it to constants, a cache wrapper would only
        warn): with A's eigenvalues
        s ± q, s = −ζ ω_n, q² = s² − ω_n², exp(A t) = a₀ I + a₁ A, a₀ = e^{st} (cosh qt − s sinh(qt)/q),
        a₁ = e^{st} sinh(qt)/q (cos and sin for q² < 0; a₁ = t e^{st} at q = 0), the overdamped one from the two
        exponentials, so no term overflows."""
        w, z = self.omega, self.damping
        s, d = -z * w, (z * w) ** 2 - w**2
        if d > 0.0:  # overdamped: e^{(s ± q) t}, both decaying
            q = math.sqrt(d)
            fast, slow = math.exp((s - q) * dt), math.exp((s + q) * dt)
            even, odd = 0.5 * (slow + fast), (slow - fast) / (2.0 * q)
        elif d < 0.0:
            q, decay = math.sqrt(-d), math.exp(s * dt)
            even, odd = decay * math.cos(q * dt), decay * math.sin(q * dt) / q
        else:
            even, odd = math.exp(s * dt), dt * math.exp(s * dt)
        a0, a1 = even - s * odd, odd
        return (a0, a1), (-(w**2) * a1, a0 - 2.0 * z * w * a1)

    def sampled_lag(self, dt: float) -> float:
        """How far (s) the axis trails a ramp at the ends of steps of ``dt``, once settled, when each step commands
        (held) the ramp's value at the step's end, within the limits: 2 ζ / ω_n − Δt / 2 for a slow axis, 0 for one
        that settles within the step. At the step ends the error e = θ − r and the rate repeat: e = c (e − Δt),
        c = p00 + p01 p10 / (1 − p11) (Φ's entries), so the lag is c Δt / (1 − c)."""
        (p00, p01), (p10, p11) = self.transition(dt)
        c = p00 + p01 * p10 / (1.0 - p11)
        return c * dt / (1.0 - c)

    @property
    def limited(self) -> bool:
        """Whether a rate or an acceleration limit is set (else only the range can bind)."""
        return math.isfinite(self.rate) or math.isfinite(self.acceleration)


class AxisState(NamedTuple):
    """Where an axis points ``angle`` (rad) and how fast it turns ``rate`` (rad/s), ``[..., axes]`` each."""

    angle: torch.Tensor
    rate: torch.Tensor


def command(axis: Axis, target: torch.Tensor) -> torch.Tensor:
    """The command the axis takes for a ``target`` angle: within its range, on its resolution's grid."""
    if axis.resolution > 0.0:
        target = torch.round(target / axis.resolution) * axis.resolution
    return target.clamp(-axis.range, axis.range)


def _exact(phi, state: AxisState, u: torch.Tensor) -> AxisState:
    """The zero-order-hold response over the step ``phi`` (:meth:`Axis.transition`) to the held command ``u``."""
    (p00, p01), (p10, p11) = phi
    error = state.angle - u
    return AxisState(u + p00 * error + p01 * state.rate, p10 * error + p11 * state.rate)


def respond(axis: Axis, state: AxisState, target: torch.Tensor, dt: float) -> AxisState:
    """The axis after a step of ``dt`` (s) commanded toward ``target`` (rad) from ``state``.

    The exact response (:meth:`Axis.transition`) where no limit binds. Where one does, at any of
    :data:`SUBSTEPS` points of the step, the step is taken in that many sub-steps: each the exact response
    over its length, its change in rate then held to the acceleration limit times the sub-step, its rate to the
    rate limit, and its change in angle to what the limited rate gives (the mean of the two rates over the
    sub-step); the angle is then held in the range, the rate stopped where it is. The result never exceeds
    a limit; no branch on data (a compiled step computes both and selects).
    """
    u = command(axis, target)
    whole = _exact(axis.transition(dt), state, u)
    if not axis.limited:
        return _stopped(axis, whole)
    inside = (whole.angle.abs() <= axis.range) & (whole.rate.abs() <= axis.rate)
    h = dt / SUBSTEPS
    phi = axis.transition(h)
    angle, rate = state.angle, state.rate
    for _ in range(SUBSTEPS):
        free = _exact(phi, AxisState(angle, rate), u)
        wanted = free.rate - rate
        change = wanted.clamp(-axis.acceleration * h, axis.acceleration * h)
        reached = rate + change
        new_rate = reached.clamp(-axis.rate, axis.rate)
        # a limit binds where a clamp changed its value (exact where it did not); rate + (free.rate - rate) itself
        # differs from free.rate in its last bit on about one sub-step in 15
        bound = (change != wanted) | (new_rate != reached)
        inside = inside & ~bound
        mean = 0.5 * (rate + new_rate) * h
        moved = torch.where(bound, mean, free.angle - angle)
        angle, rate = _stopped(axis, AxisState(angle + moved, new_rate))
        inside = inside & (angle.abs() < axis.range)
    return AxisState(torch.where(inside, whole.angle, angle), torch.where(inside, whole.rate, rate))


def _stopped(axis: Axis, state: AxisState) -> AxisState:
    """``state`` held inside the range, its rate zero where it met the stop."""
    angle = state.angle.clamp(-axis.range, axis.range)
    return AxisState(angle, torch.where(angle != state.angle, torch.zeros_like(state.rate), state.rate))


class PairState(NamedTuple):
    """A coarse ``gimbal`` carrying a fine ``mirror`` (:class:`AxisState` each); it points at their sum."""

    gimbal: AxisState
    mirror: AxisState

    @property
    def angle(self) -> torch.Tensor:
        return self.gimbal.angle + self.mirror.angle


def respond_pair(gimbal: Axis, mirror: Axis, state: PairState, target: torch.Tensor, dt: float) -> PairState:
    """A gimbal and its mirror after a step toward ``target``: the gimbal commanded to the target, the mirror to
    what the gimbal leaves at the step's end (its inner loop reads the gimbal's encoder far faster than the
    step), within the mirror's range."""
    coarse = respond(gimbal, state.gimbal, target, dt)
    return PairState(coarse, respond(mirror, state.mirror, target - coarse.angle, dt))


TERMINALS = ("ideal", "gimbal", "fsm", "gimbal_fsm")
"""What points an end (``env.actuator.kind``): nothing (each step's command is reached at once), a gimbal, a fast
steering mirror on a mount fixed along the calm-sea path, or a gimbal carrying a mirror."""
DRIVE_WIDTH = 4
"""An axis's drive state as the environment keeps it: the gimbal's angle and rate, the mirror's angle and rate."""


@dataclass(frozen=True)
class Actuator:
    """Each end's pointing actuators, the same at both (docs/model.md §11: the presets, their sources).

    Attributes:
        kind: one of :data:`TERMINALS`.
        gimbal_range ... gimbal_resolution: the gimbal's :class:`Axis` (both of its axes alike).
        mirror_range ... mirror_resolution: the mirror's :class:`Axis`, its range and resolution those of the
            beam's direction (twice the mirror's mechanical angle); its rate and acceleration are its response's.
    """

    kind: str = "ideal"
    gimbal_range: float = math.pi / 4
    gimbal_rate: float = 2.1
    gimbal_acceleration: float = 35.0
    gimbal_natural_frequency: float = 8.0
    gimbal_damping: float = 0.7
    gimbal_resolution: float = 1.0e-4
    mirror_range: float = 0.0524
    mirror_natural_frequency: float = 585.0
    mirror_damping: float = 0.4
    mirror_resolution: float = 2.0e-6

    def __post_init__(self) -> None:
        check_choice("kind", self.kind, TERMINALS)
        for name, build in (("gimbal", lambda: self.gimbal), ("mirror", lambda: self.mirror)):
            try:
                build()
            except ValueError as error:
                raise ValueError(f"{name}_{error}") from None

    @functools.cached_property
    def gimbal(self) -> Axis:
        return Axis(self.gimbal_range, self.gimbal_rate, self.gimbal_acceleration, self.gimbal_natural_frequency,
                    self.gimbal_damping, self.gimbal_resolution)  # fmt: skip

    @functools.cached_property
    def mirror(self) -> Axis:
        return Axis(self.mirror_range, math.inf, math.inf, self.mirror_natural_frequency, self.mirror_damping,
                    self.mirror_resolution)  # fmt: skip

    @property
    def moves(self) -> bool:
        """Whether the ends have actuators at all (``ideal``: the command is the pointing)."""
        return self.kind != "ideal"

    def lag(self, dt: float) -> float:
        """How far (s) the pointing trails a slowly turning command given once per step of ``dt`` for the step's
        end (:meth:`Axis.sampled_lag`): the mirror's, where a mirror takes out what the gimbal leaves, the gimbal's
        alone, none without actuators."""
        if not self.moves:
            return 0.0
        return (self.gimbal if self.kind == "gimbal" else self.mirror).sampled_lag(dt)

    @property
    def fixed_mount(self) -> bool:
        """Whether the mirror sits on a mount fixed along the calm-sea path (``fsm``), not on a gimbal."""
        return self.kind == "fsm"


def respond_terminal(actuator: Actuator, drive: torch.Tensor, target: torch.Tensor, dt: float) -> torch.Tensor:
    """The drive state ``[..., axes, DRIVE_WIDTH]`` (:data:`DRIVE_WIDTH`) after a step of ``dt`` toward the ``target``
    angles ``[..., axes]`` (rad, from the terminal's mount), and the angles the terminal points at are its
    :func:`terminal_angle`."""
    gimbal, mirror = AxisState(drive[..., 0], drive[..., 1]), AxisState(drive[..., 2], drive[..., 3])
    if actuator.kind == "gimbal":
        gimbal = respond(actuator.gimbal, gimbal, target, dt)
    elif actuator.kind == "fsm":
        mirror = respond(actuator.mirror, mirror, target, dt)
    elif actuator.kind == "gimbal_fsm":
        gimbal, mirror = respond_pair(actuator.gimbal, actuator.mirror, PairState(gimbal, mirror), target, dt)
    else:
        raise ValueError(f"respond_terminal needs an actuator; {actuator.kind!r} points at once")
    return torch.stack((gimbal.angle, gimbal.rate, mirror.angle, mirror.rate), dim=-1)


def terminal_angle(drive: torch.Tensor) -> torch.Tensor:
    """Where a terminal's axes ``[..., axes]`` point, from its mount: the gimbal's angle plus the mirror's."""
    return drive[..., 0] + drive[..., 2]
