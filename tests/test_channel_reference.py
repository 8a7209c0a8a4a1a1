"""Every channel model on both seas gives, for the same seeds, the numbers it gave before the channel models
became objects in :mod:`waterair.physics.channel` (float64, eager).

``tests/data/channel_reference.pt`` holds recordings of the same rollouts, each made by :func:`record` on one
machine and kept with that machine's identity (:func:`machine`): the CPU's vendor and model, torch's version
and build, the instruction set torch's CPU kernels dispatch to, and torch's thread count. The test runs the
rollouts on today's tree and compares every output the step reports (gains, bounds, intensities,
observations with the quadrant spot, rewards, the residual base controller's tilts) with each recording:

* **exactly** (``torch.equal``) against a recording whose identity is this machine's: the guarantee that a
  change which should leave the physics alone leaves it alone to the last bit;
* **within 1e-12 relative** (:data:`TOLERANCE`) against every recording where none is this machine's. Two
  machines round differently although they run the same torch: the vectorised math of the CPU kernels (exp,
  log, sqrt, sums over SIMD lanes) depends on the instruction set, and MKL, torch's BLAS, chooses its code by
  the CPU's make, so an Intel and an AMD processor, both AVX512, differ by up to 3e-16 in float64. One ulp
  passes the tolerance; a change of the physics (1e-9 and more) does not.

The exact check that needs no recording, and so holds on every machine, is tests/test_paper_preset.py: the
paper's preset against the same rollout through the physics layer's functions, in one process.

Recorded again after physics changes: the facet interception (docs/model.md §4.3) moved the full channel and
the counting tracer on the measured-slope sea (gains +0.25 to +0.9 % on average over these rollouts, the
bounds +0.3 to +0.7 %, G_0 not at all); the full channel on that sea then placed a lattice for the pointing
beside the bound's, on 9 × 9 nodes over ±4.5 σ (docs/model.md §4.3; gains −1.2 % and +0.8 %, bounds −1.2 % and
−0.1 % on average), and averaged the receiver's field of view over each node's cell (§4.3, "The field of view's
edge"; on the Intel machine alone, where the AMD recordings of those two cases were dropped); the
``residual_realistic`` cases were recorded again when the residual interface gained its
acquisition (docs/environment.md, "Residual actions"), and again, on the Intel machine alone, when the sensor
noise became a stream per link (docs/environment.md, "Sensing"): the AMD recordings no longer hold them, so an
AMD machine compares those cases with the Intel recording within the tolerance (the new noise on this machine
through AVX2 and AVX512: equal, or 8e-17 apart). The full channel on the measured-slope sea was recorded again
on an AMD EPYC (Zen 4) alone when the eager lattice's per-axis factors became powers of one (within 1e-15 of
the Intel recording it replaced), and the full channel and the counting tracer on both seas again on an AMD EPYC
(Zen 5) alone when the gains took the angles' sines and cosines instead of the angles (within 1.2e-15 of the
recordings they replaced): the Zen 5 recording holds every case. Every other case is still the
first recording: the paper's single path (`+experiment=paper`) among them. The two recordings of an AMD EPYC
(AVX512, and AVX2 through ``ATEN_CPU_CAPABILITY=avx2``) predate the identity: their model and thread count were
not kept, so no machine compares with them exactly. ``python tests/test_channel_reference.py [CASE ...]`` adds
(or replaces) this machine's recording, after checking that it agrees with the others within the tolerance; the
CASEs (``channel/sea/interface``) named are dropped from the others' recordings: cases a change meant to move.
"""

import itertools
import sys
from pathlib import Path

import pytest
import torch
from conftest import machine

from waterair.envs.env import WaterAirEnv

pytestmark = pytest.mark.capability  # exact on the recording's machine, within TOLERANCE elsewhere

REFERENCE = Path(__file__).parent / "data" / "channel_reference.pt"
TOLERANCE = {"rtol": 1e-12, "atol": 1e-15}
"""Another machine's recording: 1e-12 relative, and 1e-15 absolute for values that are zero but for rounding."""
CHANNELS = ("single_path", "full", "montecarlo")
SEAS = {
    "paper": {"spectrum": "jonswap", "n_freq": 12, "n_dir": 6},
    "ocean": {"spectrum": "elfouhaily", "n_wavenumbers": 12, "n_dir": 6},
}
INTERFACES = {
    # the paper's interface: absolute pointing, an ideal sensor that reads the spot even without light
    "absolute_ideal": {"observation_extras": ("spot", "spot_valid", "history"), "geometry": {"offset_ratio": 0.1}},
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
        channel={"name": "counting", "rays": 2000, "facets": 8} if channel == "montecarlo" else {"name": channel},
        sea={**SEAS[sea], "wind": 12.0},  # the wind of the recordings; the residual interface draws its own
        draws="stream",  # the batch's draws of the recordings, in order from one generator
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
    trace["reference_gain"] = env.state.reference_gain.clone()
    return trace


def cases():
    return [(channel, sea, interface) for channel in CHANNELS for sea in SEAS for interface in INTERFACES]


def compare(got: dict[str, torch.Tensor], expected: dict[str, torch.Tensor], exact: bool) -> None:
    """Raise AssertionError unless every output of ``got`` equals ``expected``'s: bit for bit if ``exact``,
    else within :data:`TOLERANCE`."""
    assert set(got) == set(expected)
    for key, value in expected.items():
        difference = (got[key].double() - value.double()).abs().max().item()
        if exact:
            assert torch.equal(got[key], value), f"{key}: {difference:.3g} from the recording of this machine"
        else:
            torch.testing.assert_close(got[key], value, **TOLERANCE, msg=f"{key}: {difference:.3g}")


def record(path: Path = REFERENCE, changed: tuple[str, ...] = ()) -> None:
    """Add this machine's recording to the file, replacing an earlier one of the same identity, once the
    rollouts agree with every other machine's within :data:`TOLERANCE`. The cases named in ``changed``
    (``channel/sea/interface``) are cases whose numbers a change meant to move: the other machines' recordings
    of them no longer describe the tree, and are dropped rather than compared."""
    recordings = torch.load(path, weights_only=True)["recordings"] if path.exists() else []
    identity = machine()
    rollouts = {"/".join(case): rollout(*case) for case in cases()}
    for other in recordings:
        for case in changed:
            other["rollouts"].pop(case, None)
        for case, trace in other["rollouts"].items():
            compare(rollouts[case], trace, exact=False)
    kept = [other for other in recordings if other["identity"] != identity]
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save({"recordings": [*kept, {"identity": identity, "rollouts": rollouts}]}, path)


@pytest.fixture(scope="module")
def recordings() -> list[dict]:
    return torch.load(REFERENCE, weights_only=True)["recordings"]


@pytest.mark.parametrize(("channel", "sea", "interface"), cases())
def test_every_channel_gives_what_it_gave_before(recordings, channel, sea, interface):
    got, case = rollout(channel, sea, interface), f"{channel}/{sea}/{interface}"
    holding = [recorded for recorded in recordings if case in recorded["rollouts"]]
    assert holding, f"no machine's recording holds {case}"
    mine = [recorded for recorded in holding if recorded["identity"] == machine()]
    for recorded in mine or holding:  # exactly on the machine that recorded, else within the tolerance
        expected = recorded["rollouts"][case]
        assert expected["gain"].abs().max() > 0  # light reached the receivers: the comparison is not of zeros
        compare(got, expected, exact=bool(mine))


def test_the_recordings_of_different_machines_agree_within_the_tolerance_and_not_exactly(recordings):
    # the tolerance is only believed because recordings of the same tree on other machines agree within it
    assert len({(r["identity"]["cpu_vendor"], r["identity"]["capability"]) for r in recordings}) >= 3
    apart = 0
    for first, second in itertools.combinations(recordings, 2):
        shared = first["rollouts"].keys() & second["rollouts"].keys()
        for case in shared:
            trace = first["rollouts"][case]
            compare(trace, second["rollouts"][case], exact=False)
            apart += any(not torch.equal(value, second["rollouts"][case][key]) for key, value in trace.items())
    assert apart > 0  # and they do differ: an exact comparison with another machine's would fail


def test_one_ulp_fails_only_the_exact_comparison_and_1e_9_fails_both(recordings):
    case = "full/ocean/absolute_ideal"
    expected = next(recording["rollouts"][case] for recording in recordings if case in recording["rollouts"])
    for key, value in expected.items():
        if not value.is_floating_point():
            continue
        largest = value.abs().argmax()
        for change, fails_tolerant in ((lambda v: torch.nextafter(v, 2 * v), False), (lambda v: v * (1 + 1e-9), True)):
            got = {name: tensor.clone() for name, tensor in expected.items()}
            flat = got[key].view(-1)
            flat[largest] = change(flat[largest])
            with pytest.raises(AssertionError):
                compare(got, expected, exact=True)
            if fails_tolerant:
                with pytest.raises(AssertionError):
                    compare(got, expected, exact=False)
            else:
                compare(got, expected, exact=False)


if __name__ == "__main__":
    torch.set_num_threads(1)  # as make test's workers
    record(changed=tuple(sys.argv[1:]))
