"""Alignment metrics of SPEC §7, as pure functions of gain tensors.

All take gains ``[R, T]`` (realisations × steps, 1/m²) and reduce over everything; the
confidence interval treats each realisation's time average as one independent sample.
"""

from __future__ import annotations

import math

import torch
from tensordict import TensorDictBase

OUTAGE_FRACTION = 0.1
"""A step is an outage when G < 0.1 G_0 (SPEC §7)."""


def mean_gain(gain: torch.Tensor) -> float:
    """Mean channel gain (1/m²)."""
    return gain.double().mean().item()


def ratio_to_upper_bound(gain: torch.Tensor, upper: torch.Tensor) -> float:
    """mean(G) / mean(G_UB): 1 for perfect alignment."""
    return (gain.double().mean() / upper.double().mean()).item()


def sigma2_diff(gain: torch.Tensor, upper: torch.Tensor) -> float:
    """σ²_diff = var(G_UB − G) over all steps and realisations (the paper's stability metric)."""
    return (upper.double() - gain.double()).var(unbiased=False).item()


def outage_probability(gain: torch.Tensor, reference: torch.Tensor) -> float:
    """P(G < 0.1 G_0); ``reference`` is G_0, broadcastable against ``gain``."""
    return (gain < OUTAGE_FRACTION * reference).double().mean().item()


def confidence_interval(gain: torch.Tensor, level: float = 0.95) -> float:
    """Half-width of the normal confidence interval of the mean over realisations (rows)."""
    per_realisation = gain.double().reshape(gain.shape[0], -1).mean(-1)
    count = per_realisation.numel()
    if count < 2:
        return float("nan")
    z = math.sqrt(2.0) * torch.erfinv(torch.tensor(level, dtype=torch.float64)).item()
    return z * per_realisation.std(unbiased=True).item() / math.sqrt(count)


def summarise(rollout: TensorDictBase, reference_gain: torch.Tensor) -> dict[str, float]:
    """Every metric of a rollout ``[R, T]`` carrying ``("next", "gain")`` etc."""
    gain, upper = rollout["next", "gain"], rollout["next", "gain_upper_bound"]
    return {
        "mean_gain": mean_gain(gain),
        "mean_gain_ci95": confidence_interval(gain),
        "ratio_to_ub": ratio_to_upper_bound(gain, upper),
        "sigma2_diff": sigma2_diff(gain, upper),
        "outage": outage_probability(gain, reference_gain.reshape(-1, *([1] * (gain.dim() - 1)))),
        "valid_share": rollout["next", "path_valid"].double().mean().item(),
        "mean_intensity": rollout["next", "intensity"].double().mean().item(),
    }
