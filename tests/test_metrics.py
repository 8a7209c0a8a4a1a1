"""Metrics (docs/model.md §8) on synthetic gain arrays whose answers are known in closed form."""

import math

import pytest
import torch

from waterair.evaluation.metrics import (
    COMPARED,
    HELD,
    METRICS,
    PHASE_METRICS,
    fade_probability,
    held_draws,
    paired_comparison,
    phase_metrics,
    ratio_to_upper_bound,
    scenario_metrics,
    sigma2_diff,
    verdict,
)
from waterair.physics.link import LinkBudget, fec_power, link_performance


def test_sigma2_diff_of_a_known_difference():
    # G_UB − G alternates between 1 and 3 (mean 2): the population variance is exactly 1.
    upper = torch.full((4, 6), 5.0)
    gain = upper - torch.tensor([1.0, 3.0]).repeat(4, 3)
    assert sigma2_diff(gain, upper) == pytest.approx(1.0, abs=1e-12)
    # A constant shortfall has no variance, however large it is.
    assert sigma2_diff(upper - 2.5, upper) == pytest.approx(0.0, abs=1e-12)


def test_fade_counts_steps_below_a_tenth_of_the_reference():
    gain = torch.tensor([[0.05, 0.2, 0.09, 1.0], [0.1, 0.11, 0.0, 0.5]])
    # references 1 and 2: thresholds 0.1 and 0.2; fades 0.05, 0.09 | 0.1, 0.11, 0.0
    reference = torch.tensor([[1.0], [2.0]])
    assert fade_probability(gain, reference) == pytest.approx(5 / 8)


@pytest.mark.parametrize("link", [LinkBudget(), LinkBudget(background_radiance=0.0, bit_rate=2e7)], ids=["day", "dark"])
def test_link_metrics_are_the_budget_of_each_step_and_outage_starts_at_the_fec_power(link):
    # Gains spread over a decade either side of the FEC limit's gain, so that some steps are in outage.
    threshold = fec_power(link) / link.received_power_per_gain
    gain = threshold * 10.0 ** (2.0 * torch.rand(6, 40, generator=torch.Generator().manual_seed(2)) - 1.0)
    gain = gain.double()
    m = scenario_metrics(gain, gain * 2.0, torch.ones(6), torch.ones(6, 40, dtype=torch.bool), link=link)
    delivered = link_performance(gain, link)
    assert m["outage"] == pytest.approx((gain < threshold).double().mean().item())  # (9.13) ⟺ P_r < P_FEC
    assert 0.0 < m["outage"] < 1.0
    assert m["ber"] == pytest.approx(delivered.ber.mean().item(), rel=1e-12)
    assert m["rate"] == pytest.approx(delivered.max_bit_rate.mean().item(), rel=1e-12)
    for name in ("ber", "outage", "rate", "received_power_dbm"):
        assert m[f"{name}_lo"] <= m[name] <= m[f"{name}_hi"], name
    power = (gain * link.received_power_per_gain).mean().item()
    assert m["received_power_dbm"] == pytest.approx(10 * math.log10(power / 1e-3), abs=1e-12)
    # the rate held 99 % of the time: 1 % of the 240 steps (2.4) sustain less, by the sorted list
    ordered = delivered.max_bit_rate.flatten().sort().values
    assert ordered[2] <= m["rate_held"] <= ordered[3] and m["rate_held"] < m["rate"]
    # held 99.9 % of the time: 0.24 of the 240 steps sustain less, between the two slowest
    assert ordered[0] <= m["rate_held_999"] <= ordered[1] and m["rate_held_999"] <= m["rate_held"]


def test_ratio_to_upper_bound_is_a_ratio_of_means_not_a_mean_of_ratios():
    gain = torch.tensor([[1.0, 0.0]])
    upper = torch.tensor([[1.0, 3.0]])
    assert ratio_to_upper_bound(gain, upper) == pytest.approx(0.25)


def test_scenario_metrics_point_values_match_the_plain_definitions():
    generator = torch.Generator().manual_seed(1)
    upper = 1.0 + torch.rand(8, 50, generator=generator, dtype=torch.float64)
    gain = upper * torch.rand(8, 50, generator=generator, dtype=torch.float64)
    reference = 1.0 + torch.rand(8, generator=generator, dtype=torch.float64)
    valid = torch.rand(8, 50, generator=generator) > 0.2
    m = scenario_metrics(gain, upper, reference, valid)
    named = (*METRICS, "received_power_dbm", *HELD)
    assert {f"{k}{suffix}" for k in named for suffix in ("", "_lo", "_hi")} == set(m)
    assert m["mean_gain"] == pytest.approx(gain.mean().item(), rel=1e-12)
    assert m["ratio_to_ub"] == pytest.approx((gain.mean() / upper.mean()).item(), rel=1e-12)
    assert m["sigma2_diff"] == pytest.approx((upper - gain).var(unbiased=False).item(), rel=1e-9)
    assert m["fade_10db"] == pytest.approx((gain < 0.1 * reference[:, None]).double().mean().item())
    assert m["valid_share"] == pytest.approx(valid.double().mean().item())
    assert m["mean_intensity"] == pytest.approx((gain / reference[:, None]).mean().item(), rel=1e-12)
    for name in METRICS:
        assert m[f"{name}_lo"] <= m[name] <= m[f"{name}_hi"], name


def test_upper_bound_against_itself_has_ratio_one_and_no_spread():
    upper = 1.0 + torch.rand(16, 40, dtype=torch.float64)
    m = scenario_metrics(upper, upper, torch.ones(16), torch.ones(16, 40, dtype=torch.bool))
    assert m["ratio_to_ub"] == 1.0 and m["sigma2_diff"] == 0.0
    assert m["ratio_to_ub_lo"] == m["ratio_to_ub_hi"] == 1.0
    assert m["sigma2_diff_hi"] == 0.0


def test_bootstrap_interval_matches_the_normal_interval_of_independent_realisations():
    # Each realisation is a constant level drawn from N(1, 0.2²): the mean's 95 % interval is
    # ±1.96·0.2/√R around the sample mean; the bootstrap must agree to within sampling error.
    count = 400
    levels = 1.0 + 0.2 * torch.randn(count, 1, generator=torch.Generator().manual_seed(3), dtype=torch.float64)
    gain = levels.expand(count, 30)
    m = scenario_metrics(gain, gain + 1.0, torch.ones(count), torch.ones(count, 30, dtype=torch.bool))
    half_width = (m["mean_gain_hi"] - m["mean_gain_lo"]) / 2
    expected = 1.959964 * levels.std().item() / math.sqrt(count)
    assert half_width == pytest.approx(expected, rel=0.1)
    # Realisations that are all the same leave no uncertainty.
    flat = scenario_metrics(torch.ones(5, 7), torch.full((5, 7), 2.0), torch.ones(5), torch.ones(5, 7))
    assert flat["mean_gain_lo"] == flat["mean_gain_hi"] == 1.0


def test_no_valid_path_anywhere_gives_ratio_zero_not_nan():
    zeros = torch.zeros(3, 4)
    m = scenario_metrics(zeros, zeros, torch.ones(3), torch.zeros(3, 4, dtype=torch.bool))
    assert m["ratio_to_ub"] == 0.0 and m["valid_share"] == 0.0 and m["fade_10db"] == 1.0
    assert m["outage"] == 1.0 and m["ber"] == 0.5 and m["rate"] == 0.0


def test_the_acquisition_and_the_tracking_are_measured_apart():
    """The first 0.5 s (10 steps of 50 ms) against the rest: each phase's metrics are those of its own steps
    alone, so a policy that is blind while it acquires and perfect after shows a ratio of 0 and 1."""
    generator = torch.Generator().manual_seed(2)
    upper = 1.0 + torch.rand(5, 60, generator=generator, dtype=torch.float64)
    gain = upper.clone()
    gain[:, :10] = 0.0
    reference, valid = torch.ones(5, dtype=torch.float64), torch.ones(5, 60, dtype=torch.bool)
    link = LinkBudget()
    phases = phase_metrics(gain, upper, reference, valid, 0.05, link=link)
    assert phases["acquisition_ratio_to_ub"] == 0.0 and phases["tracking_ratio_to_ub"] == 1.0
    tracking = scenario_metrics(gain[:, 10:], upper[:, 10:], reference, valid[:, 10:], link=link)
    for name in PHASE_METRICS:
        assert phases[f"tracking_{name}"] == tracking[name], name
    assert phases["acquisition_rate"] == 0.0 < phases["tracking_rate_held_999"]
    assert {"tracking_rate_lo", "acquisition_outage_hi", "tracking_rate_held_lo"} <= set(phases)
    # a trace no longer than the acquisition has no tracking
    short = phase_metrics(gain[:, :8], upper[:, :8], reference, valid[:, :8], 0.05, link=link)
    assert math.isnan(short["tracking_rate_held"]) and short["acquisition_ratio_to_ub"] == 0.0


def _traces(gain: torch.Tensor) -> tuple:
    """A policy's traces as the metrics take them: its gain, an upper bound above it, G_0 = 1, every path valid."""
    return gain, gain.max() + torch.ones_like(gain), torch.ones(gain.shape[0]), torch.ones_like(gain, dtype=torch.bool)


def test_the_held_rates_bootstrap_pools_each_resamples_seas_as_a_direct_pooling_does():
    """Each resample's held rate (a weighted quantile over the lowest steps) against the resample built by hand:
    the drawn realisations' steps pooled, sorted, the nearest-rank (1 − share) quantile, in float64."""
    generator = torch.Generator().manual_seed(5)
    rates = torch.rand(12, 50, generator=generator, dtype=torch.float64) * torch.rand(12, 1, generator=generator)
    picks = torch.randint(12, (40, 12), generator=generator)
    for share in (0.99, 0.9, 0.5):
        drawn = held_draws(rates, share, picks)
        for k in range(picks.shape[0]):
            pooled = rates[picks[k]].flatten().sort().values
            assert drawn[k].item() == pooled[math.ceil((1.0 - share) * pooled.numel()) - 1].item()


def test_every_row_bounds_its_held_rates_and_one_sea_leaves_them_open():
    gain = torch.rand(20, 60, generator=torch.Generator().manual_seed(2), dtype=torch.float64) * 1e-3
    m = scenario_metrics(*_traces(gain))
    for name in HELD:
        assert m[f"{name}_lo"] <= m[name] <= m[f"{name}_hi"] and m[f"{name}_lo"] < m[f"{name}_hi"], name
    one = scenario_metrics(*_traces(gain[:1]))
    assert all(math.isnan(one[f"{name}_lo"]) for name in HELD)


def test_a_policy_against_itself_differs_by_exactly_nothing_and_against_a_scaled_copy_by_the_scale():
    gain = torch.rand(16, 40, generator=torch.Generator().manual_seed(4), dtype=torch.float64) * 1e-3
    same = paired_comparison(_traces(gain), _traces(gain))
    for name in COMPARED:
        assert same[f"{name}_diff"] == same[f"{name}_diff_lo"] == same[f"{name}_diff_hi"] == 0.0, name
    upper = _traces(gain)[1]
    scaled = paired_comparison((1.1 * gain, *_traces(gain)[1:]), (gain, upper, *_traces(gain)[2:]))
    for name in ("mean_gain", "ratio_to_ub"):
        assert scaled[f"{name}_ratio"] == pytest.approx(1.1)
        assert scaled[f"{name}_ratio_lo"] <= 1.1 + 1e-12 and 1.1 - 1e-12 <= scaled[f"{name}_ratio_hi"], name
    assert (
        scaled["mean_gain_diff_lo"] > 0 and verdict(scaled["mean_gain_diff_lo"], scaled["mean_gain_diff_hi"]) == "ahead"
    )


def test_pairing_cancels_what_the_shared_seas_do_to_both_policies():
    """Two policies whose gains follow the same seas (a level per realisation, spread 50 %) and differ by 1 %:
    paired, the difference is known far better than either policy's mean, and the later is ahead."""
    generator = torch.Generator().manual_seed(6)
    seas = 1.0 + 0.5 * torch.rand(24, 1, generator=generator, dtype=torch.float64)
    a = seas * (1.0 + 0.02 * torch.rand(24, 30, generator=generator, dtype=torch.float64)) * 1e-3
    b = 1.01 * a
    alone = scenario_metrics(*_traces(a))
    paired = paired_comparison(_traces(b), (a, *_traces(b)[1:]))
    width = paired["mean_gain_diff_hi"] - paired["mean_gain_diff_lo"]
    assert width < 0.1 * (alone["mean_gain_hi"] - alone["mean_gain_lo"])
    assert verdict(paired["mean_gain_ratio_lo"], paired["mean_gain_ratio_hi"], even=1.0) == "ahead"
    assert verdict(-1.0, 2.0) == "not separable" and verdict(-2.0, -1.0) == "behind"
    assert verdict(math.nan, math.nan) == "not separable"
