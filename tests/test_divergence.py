"""Each link's own beam divergence ω_D (``env.divergence_range``, ``env.divergence_values``): a per-link
quantity of the state, drawn at each reset, that every gain, the misalignment, the observation's ``divergence``
part and the intensity dither read for their own link, so that one batch (one policy, one graph) serves every
divergence. A link's outputs must not depend on the divergences of the links beside it."""

import math

import pytest
import torch

from tests.conftest import preset_config
from waterair.envs import draws
from waterair.envs.config import EnvConfig
from waterair.envs.controllers import CONTROLLERS
from waterair.envs.env import WaterAirEnv
from waterair.evaluation.runner import compare_policies
from waterair.evaluation.scenarios import Scenario

SPREAD = (0.005, 0.02, 0.1)
"""Divergences (rad) a mixed batch holds, one per link: the narrow end, the middle and the wide end of training's."""
COMPARED = ("observation", "gain", "gain_upper_bound", "intensity", "reward", "alpha_d", "base_tilt", "divergence")


def rollout(env: WaterAirEnv, steps: int, controller: str | None) -> dict[str, torch.Tensor]:
    """Each output of :data:`COMPARED` over ``steps`` steps ``[steps, B, ...]``: seeded random actions, or a
    classical ``controller``'s."""
    policy = CONTROLLERS[controller](env) if controller else None
    generator = torch.Generator().manual_seed(3)
    td, trace = env.reset(), {key: [] for key in COMPARED}
    for _ in range(steps):
        if policy is None:
            td.set("action", 0.3 * torch.randn(env.batch_size[0], 4, generator=generator))
        else:
            td = policy(td)
        td = env.step(td)["next"]
        for key in COMPARED:
            trace[key].append(td[key])
    return {key: torch.stack(values) for key, values in trace.items()}


@pytest.mark.parametrize(
    "channel,controller",
    [("single_path", None), ("full", None), ("full", "intensity_dither"), ("single_path", "beacon_tracker")],
)
def test_a_batch_of_mixed_divergences_gives_each_link_what_a_batch_of_its_divergence_alone_gives(channel, controller):
    """Link i of a batch holding :data:`SPREAD` (point i of realisation 0) against link i of a batch whose every
    link has SPREAD[i] (its points alike: the same realisation, seas, geometry and sensor noise, none of which
    depends on ω_D, and the same place in the batch), realistic sensing with the beacon read, residual actions on
    the beacon tracker: bit for bit, eagerly."""
    steps = 12
    base = preset_config(
        "beacon", "realistic", len(SPREAD), channel={"name": channel}, action_mode="residual", divergence_range=None
    )
    if channel == "full":
        base = base.replace(sea={"n_wavenumbers": 24, "n_dir": 8})
    if controller == "intensity_dither":
        base = base.replace(residual_base="flat_snell", observation_extras=("divergence",))
    mixed = rollout(WaterAirEnv(base.replace(divergence_values=SPREAD)), steps, controller)
    alone = [
        rollout(WaterAirEnv(base.replace(divergence_values=(w,) * len(SPREAD))), steps, controller) for w in SPREAD
    ]
    for link, single in enumerate(alone):
        assert torch.equal(mixed["divergence"][:, link], torch.full((steps,), SPREAD[link], dtype=torch.float64))
        for key in COMPARED:
            assert torch.equal(mixed[key][:, link], single[key][:, link]), (key, SPREAD[link])
    # the divergence matters: the narrow beam's link, with the wide beam's optics, gains otherwise
    assert not torch.equal(alone[0]["gain"][:, 0], alone[2]["gain"][:, 0])
    assert mixed["gain"].abs().max() > 0


def test_a_divergence_range_is_drawn_uniformly_in_the_logarithm_within_it():
    """Every octave of the range as likely: Kolmogorov–Smirnov against the uniform law of log ω_D (a uniform
    law of ω_D itself puts 1/20 of the links below 10 mrad where the log-uniform puts 23 %, D ≈ 0.18)."""
    low, high = 0.005, 0.1
    config = EnvConfig(divergence_range=(low, high))
    count = 20_000
    drawn = draws.divergence(config, torch.arange(count), draws.StreamDraws(torch.Generator().manual_seed(5)))
    assert drawn.dtype == torch.float64 and drawn.shape == (count,)
    assert drawn.min() >= low and drawn.max() <= high
    fraction = (torch.log(drawn.sort().values) - math.log(low)) / math.log(high / low)
    ranks = torch.arange(1, count + 1, dtype=torch.float64) / count
    distance = torch.maximum((ranks - fraction).abs(), (ranks - 1.0 / count - fraction).abs()).max()
    assert distance < 1.95 / math.sqrt(count)
    assert torch.equal(
        draws.divergence(EnvConfig(), torch.arange(4), None), torch.full((4,), 0.05, dtype=torch.float64)
    )


def test_the_divergence_observed_is_linear_in_its_logarithm_and_exact_in_the_state():
    """The ``divergence`` part reads −1 at 5 mrad, 1 at 100 mrad, 0 at their geometric mean; the state and the
    ``divergence`` key hold the configured values exactly (float64)."""
    values = (0.005, 0.1, math.sqrt(0.005 * 0.1), 0.2)
    env = WaterAirEnv(EnvConfig(num_envs=4, divergence_values=values, observation_extras=("divergence",)))
    td = env.reset()
    assert torch.equal(td["divergence"], torch.tensor(values, dtype=torch.float64))
    observed = env.observation_part(td["observation"], "divergence")[:, 0]
    expected = torch.tensor([-1.0, 1.0, 0.0, 1.0 + 2.0 * math.log(2.0) / math.log(20.0)])
    torch.testing.assert_close(observed, expected, rtol=0.0, atol=1e-6)
    assert env.observation_spec["observation"].shape[-1] == env.config.observation_size == 9


@pytest.mark.parametrize(
    "overrides,message",
    [
        ({"divergence_range": [0.0, 0.1]}, "env.divergence_range[0] = 0.0 is out of range; allowed (0, 1.5] rad"),
        ({"divergence_range": [0.01, 2.0]}, "env.divergence_range[1] = 2.0 is out of range; allowed [0.01, 1.5] rad"),
        ({"divergence_values": [0.01, -0.1]}, "env.divergence_values[1] = -0.1 is out of range"),
        (
            {"divergence_values": [0.01], "divergence_range": [0.01, 0.1]},
            "env.divergence_values and env.divergence_range are both set",
        ),
    ],
)
def test_a_divergence_out_of_range_names_the_key_the_value_and_the_range(overrides, message):
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("(", r"\(")):
        EnvConfig.from_mapping(overrides)


def test_an_evaluation_runs_every_link_at_the_scenarios_divergence_whatever_the_training_drew():
    """Training's closing evaluation takes the training environment, its divergence range too: the rollouts put
    every link at optics.divergence, the divergence its link budget converts gain at, as for any scenario."""
    scenario = Scenario("train", "training point", None, ((12.0, 0.1, 0.0),), 2, 6, 7)
    sea = {"n_wavenumbers": 24, "n_dir": 8}
    base = EnvConfig(channel={"name": "single_path"}, sea=sea, optics={"divergence": 0.01})
    ranged = base.replace(divergence_range=(0.005, 0.1))
    fixed = compare_policies(base, {"flat": "flat_snell"}, scenario)
    assert compare_policies(ranged, {"flat": "flat_snell"}, scenario) == fixed
    wide = compare_policies(base.replace(optics={"divergence": 0.05}), {"flat": "flat_snell"}, scenario)
    assert fixed["flat"]["mean_gain"] != wide["flat"]["mean_gain"]  # the divergence shows
