"""Sensor noise in streams keyed by link: the hash against SplitMix64 written here in Python integers, the
draws against the normal law, and a controller's metrics alone, beside others and under another name."""

import math

import torch
from conftest import paper_physics

from waterair.envs.config import EnvConfig
from waterair.envs.noise import mix, normals, stream_keys
from waterair.evaluation.rollouts import rollout_policies

WORD = (1 << 64) - 1


def splitmix_finaliser(x: int) -> int:
    """SplitMix64's finaliser on an unsigned 64-bit word, in Python's unbounded integers."""
    x = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & WORD
    x = ((x ^ (x >> 27)) * 0x94D049BB133111EB) & WORD
    return x ^ (x >> 31)


def test_the_int64_hash_is_splitmix64_modulo_two_to_the_64():
    words = torch.randint(-(1 << 63), (1 << 63) - 1, (2000,), generator=torch.Generator().manual_seed(0))
    words = torch.cat((words, torch.tensor([0, 1, -1, (1 << 63) - 1, -(1 << 63)])))
    mixed = mix(words)
    for word, result in zip(words.tolist(), mixed.tolist(), strict=True):
        assert result & WORD == splitmix_finaliser(word & WORD)


def test_stream_draws_are_standard_normal_and_uncorrelated_across_columns_links_and_readings():
    keys = stream_keys(100_000, 1)
    draws = torch.cat((normals(keys, 12345, 4), normals(keys, 12346, 4)), dim=-1)  # two readings
    n = draws.shape[0]
    assert draws.mean(0).abs().max().item() < 5 / math.sqrt(n)
    assert (draws.std(0) - 1).abs().max().item() < 0.015
    correlation = torch.corrcoef(torch.cat((draws[1:], draws[:-1, :1]), dim=-1).T)  # neighbouring links too
    off_diagonal = correlation - torch.eye(correlation.shape[0], dtype=draws.dtype)
    assert off_diagonal.abs().max().item() < 5 / math.sqrt(n)
    # Kolmogorov–Smirnov against Φ: D below the 0.1 % critical value 1.95/√n for every column
    ordered = draws.sort(0).values
    cdf = 0.5 * (1 + torch.erf(ordered / math.sqrt(2)))
    ranks = torch.arange(1, n + 1, dtype=draws.dtype).unsqueeze(-1)
    distance = torch.maximum(ranks / n - cdf, cdf - (ranks - 1) / n).max(0).values
    assert distance.max().item() < 1.95 / math.sqrt(n)


def test_a_link_keeps_its_stream_whatever_runs_beside_it_and_however_many_links_there_are():
    alone = stream_keys(3, 1)
    beside = stream_keys(9, 3)  # three controllers side by side: each block of three the same links
    for block in range(3):
        assert torch.equal(beside[3 * block : 3 * block + 3], alone)
    assert torch.equal(stream_keys(5, 1)[:3], alone)  # more links: the first keep theirs
    assert stream_keys(1000, 1).unique().numel() == 1000  # every link its own stream
    assert torch.equal(normals(beside[3:6], 7, 4), normals(alone, 7, 4))
    assert not torch.equal(normals(alone, 7, 4), normals(alone, 8, 4))


def test_a_controller_scores_the_same_alone_and_beside_others_with_noisy_sensing_under_any_name():
    config = EnvConfig().replace(
        **paper_physics(n_freq=16, n_dir=8),
        observation_extras=("spot", "spot_valid", "history", "action_history", "geometry"),
        intensity_noise=0.05,
        intensity_noise_floor=1e-3,
        spot_noise_rad=2e-3,
        latency_steps=1,
        compile_kernel=False,
    )
    points = [(8.0, 0.1, 0.0), (12.0, 0.3, 45.0)]
    alone = rollout_policies(config, [("aoa_tracker", "aoa_tracker")], points, 2, 12, seed=5)
    beside = rollout_policies(config, [("flat_snell", "flat_snell"), ("renamed", "aoa_tracker")], points, 2, 12, seed=5)
    for key, trace in alone["aoa_tracker"].items():
        assert torch.equal(trace, beside["renamed"][key]), key
    # the noise is real: the noisy tracker differs from an ideal one on the same seas
    ideal = rollout_policies(
        config.replace(intensity_noise=0.0, intensity_noise_floor=0.0, spot_noise_rad=0.0),
        [("aoa_tracker", "aoa_tracker")],
        points,
        2,
        12,
        seed=5,
    )
    assert not torch.equal(ideal["aoa_tracker"]["gain"], alone["aoa_tracker"]["gain"])
