"""Draws keyed by what they are (docs/model.md §10): the key-to-draw hash against SplitMix64 written here in Python
integers, a scenario point alone against the same point inside a grid, and a training batch split over
environments against the whole batch."""

import math

import pytest
import torch
from conftest import compose_config, paper_physics

from waterair.core.hashing import key, uniforms
from waterair.envs import draws
from waterair.envs.config import EnvConfig
from waterair.envs.env import WaterAirEnv
from waterair.evaluation.rollouts import rollout_policies
from waterair.evaluation.runner import evaluate

WORD = (1 << 64) - 1
GOLDEN = 0x9E3779B97F4A7C15


def splitmix(x: int) -> int:
    """SplitMix64's finaliser on an unsigned 64-bit word, in Python's unbounded integers."""
    x = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & WORD
    x = ((x ^ (x >> 27)) * 0x94D049BB133111EB) & WORD
    return x ^ (x >> 31)


def reference_uniforms(parts: tuple[int, ...], count: int) -> list[float]:
    """The key of ``parts`` (each folded in: word ← mix(3 word + part · golden + 1)) and its ``count`` uniforms
    (the key mixed once more, plus c · golden for counter c, mixed; its top 53 bits, centred in their cell)."""
    word = 0
    for part in parts:
        word = splitmix((3 * word + (part & WORD) * GOLDEN + 1) & WORD)
    base = splitmix(word)
    return [((splitmix((base + c * GOLDEN) & WORD) >> 11) + 0.5) * 2.0**-53 for c in range(1, count + 1)]


def test_a_keys_uniforms_are_splitmix64s_of_its_parts_and_differ_by_role():
    cases = [(0, 0, 0, 1), (12345, 7, 3, 4), (2**62 + 11, 2**40, 0, 7), (1, -1, 5, 2)]
    for parts in cases:
        got = uniforms(key(*(torch.tensor([p]) for p in parts)), 6)[0].tolist()
        assert got == reference_uniforms(parts, 6), parts
    # a batch of keys at once, each its own; another role, or the parts in another order, another draw
    batch = uniforms(key(12345, torch.arange(4), 0, 4), 3)
    assert [row.tolist() for row in batch] == [reference_uniforms((12345, r, 0, 4), 3) for r in range(4)]
    assert not torch.equal(uniforms(key(1, 2, 3), 4), uniforms(key(1, 3, 2), 4))
    # a seed of 64 bits (torch's nondeterministic ones) is its bits: 2^64 - 1 is -1
    assert torch.equal(key(2**64 - 1, 5), key(-1, 5)) and uniforms(key(2**64 - 1, 5), 2).tolist() == reference_uniforms(
        (2**64 - 1, 5), 2
    )
    assert uniforms(key(5, 0, 0, 3), 10_000).mean().item() == pytest.approx(0.5, abs=0.01)


FLOAT32 = 1e-5
"""How far a point alone and in a grid may differ: its draws are the same bit for bit, but a vectorised kernel
(exp, sqrt over a batch) rounds the last elements of its tensor in scalar code, so a link's last float32 bits depend
on where it sits in the batch (1e-7 relative seen; a learned policy's actions can carry it to 1e-8 in a mean)."""
KEYED = {**paper_physics(n_freq=16, n_dir=8), "draws": "keyed", "seed": 3}


def test_one_point_alone_gives_bit_for_bit_what_it_gives_inside_a_grid():
    """S3's kind of grid (three winds) against its 12 m/s point alone: the same seas, the same sensor noise, the
    same traces for the classical controllers and the bound, realisation by realisation, to float32's rounding
    (:data:`FLOAT32`)."""
    config = EnvConfig(**KEYED, latency_steps=1, intensity_noise=0.05, spot_noise_rad=1e-3, beacon_noise_rad=1e-3,
                       observation_extras=("spot", "spot_valid", "beacon", "beacon_valid"))  # fmt: skip
    members = [(name, name) for name in ("beacon_tracker", "aoa_tracker", "flat_snell")]
    grid = rollout_policies(config, members, [(4.0, 0.1, 0.0), (12.0, 0.1, 0.0), (20.0, 0.2, 0.0)], 3, 6, 11)
    alone = rollout_policies(config, members, [(12.0, 0.1, 0.0)], 3, 6, 11)
    for label, _ in members:
        for name in ("gain", "gain_upper_bound", "reference_gain"):
            got, expected = grid[label][name][:, 1], alone[label][name][:, 0]
            torch.testing.assert_close(got, expected, rtol=FLOAT32, atol=0, msg=(label, name))
    # and the points differ: another wind is another sea, on the same phases
    assert not torch.equal(grid["flat_snell"]["gain"][:, 0], grid["flat_snell"]["gain"][:, 1])


def test_a_points_realisations_share_their_phases_with_every_other_point():
    env = WaterAirEnv(EnvConfig(**KEYED, num_envs=6, wind_values=(4.0, 12.0)))
    env.reset()
    phase = env.surface.phase
    assert torch.equal(phase[0], phase[1]) and torch.equal(phase[2], phase[3]) and not torch.equal(phase[0], phase[2])
    assert not torch.equal(env.surface.omega[0], env.surface.omega[1])  # each point's wind sets its own waves


RANDOMISED = {"wind_range": (4.0, 20.0), "offset_range": (0.0, 0.5), "offset_azimuth_range": (-180.0, 180.0),
              "wind_direction_range": (-180.0, 180.0), "divergence_range": (0.005, 0.1)}  # fmt: skip


def test_a_batch_split_over_environments_resets_each_link_as_the_whole_batch_does():
    """Training's resets: sixteen links in one environment against links 0-7 and 8-15 in two (``link_offset``),
    over two episodes: the same seas, geometry and divergence for the same link and episode."""

    def episodes(env: WaterAirEnv) -> list[dict]:
        seen = []
        for _ in range(2):
            td = env.reset()
            seen.append({"phase": env.surface.phase.clone(), "omega": env.surface.omega.clone(),
                         "rx": td["rx_position"].clone(), "divergence": td["divergence"].clone()})  # fmt: skip
        return seen

    whole = episodes(WaterAirEnv(EnvConfig(**KEYED, **RANDOMISED, num_envs=16)))
    halves = [episodes(WaterAirEnv(EnvConfig(**KEYED, **RANDOMISED, num_envs=8, link_offset=o))) for o in (0, 8)]
    for k in range(2):
        for name, value in whole[k].items():
            assert torch.equal(value, torch.cat([half[k][name] for half in halves])), (k, name)
    assert not torch.equal(whole[0]["phase"], whole[1]["phase"])  # each episode its own seas
    assert whole[0]["divergence"].unique().numel() == 16  # each link its own draw


def test_an_unseeded_environment_draws_keyed_seas_of_its_own():
    """Its key starts from torch's nondeterministic 64-bit seed, which an int64 holds only as its bits."""
    phases = []
    for _ in range(2):
        env = WaterAirEnv(EnvConfig(**{**KEYED, "seed": None}, num_envs=2))
        env.reset()
        phases.append(env.surface.phase)
    assert not torch.equal(*phases)


def test_stream_draws_are_the_generators_in_order_and_keyed_ones_ignore_the_batch():
    generator = torch.Generator().manual_seed(4)
    drawn = draws.StreamDraws(generator).uniform("wind", 1, 5)[:, 0]
    assert torch.equal(drawn, torch.rand(5, generator=torch.Generator().manual_seed(4), dtype=torch.float64))
    config = EnvConfig(draws="keyed", wind_values=(4.0, 12.0))
    links = torch.arange(6)
    assert draws.realisations(config, links).tolist() == [0, 0, 1, 1, 2, 2]
    assert draws.realisations(config.replace(link_offset=5), links).tolist() == [5, 5, 6, 6, 7, 7]
    keys = draws.link_keys(config, 3, links, torch.zeros(6, dtype=torch.int64))
    assert torch.equal(draws.KeyedDraws(keys).uniform("phase", 4, 6)[2:4], draws.KeyedDraws(keys[2:4]).uniform(
        "phase", 4, 2))  # fmt: skip


SMALL = ["env.sea.n_dir=8", "env.compile_kernel=false", "bootstrap.resamples=50", "workers=1", "scenarios.S1=null",
         "scenarios.S5=null", "baselines=[beacon_tracker,flat_snell]", "physics_figures=false"]  # fmt: skip
SWEEPS = {"S2": "offset_ratios=[0.0,0.1,0.3]", "S3": "winds=[4.0,12.0]", "S4": "azimuths_deg=[0.0,90.0]"}


def same(a: dict, b: dict) -> bool:
    """Two rows equal value for value to float32's rounding (:data:`FLOAT32`), NaN (a metric the scenario has
    none of) equal to NaN."""
    return a.keys() == b.keys() and all(a[k] == b[k] or math.isclose(a[k], b[k], rel_tol=FLOAT32) or
                                        (math.isnan(a[k]) and math.isnan(b[k])) for k in a)  # fmt: skip


def test_scenarios_split_over_evaluations_and_a_point_alone_give_the_rows_of_one_evaluation():
    """S2, S3 and S4 share a seed, so one evaluation runs them as one batch; each alone (as a process of its own
    would), and S3's 12 m/s point alone, give the same rows for the shipped policies, the controllers and the
    bound: every metric and interval, to float32's rounding (:data:`FLOAT32`)."""

    def rows(*overrides) -> dict:
        sweeps = [f"scenarios.{name}.{sweep}" for name, sweep in SWEEPS.items()]
        sizes = [f"scenarios.{name}.{key}" for name in SWEEPS for key in ("realisations=3", "steps=6")]
        result = evaluate(compose_config("evaluate", [*SMALL, *sweeps, *sizes, *overrides]), progress=lambda _: None)
        return {(r["scenario"], r["policy"], *(r[k] for k in ("wind", "offset_ratio", "offset_azimuth_deg"))): r
                for r in result.rows}  # fmt: skip

    whole = rows()
    alone = {}
    for name in SWEEPS:
        alone.update(rows(*(f"scenarios.{other}=null" for other in SWEEPS if other != name)))
    assert alone.keys() == whole.keys() and {key[1] for key in whole} >= {"ppo default", "beacon_tracker"}
    assert [key for key in whole if not same(alone[key], whole[key])] == []
    point = rows("scenarios.S2=null", "scenarios.S4=null", "scenarios.S3.winds=[12.0]")
    assert point.keys() == {key for key in whole if key[0] == "S3" and key[2] == 12.0}
    assert all(same(point[key], whole[key]) for key in point)
    # the points differ (another wind, another sea on the same phases), and the rows hold their held rates' intervals
    four, twelve = (whole[("S3", "ppo default", wind, 0.1, 0.0)] for wind in (4.0, 12.0))
    assert four["mean_gain"] != twelve["mean_gain"] and {"rate_held_lo", "rate_held_hi"} <= twelve.keys()
