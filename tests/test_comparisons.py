"""Each learned policy against its base (waterair.evaluation.comparisons): the verdict on the held rates; and the
one upper bound every row of a comparison is a ratio to."""

import math
from types import SimpleNamespace

import pytest
import torch

from waterair.envs.config import EnvConfig
from waterair.evaluation.comparisons import COMPARISON_KEYS, HOLDS_NOTHING, comparison_rows
from waterair.evaluation.metrics import scenario_metrics
from waterair.evaluation.rollouts import rollout_policies
from waterair.evaluation.runner import compare_policies
from waterair.evaluation.scenarios import SETTING_COLUMNS, Scenario
from waterair.physics.link import LinkBudget

POLICIES = [{"label": "learned", "kind": "learned", "base": "base"}, {"label": "base", "kind": "baseline"}]
BOOTSTRAP = SimpleNamespace(level=0.95, resamples=200, seed=0)


def _runs(scale_learned: float, scale_base: float) -> dict:
    """Two policies on 12 seas × 1 point × 40 steps whose gains differ by a factor, the same seas beneath."""
    seas = 1.0 + torch.rand(12, 1, 40, generator=torch.Generator().manual_seed(3), dtype=torch.float64)
    traces = {}
    for label, scale in (("learned", scale_learned), ("base", scale_base)):
        gain = scale * seas
        traces[label] = {"gain": gain, "gain_upper_bound": 2.0 * scale_base * seas.clamp(min=2.0),
                         "reference_gain": torch.full((12, 1), 2.0 * scale_base), "path_valid": gain > 0}  # fmt: skip
    return traces


def _compare(runs: dict) -> dict:
    held = {}
    for label, t in runs.items():
        traces = (t["gain"][:, 0], t["gain_upper_bound"][:, 0], t["reference_gain"][:, 0], t["path_valid"][:, 0])
        held[label] = scenario_metrics(*traces, link=LinkBudget(), resamples=10)["rate_held"]
    (row,) = comparison_rows(POLICIES, runs, 0, {"scenario": "S5"}, held, LinkBudget(), BOOTSTRAP)
    assert (row["rate_held"], row["base_rate_held"]) == (held["learned"], held["base"])
    where = {"wind", "offset_ratio", "offset_azimuth_deg", "divergence", *SETTING_COLUMNS}  # the caller's: not given
    assert set(row) >= set(COMPARISON_KEYS) - where
    return row


def test_two_policies_that_hold_no_link_have_no_held_ratio_and_are_said_to_hold_nothing():
    # gains of 1e-7 /m² carry about 40 bit/s: the learned policy holds 1.5× the base's, but neither is a link
    row = _compare(_runs(1.5e-7, 1e-7))
    assert max(row["rate_held"], row["base_rate_held"]) < HOLDS_NOTHING and row["rate_held"] > row["base_rate_held"]
    assert row["rate_held_verdict"] == "neither holds"
    assert all(math.isnan(row[f"rate_held_ratio{suffix}"]) for suffix in ("", "_lo", "_hi"))
    assert row["rate_held_diff"] > 0  # the difference stays: it is in bit/s and says how little either holds


def test_the_same_factor_on_a_link_that_holds_is_judged_by_its_interval():
    # 1e-5 /m²: hundreds of kbit/s; the learned policy's gain 1.5× the base's on every step of every sea
    row = _compare(_runs(1.5e-5, 1e-5))
    assert row["base_rate_held"] > HOLDS_NOTHING and row["rate_held_verdict"] == "ahead"
    assert 1.0 < row["rate_held_ratio_lo"] <= row["rate_held_ratio"] <= row["rate_held_ratio_hi"]


def test_every_row_shares_one_upper_bound_whatever_the_order_of_the_policies():
    """Each replica's bound is the search's, or its own gain where its pointing received more (docs/model.md §4.5):
    the evaluation's bound is the most any replica found, the same for every row in any order of the policies."""
    beacon = {"observation_extras": ("spot", "spot_valid", "beacon", "beacon_valid")}
    config = EnvConfig(sea={"n_wavenumbers": 24, "n_dir": 8}, optics={"divergence": 0.01}, **beacon)
    scenario = Scenario("S", "a narrow beam far off the vertical", None, ((12.0, 0.5, 0.0),), 3, 40, 11)
    members = {"tracking": "tracking", "kalman": "kalman_tracker", "facing": "straight_facing"}
    raw = rollout_policies(config, list(members.items()), scenario.points, 3, 40, 11)
    # the replicas' own bounds do differ: the old row, the first member's bound, depended on the order
    assert not torch.equal(raw["tracking"]["gain_upper_bound"], raw["facing"]["gain_upper_bound"])
    forward = compare_policies(config, members, scenario)
    backward = compare_policies(config, dict(reversed(members.items())), scenario)
    assert forward == backward
    bound = torch.stack([t["gain_upper_bound"] for t in raw.values()]).amax(0)
    assert forward["upper_bound"]["mean_gain"] == pytest.approx(bound.double().mean().item(), rel=1e-12)
    for label, t in raw.items():
        assert (t["gain"] <= bound).all()
        assert forward[label]["ratio_to_ub"] == pytest.approx(t["gain"].double().mean() / bound.double().mean())
    # a group of another interface runs in its own environment on the same seas: where neither pointing received
    # more than the search, the two searches agree (to float32 rounding of a batch laid out otherwise)
    plain = config.replace(observation_extras=())
    (apart,) = rollout_policies(plain, [("flat", "flat_snell")], scenario.points, 3, 40, 11).values()
    searched = (apart["gain"] < apart["gain_upper_bound"]) & (raw["facing"]["gain"] < raw["facing"]["gain_upper_bound"])
    assert searched.double().mean() > 0.9
    got, expected = apart["gain_upper_bound"][searched], raw["facing"]["gain_upper_bound"][searched]
    torch.testing.assert_close(got, expected, rtol=1e-5, atol=0)
    both = compare_policies(config, members, scenario, beside=[(plain, {"flat": "flat_snell"})])
    assert both["upper_bound"]["mean_gain"] >= forward["upper_bound"]["mean_gain"]
    assert both["flat"]["ratio_to_ub"] <= 1.0
