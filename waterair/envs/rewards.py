"""Rewards as functions of the normalised intensity I = G / G_0 (docs/model.md §7, paper Sec. IV-B).

* ``le`` (the paper's logarithm-exponential): R(I) = G_r (ln(a I + 1) + log10(b I) + exp(c I)) + B
* ``linear``: R(I) = I
* ``log``: R(I) = log10(max(I, floor))

Each may add a pointing term with a slope where no light arrives: R − pointing · m, where
m = α_D / ω_D + α_A / ω_A is the misalignment of both ends from the present path in units of the
beam divergence and the receiver's half field of view. Both the gain and −m peak at α_D = α_A = 0
(the upper bound's pointing), so the term moves no optimum; it gives a lost beam a way back.

log10(b I) is −∞ at I = 0, so that term uses max(I, floor). With a > 0, b > 0, c ≥ 0 and
G_r > 0 every term is non-decreasing and the log terms strictly increasing, so R is strictly
increasing in I above the floor (and constant-free of NaN/inf everywhere).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass

import torch

from waterair.core.validation import check_choice, check_range

REWARD_NAMES = ("le", "linear", "log")


@dataclass(frozen=True)
class Reward:
    """A validated reward of the normalised intensity I (dimensionless).

    Attributes:
        name: ``le``, ``linear`` or ``log`` (the ``reward`` group's option).
        a: ln-term coefficient, > 0.
        b: log10-term coefficient, > 0.
        c: exp-term coefficient, ≥ 0 (≤ 10, so that exp(c I) stays finite for I ≤ 10).
        gain: overall gain G_r, > 0.
        bias: additive bias B.
        floor: the smallest I fed to the log terms, in (0, 1).
        pointing: weight of the misalignment penalty, ≥ 0 (0: the reward of I alone).

    Defaults (a = 10, b = 100, c = 0.7, floor = 1e-3, gain = 0.1, bias = 0): over the intensities
    the environment produces (I ≈ 0 misaligned to I ≈ 1-2 aligned, see docs/environment.md) the
    three terms span comparable ranges on I in [0.05, 2] (ln(10 I + 1): 0.4 → 3.0, log10(100 I):
    0.7 → 2.3, exp(0.7 I): 1.0 → 4.1), so none dominates; R(0) = 0.1 (0 − 1 + 1) = 0, and gain 0.1
    keeps the LE reward in about [0, 0.9], a scale that suits a critic with a small discount (the paper: 0.2);
    the pointing term takes ``pointing`` per beam width of misalignment off it (below 0 far from the path).
    """

    name: str = "le"
    a: float = 10.0
    b: float = 100.0
    c: float = 0.7
    gain: float = 0.1
    bias: float = 0.0
    floor: float = 1e-3
    pointing: float = 0.0

    def __post_init__(self) -> None:
        check_choice("reward.name", self.name, REWARD_NAMES)
        check_range("reward.a", self.a, 0.0, 1e6, low_open=True)
        check_range("reward.b", self.b, 0.0, 1e12, low_open=True)
        check_range("reward.c", self.c, 0.0, 10.0)
        check_range("reward.gain", self.gain, 0.0, 1e6, low_open=True)
        check_range("reward.bias", self.bias, -1e6, 1e6)
        check_range("reward.floor", self.floor, 0.0, 1.0, low_open=True, high_open=True)
        check_range("reward.pointing", self.pointing, 0.0, 1e3)

    def __call__(self, intensity: torch.Tensor, misalignment: torch.Tensor | None = None) -> torch.Tensor:
        """Reward of intensity I ≥ 0 (any shape), less ``pointing`` × ``misalignment`` (same shape)
        when given; finite for every finite I in [0, 10]."""
        reward = self.of_intensity(intensity)
        if misalignment is None or self.pointing == 0.0:
            return reward
        return reward - self.pointing * misalignment

    def of_intensity(self, intensity: torch.Tensor) -> torch.Tensor:
        """The intensity part of the reward (the paper's, for ``le``)."""
        clamped = intensity.clamp(min=self.floor)
        if self.name == "linear":
            return intensity
        if self.name == "log":
            return torch.log10(clamped)
        terms = torch.log1p(self.a * intensity) + torch.log10(self.b * clamped) + torch.exp(self.c * intensity)
        return self.gain * terms + self.bias

    @classmethod
    def from_mapping(cls, values: Mapping) -> Reward:
        """Build from a plain mapping (a resolved ``reward`` group); unknown keys are errors."""
        known = [f.name for f in dataclasses.fields(cls)]
        unknown = sorted(set(values) - set(known))
        if unknown:
            raise ValueError(f"reward.{unknown[0]} is not a known key; allowed: {', '.join(known)}")
        return cls(**values)


def le_reward_terms(intensity: torch.Tensor, reward: Reward) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The three LE terms ln(aI + 1), log10(b max(I, floor)), exp(cI), for calibration plots."""
    return (
        torch.log1p(reward.a * intensity),
        torch.log10(reward.b * intensity.clamp(min=reward.floor)),
        torch.exp(reward.c * intensity),
    )


__all__ = ["REWARD_NAMES", "Reward", "le_reward_terms"]
