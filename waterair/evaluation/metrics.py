"""Alignment metrics (docs/model.md §8), as pure functions of gain tensors.

All take gains ``[R, T]`` (realisations × steps, 1/m²) and reduce over everything; confidence
intervals treat each realisation (one sea) as one independent sample, since steps of one sea are
strongly correlated. What the link delivers (BER, outage, rate) comes from the link budget,
:func:`waterair.physics.link.link_performance`, of each step's gain.
"""

from __future__ import annotations

import math

import torch

from waterair.physics.link import LinkBudget, link_performance

HELD_SHARE = 0.99
"""``rate_held`` is the bit rate the link sustains in this share of steps (its 1st percentile)."""
STRICT_HELD_SHARE = 0.999
"""``rate_held_999`` is the bit rate the link sustains in this share of steps (its 0.1st percentile)."""
ACQUISITION_SECONDS = 0.5
"""The first seconds of an episode, when a controller finds the link (its first readings come from the
gimbals parked at the reset): :func:`phase_metrics` reports them apart from the tracking after."""
PHASE_METRICS = ("ratio_to_ub", "rate", "outage", "rate_held", "rate_held_999")
"""What :func:`phase_metrics` reports of each phase, ``acquisition_<name>`` and ``tracking_<name>``."""
FADE_FRACTION = 0.1
"""A step is a 10 dB fade when G < 0.1 G_0 (docs/model.md §8): a fade, not an outage, which the link budget defines."""


def mean_gain(gain: torch.Tensor) -> float:
    """Mean channel gain (1/m²)."""
    return gain.double().mean().item()


def ratio_to_upper_bound(gain: torch.Tensor, upper: torch.Tensor) -> float:
    """mean(G) / mean(G_UB): 1 for perfect alignment."""
    return (gain.double().mean() / upper.double().mean()).item()


def sigma2_diff(gain: torch.Tensor, upper: torch.Tensor) -> float:
    """σ²_diff = var(G_UB − G) over all steps and realisations (the paper's stability metric)."""
    return (upper.double() - gain.double()).var(unbiased=False).item()


def fade_probability(gain: torch.Tensor, reference: torch.Tensor) -> float:
    """P(G < 0.1 G_0), the share of steps 10 dB or more below the calm-sea gain; ``reference`` is G_0,
    broadcastable against ``gain``."""
    return (gain < FADE_FRACTION * reference).double().mean().item()


METRICS = (
    "mean_gain",
    "ratio_to_ub",
    "sigma2_diff",
    "fade_10db",
    "valid_share",
    "mean_intensity",
    "ber",
    "outage",
    "rate",
)
"""What :func:`scenario_metrics` reports, each with ``_lo`` / ``_hi`` bounds: ``ber`` the mean bit error
rate, ``outage`` the share of steps with BER above the FEC limit, ``rate`` the mean bit rate at the FEC
limit (bit/s), all of the link budget. Beside them, :func:`scenario_metrics` gives ``received_power_dbm`` (the mean
received power, with bounds), ``rate_held`` and ``rate_held_999`` (the rates held in :data:`HELD_SHARE` and
:data:`STRICT_HELD_SHARE` of steps, no bounds)."""


def scenario_metrics(
    gain: torch.Tensor,
    upper: torch.Tensor,
    reference: torch.Tensor,
    valid: torch.Tensor,
    *,
    link: LinkBudget | None = None,
    level: float = 0.95,
    resamples: int = 2000,
    seed: int = 0,
) -> dict[str, float]:
    """Every metric (docs/model.md §8) of one scenario point, with bootstrap confidence bounds over realisations.

    ``gain``, ``upper`` (G_UB) and ``valid`` are ``[R, T]``; ``reference`` is G_0 per realisation
    ``[R]`` (or a scalar). The point values are the plain definitions over all R·T steps: mean G,
    mean(G)/mean(G_UB), var(G_UB − G), P(G < 0.1 G_0), the valid-path share, mean(G / G_0), and of
    ``link`` (default: :class:`LinkBudget`'s defaults) the mean BER, P(BER > FEC limit) and the mean
    bit rate at the FEC limit.
    Each gets ``<name>_lo`` / ``<name>_hi``: the percentile interval of ``resamples`` bootstrap
    draws of whole realisations (seeded, so a report is reproducible). Per-realisation sums are
    resampled, which is exact and costs O(resamples × R).
    Also ``received_power_dbm`` (10 log10 of the mean P_r in mW, bounds from the mean gain's: P_r is linear
    in G), ``rate_held`` and ``rate_held_999``, the bit rates sustained in :data:`HELD_SHARE` and
    :data:`STRICT_HELD_SHARE` of all R·T steps (percentiles of steps, given without bounds).
    """
    link = link or LinkBudget()
    delivered = link_performance(gain.double(), link)
    stats = _realisation_sums(gain, upper, reference, valid, delivered)
    point = _metrics_from_sums(stats.sum(0, keepdim=True), steps=gain.shape[-1] * gain.shape[0])
    generator = torch.Generator().manual_seed(seed)
    count = stats.shape[0]
    picks = torch.randint(count, (resamples, count), generator=generator)
    draws = _metrics_from_sums(stats[picks].sum(1), steps=gain.shape[-1] * count)
    tail = (1.0 - level) / 2.0
    bounds = torch.quantile(draws, torch.tensor([tail, 1.0 - tail], dtype=torch.float64), dim=0)
    out = {}
    for index, name in enumerate(METRICS):
        out[name] = point[0, index].item()
        out[f"{name}_lo"] = bounds[0, index].item() if count > 1 else float("nan")
        out[f"{name}_hi"] = bounds[1, index].item() if count > 1 else float("nan")
    for suffix in ("", "_lo", "_hi"):
        out[f"received_power_dbm{suffix}"] = power_dbm(out[f"mean_gain{suffix}"] * link.received_power_per_gain)
    rates = delivered.max_bit_rate.flatten()
    out["rate_held"] = torch.quantile(rates, 1.0 - HELD_SHARE).item()
    out["rate_held_999"] = torch.quantile(rates, 1.0 - STRICT_HELD_SHARE).item()
    return out


def phase_metrics(
    gain: torch.Tensor,
    upper: torch.Tensor,
    reference: torch.Tensor,
    valid: torch.Tensor,
    dt: float,
    *,
    link: LinkBudget | None = None,
    **bootstrap,
) -> dict[str, float]:
    """:data:`PHASE_METRICS` (with bounds where :func:`scenario_metrics` gives them) of the acquisition, the first
    :data:`ACQUISITION_SECONDS` of each realisation's steps (``dt`` s each), and of the tracking after it, as
    ``acquisition_<name>`` and ``tracking_<name>``; arguments as :func:`scenario_metrics`. Traces no longer than
    the acquisition have no tracking: NaN."""
    split = min(round(ACQUISITION_SECONDS / dt), gain.shape[-1])
    out = {}
    for phase, steps in (("acquisition", slice(None, split)), ("tracking", slice(split, None))):
        empty = gain[..., steps].shape[-1] == 0
        metrics = (
            {}
            if empty
            else scenario_metrics(
                gain[..., steps], upper[..., steps], reference, valid[..., steps], link=link, **bootstrap
            )
        )
        for name in PHASE_METRICS:
            for suffix in ("", "_lo", "_hi") if name in METRICS else ("",):
                out[f"{phase}_{name}{suffix}"] = metrics.get(f"{name}{suffix}", math.nan)
    return out


def power_dbm(watts: float) -> float:
    """10 log10(P / 1 mW); −inf for no light, NaN stays NaN."""
    return 10.0 * math.log10(watts * 1e3) if watts > 0 else (-math.inf if watts == 0 else math.nan)


def _realisation_sums(gain, upper, reference, valid, delivered) -> torch.Tensor:
    """``[R, 10]`` per-realisation sums: G, G_UB, D = G_UB − G, D², fades, valid steps, G / G_0, BER,
    outages, bit rates."""
    gain, upper = gain.double().reshape(gain.shape[0], -1), upper.double().reshape(gain.shape[0], -1)
    reference = torch.as_tensor(reference, dtype=torch.float64).reshape(-1, 1).expand(gain.shape[0], 1)
    diff = upper - gain
    delivered = delivered.reshape(gain.shape)
    columns = (
        gain,
        upper,
        diff,
        diff**2,
        (gain < FADE_FRACTION * reference).double(),
        valid.reshape(gain.shape[0], -1).double(),
        gain / reference,
        delivered.ber,
        delivered.outage.double(),
        delivered.max_bit_rate,
    )
    return torch.stack([c.sum(-1) for c in columns], dim=-1)


def _metrics_from_sums(sums: torch.Tensor, steps: int) -> torch.Tensor:
    """``[..., 10]`` summed statistics over ``steps`` samples → ``[..., len(METRICS)]`` in METRICS order."""
    g, u, d, d2, fade, valid, intensity, ber, outage, rate = sums.unbind(-1)
    variance = (d2 / steps - (d / steps) ** 2).clamp(min=0.0)
    ratio = torch.where(u > 0, g / u.clamp(min=1e-300), torch.zeros_like(g))  # no valid path at all: 0
    means = (fade, valid, intensity, ber, outage, rate)
    return torch.stack((g / steps, ratio, variance, *(m / steps for m in means)), dim=-1)
