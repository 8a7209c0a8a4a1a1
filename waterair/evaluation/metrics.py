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
received power) and ``rate_held`` and ``rate_held_999`` (the rates held in :data:`HELD_SHARE` and
:data:`STRICT_HELD_SHARE` of steps), each with bounds too."""
HELD = {"rate_held": HELD_SHARE, "rate_held_999": STRICT_HELD_SHARE}
"""The held rates and the share of steps each is held in."""
COMPARED = ("ratio_to_ub", "mean_gain", "rate", "outage", "rate_held", "rate_held_999")
"""What :func:`paired_comparison` compares of two policies on the same seas."""


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
    :data:`STRICT_HELD_SHARE` of all R·T steps (percentiles of steps; their bounds those of the same resamples'
    pooled steps, :func:`held_draws`).
    """
    link = link or LinkBudget()
    point, draws = _point_and_draws((gain, upper, reference, valid), link, _picks(gain.shape[0], resamples, seed))
    count, tail = gain.shape[0], (1.0 - level) / 2.0
    names = list(draws)
    bounds = torch.quantile(torch.stack(list(draws.values()), -1), torch.tensor([tail, 1.0 - tail]).double(), dim=0)
    out = {}
    for index, name in enumerate(names):
        out[name] = point[name]
        out[f"{name}_lo"] = bounds[0, index].item() if count > 1 else float("nan")
        out[f"{name}_hi"] = bounds[1, index].item() if count > 1 else float("nan")
    for suffix in ("", "_lo", "_hi"):
        out[f"received_power_dbm{suffix}"] = power_dbm(out[f"mean_gain{suffix}"] * link.received_power_per_gain)
    return out


def _picks(count: int, resamples: int, seed: int) -> torch.Tensor:
    """The realisations each of ``resamples`` bootstrap draws takes ``[resamples, count]``, seeded: the same for
    every policy of a point (the same seed and count), so that their intervals are paired."""
    return torch.randint(count, (resamples, count), generator=torch.Generator().manual_seed(seed))


def _point_and_draws(traces, link: LinkBudget, picks: torch.Tensor) -> tuple[dict[str, float], dict]:
    """The point values of :data:`METRICS` and the held rates of ``traces`` (gain, upper, reference, valid
    ``[R, T]``), and each one's bootstrap draws ``[resamples]`` over ``picks``."""
    gain, upper, reference, valid = traces
    delivered = link_performance(gain.double(), link)
    stats = _realisation_sums(gain, upper, reference, valid, delivered)
    steps = gain.shape[-1] * gain.shape[0]
    means, resampled = (
        _metrics_from_sums(stats.sum(0, keepdim=True), steps),
        _metrics_from_sums(stats[picks].sum(1), steps),
    )
    point = {name: means[0, index].item() for index, name in enumerate(METRICS)}
    draws = {name: resampled[:, index] for index, name in enumerate(METRICS)}
    rates = delivered.max_bit_rate.reshape(gain.shape[0], -1)
    for name, share in HELD.items():
        point[name] = torch.quantile(rates.flatten(), 1.0 - share).item()
        draws[name] = held_draws(rates, share, picks)
    return point, draws


def held_draws(rates: torch.Tensor, share: float, picks: torch.Tensor) -> torch.Tensor:
    """The rate held in ``share`` of the steps of each bootstrap resample ``[S]``: of ``rates`` ``[R, T]``, the
    realisations ``picks`` ``[S, R]`` draws, their steps pooled, the (1 − share) quantile by nearest rank. A
    weighted quantile of the sorted steps, each weighted by the times its realisation is drawn, over the fewest
    lowest steps that hold it in every resample."""
    count, steps = rates.shape
    weights = torch.zeros(picks.shape[0], count, dtype=torch.int64).scatter_add_(1, picks, torch.ones_like(picks))
    values, order = rates.reshape(-1).sort()
    owner, rank = order // steps, max(1, math.ceil((1.0 - share) * count * steps))
    prefix = min(values.numel(), 4 * rank)
    while True:  # the lowest steps cumulate the rank within 4 × rank in practice; more where a resample is skewed
        cumulative = weights[:, owner[:prefix]].cumsum(1)
        if prefix == values.numel() or bool((cumulative[:, -1] >= rank).all()):
            return values[(cumulative < rank).sum(1).clamp(max=prefix - 1)]
        prefix = min(values.numel(), 2 * prefix)


def paired_comparison(
    a, b, *, link: LinkBudget | None = None, level: float = 0.95, resamples: int = 2000, seed: int = 0
) -> dict[str, float]:
    """Policy ``a`` against ``b`` on the same seas, each ``(gain, upper, reference, valid)`` ``[R, T]`` as
    :func:`scenario_metrics` takes them: of each of :data:`COMPARED`, the difference ``<name>_diff`` and the ratio
    ``<name>_ratio`` (a over b; NaN over 0), each with ``_lo`` / ``_hi``, a paired bootstrap's percentile
    interval: every resample draws the same realisations for both (the picks :func:`scenario_metrics` draws with
    ``seed``), so that what the shared seas do to both cancels."""
    link, picks, tail = link or LinkBudget(), _picks(a[0].shape[0], resamples, seed), (1.0 - level) / 2.0
    (point_a, draws_a), (point_b, draws_b) = (_point_and_draws(traces, link, picks) for traces in (a, b))
    quantiles = torch.tensor([tail, 1.0 - tail], dtype=torch.float64)
    out = {}
    for name in COMPARED:
        ratio_point = point_a[name] / point_b[name] if point_b[name] != 0 else math.nan
        ratios = torch.where(draws_b[name] != 0, draws_a[name] / draws_b[name], math.nan)
        for kind, value, draws in (("diff", point_a[name] - point_b[name], draws_a[name] - draws_b[name]),
                                   ("ratio", ratio_point, ratios)):  # fmt: skip
            lo, hi = torch.quantile(draws, quantiles).tolist() if picks.shape[1] > 1 else (math.nan, math.nan)
            out |= {f"{name}_{kind}": value, f"{name}_{kind}_lo": lo, f"{name}_{kind}_hi": hi}
    return out


def verdict(low: float, high: float, even: float = 0.0) -> str:
    """What an interval [``low``, ``high``] of a difference (``even`` 0) or a ratio (``even`` 1) allows one to
    say: ``ahead`` where it lies above ``even``, ``behind`` below, else ``not separable`` (NaN too)."""
    return "ahead" if low > even else "behind" if high < even else "not separable"


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
            for suffix in ("", "_lo", "_hi") if name in METRICS or name in HELD else ("",):
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
