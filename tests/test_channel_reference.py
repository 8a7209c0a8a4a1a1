"""Every channel model on both seas gives, for the same seeds, exactly the numbers it gave before the
channel models became objects in :mod:`waterair.physics.channel` (float64, eager).

``tests/data/channel_reference.pt`` was written by :func:`record` on the tree before that change
(``python tests/test_channel_reference.py``); the test runs the same rollouts on today's tree and
asks for equality, bit for bit, of every output the step reports: gains, bounds, intensities,
observations (the quadrant spot included), rewards and the residual base controller's tilts.

Recorded again after one physics change: the facet interception (docs/model.md §4.3) moved the full
channel and the counting tracer on the measured-slope sea (gains +0.25 to +0.9 % on average over these
rollouts, the bounds +0.3 to +0.7 %, G_0 not at all); and a second: the full channel on that sea now places
a lattice for the pointing beside the bound's, on 9 × 9 nodes over ±4.5 σ instead of 7 × 7 over ±4 σ
(docs/model.md §4.3; over these rollouts the gains −1.2 % and +0.8 %, the bounds −1.2 % and −0.1 % on average).
The ``residual_realistic`` cases were recorded again when the residual interface gained its acquisition
(docs/environment.md, "Residual actions": the reset's reading, taken with the gimbals parked, steers nothing),
which changes their pointing at the first two steps and so every step after.
Every other case is still the first recording, bit for bit: the paper's single path (`+experiment=paper`)
among them.

The vectorised math of PyTorch's CPU kernels (exp, log, sqrt and sums over SIMD lanes) rounds
differently on different instruction sets: the Monte Carlo tracer on the measured-slope sea moves by
an ulp or two between AVX2 and AVX512. The file holds one recording per instruction set
(``torch.backends.cpu.get_cpu_capability()``; AVX2 on an AVX512 machine with ``ATEN_CPU_CAPABILITY=avx2``); a machine
whose instruction set has none compares with the others to 1e-12 relative and says so.
"""

from pathlib import Path

import pytest
import torch

from waterair.envs.env import WaterAirEnv

REFERENCE = Path(__file__).parent / "data" / "channel_reference.pt"
CHANNELS = ("single_path", "full", "montecarlo")
SEAS = {
    "paper": {"spectrum": "jonswap", "n_freq": 12, "n_dir": 6},
    "ocean": {"spectrum": "elfouhaily", "n_wavenumbers": 12, "n_dir": 6},
}
INTERFACES = {
    # the paper's interface: absolute pointing, an ideal sensor that reads the spot even without light
    "absolute_ideal": {"observation_extras": ("spot", "spot_valid", "history"), "wind": 12.0, "offset_ratio": 0.1},
    # corrections on the quadrant back-projection, through a late and noisy sensor, over many seas
    "residual_realistic": {
        "action_mode": "residual",
        "residual_base": "aoa_tracker",
        "residual_deg": 5.0,
        "observation_extras": ("spot", "spot_valid", "geometry"),
        "latency_steps": 1,
        "intensity_noise": 0.05,
        "intensity_noise_floor": 0.001,
        "intensity_saturation": 4.0,
        "spot_noise_rad": 0.001,
        "spot_threshold": 0.01,
        "wind_range": (4.0, 20.0),
        "offset_range": (0.0, 0.5),
        "offset_azimuth_range": (0.0, 360.0),
    },
}
KEYS = ("observation", "gain", "gain_upper_bound", "intensity", "path_valid", "alpha_d", "alpha_a",
        "departure", "arrival", "tilt", "base_tilt")  # fmt: skip
STEPS = 6


def rollout(channel: str, sea: str, interface: str) -> dict[str, torch.Tensor]:
    """The reset and ``STEPS`` steps of 4 links under seeded random actions (each key ``[STEPS + 1, 4, ...]``).

    ``montecarlo`` was recorded when it named the hit-counting tracer on both seas: that model is now
    ``counting`` (``montecarlo`` on the measured-slope sea is the local estimate, tested on its own)."""
    env = WaterAirEnv(
        num_envs=4,
        seed=7,
        dtype="float64",
        channel="counting" if channel == "montecarlo" else channel,
        montecarlo_rays=2000,
        montecarlo_facets=8,
        **SEAS[sea],
        **INTERFACES[interface],
    )
    # small actions: near straight facing (absolute) or near the base controller (residual), where light arrives
    actions = 0.3 * torch.rand(STEPS, 4, 4, generator=torch.Generator().manual_seed(3), dtype=torch.float64) - 0.15
    td = env.reset()
    frames, rewards = [td], []
    for action in actions:
        step = env.step(td.set("action", action))
        td = step["next"]
        frames.append(td)
        rewards.append(td["reward"])
    trace = {key: torch.stack([frame[key] for frame in frames]) for key in KEYS}
    trace["reward"] = torch.stack(rewards)
    trace["reference_gain"] = env.reference_gain.clone()
    return trace


def cases():
    return [(channel, sea, interface) for channel in CHANNELS for sea in SEAS for interface in INTERFACES]


def record(path: Path = REFERENCE) -> None:
    """Add this machine's instruction set's recording to the file (the others are kept)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    recordings = torch.load(path, weights_only=True) if path.exists() else {}
    recordings[CAPABILITY] = {"/".join(case): rollout(*case) for case in cases()}
    torch.save(recordings, path)


CAPABILITY = torch.backends.cpu.get_cpu_capability()


@pytest.fixture(scope="module")
def reference():
    return torch.load(REFERENCE, weights_only=True)


@pytest.mark.parametrize(("channel", "sea", "interface"), cases())
def test_every_channel_gives_what_it_gave_before_bit_for_bit(reference, channel, sea, interface):
    got = rollout(channel, sea, interface)
    exact = CAPABILITY in reference
    for recorded in [reference[CAPABILITY]] if exact else reference.values():
        expected = recorded[f"{channel}/{sea}/{interface}"]
        assert set(got) == set(expected)
        assert expected["gain"].abs().max() > 0  # light reached the receivers: the comparison is not of zeros
        for key, value in expected.items():
            difference = (got[key].double() - value.double()).abs().max()
            if exact:
                assert torch.equal(got[key], value), (key, CAPABILITY, difference)
            else:  # another instruction set's rounding (module docstring)
                torch.testing.assert_close(got[key], value, rtol=1e-12, atol=1e-15, msg=f"{key}: {difference}")


def test_the_reference_holds_recordings_of_more_than_one_instruction_set(reference):
    # the fallback's tolerance is only believed because two recordings of the same tree agree within it
    assert {"AVX2", "AVX512"} <= set(reference)
    for case, trace in reference["AVX2"].items():
        for key, value in trace.items():
            torch.testing.assert_close(reference["AVX512"][case][key], value, rtol=1e-12, atol=1e-15)


if __name__ == "__main__":
    record()
