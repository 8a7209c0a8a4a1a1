"""Rewards of the normalised intensity I = G / G_0 or of the link (docs/model.md §7, paper Sec. IV-B).

* ``le`` (the paper's logarithm-exponential): R(I) = G_r (ln(a I + 1) + log10(b I) + exp(c I)) + B
* ``linear``: R(I) = I
* ``log``: R(I) = log10(max(I, floor))
* ``snr``: of the link budget (docs/model.md §9): with P_r the received power of G and P_FEC the
  power at the FEC limit, R = log10(SNR(P_r) / SNR(P_FEC)) where the link is up (0 at the limit),
  and slope · (P_r / P_FEC − 1) below it (from −slope at no light up to 0), so that a link in
  outage still has a gradient toward the limit.

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
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import torch

from waterair.core.validation import check_choice, check_range
from waterair.physics.link import LinkBudget, fec_power, received_power, snr

GAIN_REWARDS = ("snr",)
"""The rewards of the gain G, through the link budget (:meth:`Reward.of_gain`)."""


@dataclass(frozen=True)
class Reward:
    """A validated reward of the normalised intensity I (dimensionless).

    Attributes:
        name: ``le``, ``linear``, ``log`` or ``snr`` (the ``reward`` group's option).
        a: ln-term coefficient, > 0.
        b: log10-term coefficient, > 0.
        c: exp-term coefficient, ≥ 0 (≤ 10, so that exp(c I) stays finite for I ≤ 10).
        gain: overall gain G_r, > 0.
        bias: additive bias B.
        floor: the smallest I fed to the log terms, in (0, 1).
        pointing: weight of the misalignment penalty, ≥ 0 (0: the reward of I alone).
        slope: ``snr`` only: the reward at no light is −slope, in (0, 100].
        link: ``snr`` only: the link budget (the ``link`` group with the channel's optics).

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
    slope: float = 1.0
    link: LinkBudget | None = None
    limit: tuple[float, float] = field(init=False, default=(math.nan, math.nan), repr=False, compare=False)
    """``snr``: P_FEC (W) and SNR(P_FEC), computed once here so that the step needs no host work."""

    def __post_init__(self) -> None:
        check_choice("reward.name", self.name, (*INTENSITY_REWARDS, *GAIN_REWARDS))
        check_range("reward.a", self.a, 0.0, 1e6, low_open=True)
        check_range("reward.b", self.b, 0.0, 1e12, low_open=True)
        check_range("reward.c", self.c, 0.0, 10.0)
        check_range("reward.gain", self.gain, 0.0, 1e6, low_open=True)
        check_range("reward.bias", self.bias, -1e6, 1e6)
        check_range("reward.floor", self.floor, 0.0, 1.0, low_open=True, high_open=True)
        check_range("reward.pointing", self.pointing, 0.0, 1e3)
        check_range("reward.slope", self.slope, 0.0, 100.0, low_open=True)
        if self.name in GAIN_REWARDS and self.link is None:
            raise ValueError(f"reward.name = {self.name!r} needs the link group (link: the budget it reads)")
        if self.link is not None:
            power = fec_power(self.link)
            at_limit = snr(torch.tensor(power, dtype=torch.float64), *self._noise()).item()
            object.__setattr__(self, "limit", (power, at_limit))

    def __call__(
        self,
        intensity: torch.Tensor,
        misalignment: torch.Tensor | None = None,
        gain: torch.Tensor | None = None,
        divergence: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """Reward of intensity I ≥ 0 (any shape), or of the gain G (1/m², same shape; ``snr``, through a beam of
        each link's ``divergence`` ``[B]`` where given), less ``pointing`` × ``misalignment`` (same shape) when
        given; finite for every finite I in [0, 10]."""
        if self.name in GAIN_REWARDS:
            if gain is None:
                raise ValueError(f"reward.name = {self.name!r} is a reward of the gain; call it with gain=")
            reward = self.of_gain(gain, divergence)
        else:
            reward = INTENSITY_REWARDS[self.name](self, intensity)
        if misalignment is None or self.pointing == 0.0:
            return reward
        return reward - self.pointing * misalignment

    def of_gain(self, gain: torch.Tensor, divergence: torch.Tensor | None = None) -> torch.Tensor:
        """The ``snr`` reward of channel gains G (1/m²): log10 SNR relative to the FEC limit, a slope below it;
        the received power through each link's beam where ``divergence`` ``[B]`` is given, else the budget's."""
        assert self.link is not None  # __post_init__ guarantees it for snr
        limit, at_limit = self.limit
        power = received_power(gain, self.link, divergence)
        above = torch.log10(snr(power.clamp(min=limit), *self._noise()) / at_limit)
        return torch.where(power >= limit, above, self.slope * (power / limit - 1.0))

    def _noise(self) -> tuple:
        assert self.link is not None
        return self.link.background_power, self.link.receiver, self.link.bandwidth

    @classmethod
    def from_mapping(cls, values: Mapping, link: LinkBudget | None = None) -> Reward:
        """Build from a plain mapping (a resolved ``reward`` group) and the link budget; unknown keys are errors."""
        known = [f.name for f in dataclasses.fields(cls) if f.init and f.name != "link"]
        unknown = sorted(set(values) - set(known))
        if unknown:
            raise ValueError(f"reward.{unknown[0]} is not a known key; allowed: {', '.join(known)}")
        return cls(**values, link=link)


def le_reward_terms(intensity: torch.Tensor, reward: Reward) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The three LE terms ln(aI + 1), log10(b max(I, floor)), exp(cI) (also for calibration plots)."""
    return (
        torch.log1p(reward.a * intensity),
        torch.log10(reward.b * intensity.clamp(min=reward.floor)),
        torch.exp(reward.c * intensity),
    )


def le_reward(reward: Reward, intensity: torch.Tensor) -> torch.Tensor:
    """The paper's logarithm-exponential reward G_r (ln(aI + 1) + log10(b I) + exp(cI)) + B."""
    ln_term, log_term, exp_term = le_reward_terms(intensity, reward)
    return reward.gain * (ln_term + log_term + exp_term) + reward.bias


INTENSITY_REWARDS: dict[str, Callable[[Reward, torch.Tensor], torch.Tensor]] = {
    "le": le_reward,
    "linear": lambda reward, intensity: intensity,
    "log": lambda reward, intensity: torch.log10(intensity.clamp(min=reward.floor)),
}
"""The rewards of the intensity I by name (the ``reward`` group's options), each ``f(reward, I)``."""
REWARD_NAMES = (*INTENSITY_REWARDS, *GAIN_REWARDS)
"""Every reward's name: a new one is a function of (reward, I) added to :data:`INTENSITY_REWARDS`."""


__all__ = ["REWARD_NAMES", "Reward", "le_reward_terms"]
