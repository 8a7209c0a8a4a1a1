"""The ends' actuators in the step (env.actuator, waterair.envs.drives): the tilt commanded against the tilt pointed at,
each checked against a closed form or a limit computed here."""

from __future__ import annotations

import math

import pytest
import torch

from waterair.envs import platforms
from waterair.envs.config import EnvConfig
from waterair.envs.drives import flat_tilts
from waterair.envs.env import WaterAirEnv
from waterair.evaluation.rollouts import kinematic, rollout_policies
from waterair.physics.motion import attitudes

SMALL = dict(num_envs=4, sea={"n_wavenumbers": 12, "n_dir": 8}, seed=3, dtype="float64", max_steps=60)
TARGET = torch.tensor([0.30, -0.20, -0.25, 0.10], dtype=torch.float64)
"""Absolute tilts each end is commanded to, from upright: a slew of 0.2-0.3 rad per axis."""


def _commanded(env: WaterAirEnv, steps: int, target: torch.Tensor = TARGET) -> tuple[list, list]:
    """The ``tilt`` and ``pointed`` keys over ``steps`` steps of one held absolute command ``target``, the reset's
    pointing first in ``pointed`` (the ends start pre-pointed along the calm-sea path)."""
    td = env.reset()
    commanded, pointed = [], [td["pointed"].clone()]
    action = (target / env.config.max_tilt).expand(env.batch_size[0], 4)
    for _ in range(steps):
        td = env.step(td.set("action", action.clone()))["next"]
        commanded.append(td["tilt"].clone())
        pointed.append(td["pointed"].clone())
    return commanded, pointed


def _step_response(t: float, f_n: float, zeta: float) -> float:
    """θ(t) / u of θ'' = ω²(u − θ) − 2ζωθ' from rest, ζ < 1 (the textbook form)."""
    w = 2 * math.pi * f_n
    wd = w * math.sqrt(1 - zeta**2)
    return 1 - math.exp(-zeta * w * t) * (math.cos(wd * t) + zeta / math.sqrt(1 - zeta**2) * math.sin(wd * t))


def test_without_actuators_the_ends_point_where_they_are_commanded():
    commanded, pointed = _commanded(WaterAirEnv(EnvConfig(**SMALL)), 3)
    assert not pointed[0].any()  # upright at the reset, as the first releases' step
    for tilt, at in zip(commanded, pointed[1:], strict=True):
        assert torch.equal(tilt, at)
        assert torch.allclose(tilt, TARGET.expand_as(tilt), atol=1e-12)


def test_an_unlimited_gimbal_follows_the_second_order_step_response_in_each_axis_angle():
    actuator = dict(kind="gimbal", gimbal_rate=math.inf, gimbal_acceleration=math.inf, gimbal_resolution=0.0,
                    gimbal_natural_frequency=2.0, gimbal_damping=0.5)  # fmt: skip
    env = WaterAirEnv(EnvConfig(**SMALL, actuator=actuator))
    _, pointed = _commanded(env, 12)
    start, angles = torch.asin(pointed[0]), torch.asin(TARGET)
    assert (start - angles).abs().min() > 0.05  # each axis has a step to make
    for n, at in enumerate(pointed[1:], start=1):
        expected = torch.sin(start + (angles - start) * _step_response(n * env.config.dt, 2.0, 0.5))
        assert torch.allclose(at, expected.expand_as(at), rtol=1e-9, atol=1e-12)


def test_a_rate_limited_gimbal_slews_no_faster_than_its_rate_and_arrives():
    env = WaterAirEnv(EnvConfig(**SMALL, actuator={"kind": "gimbal", "gimbal_rate": 1.0, "gimbal_resolution": 0.0}))
    commanded, pointed = _commanded(env, 40)
    angles = [torch.asin(at) for at in pointed]
    steps = torch.stack([b - a for a, b in zip(angles, angles[1:], strict=False)]).abs()
    assert steps.max() <= 1.0 * env.config.dt + 1e-12  # 1 rad/s over 50 ms
    assert torch.allclose(commanded[0], TARGET.expand(4, 4))  # the command is at once ...
    assert (pointed[1] - TARGET).abs().max() > 0.1  # ... the pointing not ...
    assert torch.allclose(pointed[-1], TARGET.expand(4, 4), atol=1e-3)  # ... until the slew is done


def test_a_mirror_on_a_gimbal_takes_out_what_the_gimbal_leaves():
    slow = {"gimbal_rate": 1.0, "gimbal_resolution": 0.0, "mirror_resolution": 0.0}
    _, gimbal = _commanded(WaterAirEnv(EnvConfig(**SMALL, actuator={"kind": "gimbal", **slow})), 8)
    _, both = _commanded(WaterAirEnv(EnvConfig(**SMALL, actuator={"kind": "gimbal_fsm", **slow})), 8)
    mirror_range = EnvConfig().actuator.mirror_range
    for n in range(1, 9):
        left = (torch.asin(TARGET) - torch.asin(gimbal[n][0])).abs()
        removed = (torch.asin(gimbal[n][0]) - torch.asin(both[n][0])).abs()
        # the mirror (575 Hz) settles within the step: it removes the gimbal's error up to its range
        assert torch.allclose(removed, torch.minimum(left, torch.full_like(left, mirror_range)), atol=2e-4)


@pytest.mark.parametrize(("kind", "motion"), [("gimbal", "static"), ("gimbal_fsm", "static"), ("gimbal", "hover")])
def test_a_slewing_end_starts_pre_pointed_on_the_calm_sea_path_in_its_body_at_rest(kind, motion):
    config = EnvConfig(**SMALL, actuator={"kind": kind, "gimbal_resolution": 0.0, "mirror_resolution": 0.0},
                       motion={"kind": motion})  # fmt: skip
    env = WaterAirEnv(config)
    td = env.reset()
    state = env.state
    known = state.known.unbind(1) if motion != "static" else (state.tx_position, state.rx_position, state.flat_point)
    aim = flat_tilts(known[2], known[0], known[1])
    assert torch.allclose(td["pointed"], aim) and torch.allclose(td["tilt"], aim)
    assert aim.abs().max() > 0.05 and not state.drive[..., 1::2].any()  # turned from upright, at rest
    body = aim
    if motion != "static":  # each end's gimbal turns in its body: the world's tilts through its read attitude
        _, tx_read, _, rx_read = platforms.body_rotations(attitudes(state.motion))
        body = platforms.rotate_tilts(aim, tx_read, rx_read, inverse=True)
        assert (body - aim).abs().max() > 1e-3  # the drone's attitude is degrees
    assert torch.allclose(state.drive[..., 0], torch.asin(body), atol=1e-12)
    if motion == "static":  # held there, it stays there: no slew on the first step
        after = env.step(td.set("action", aim / config.max_tilt))["next"]
        assert torch.allclose(env.state.drive[..., :2], state.drive[..., :2], atol=1e-12)
        assert torch.allclose(after["pointed"], aim, atol=1e-12)


def test_a_fixed_mirror_starts_on_the_calm_sea_path_and_never_leaves_its_range_around_it():
    env = WaterAirEnv(EnvConfig(**SMALL, actuator={"kind": "fsm", "mirror_range": 0.02}))
    td = env.reset()
    mount = flat_tilts(env.state.flat_point, env.state.tx_position, env.state.rx_position)
    assert torch.allclose(td["pointed"], mount) and torch.allclose(td["tilt"], mount)
    _, pointed = _commanded(env, 5)
    for at in pointed[1:]:
        deflection = (torch.asin(at) - torch.asin(mount)).abs()
        assert deflection.max() <= 0.02 + 1e-12
        assert deflection.max() >= 0.02 - 1e-6  # the command is further than the mirror reaches: it is at its stop


def test_delta_actions_move_the_command_not_the_lagging_pointing():
    config = EnvConfig(**SMALL, action_mode="delta", actuator={"kind": "gimbal", "gimbal_rate": 0.2})
    env = WaterAirEnv(config)
    td = env.reset()
    start = td["tilt"].clone()  # pre-pointed along the calm-sea path
    for n in range(1, 4):
        td = env.step(td.set("action", torch.ones(4, 4, dtype=torch.float64)))["next"]
        slew = math.sin(math.radians(config.max_slew_deg_s * config.dt))
        assert torch.allclose(td["tilt"], start + n * slew)
    assert (td["pointed"] < td["tilt"] - 1e-3).all()  # 0.2 rad/s lags 60 deg/s


@pytest.mark.parametrize(
    ("actuator", "message"),
    [
        ({"kind": "laser"}, "env.actuator.kind = 'laser'"),
        ({"kind": "gimbal", "gimbal_rate": -1.0}, "env.actuator.gimbal_rate = -1.0 is out of range"),
        ({"mirror_damping": 0.0}, "env.actuator.mirror_damping = 0.0 is out of range"),
        ({"slew": 1.0}, "env.actuator.slew is not a known key"),
    ],
)
def test_actuator_keys_are_validated_by_name(actuator, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(".", r"\.")):
        EnvConfig(actuator=actuator)


def test_a_replica_not_actuated_points_where_it_commands_beside_one_that_slews():
    config = EnvConfig(**{**SMALL, "num_envs": 8}, replicas=2, replica_actions=({}, {"actuated": False}),
                       actuator={"kind": "gimbal", "gimbal_rate": 1.0})  # fmt: skip
    commanded, pointed = _commanded(WaterAirEnv(config), 3)
    assert torch.equal(pointed[-1][4:], commanded[-1][4:])  # replica 1: the command, at once
    assert (pointed[-1][:4] - commanded[-1][:4]).abs().max() > 0.05  # replica 0: still slewing


def test_evaluation_runs_the_kinematic_reference_without_the_actuators_and_the_controllers_through_them():
    members = [("tracking", "tracking"), ("snell", "flat_snell")]
    base = EnvConfig(**{**SMALL, "num_envs": 2}, replicas=2, actuator={"kind": "gimbal", "gimbal_rate": 0.5})
    assert kinematic(base, members) == ({"actuated": False}, {})
    assert kinematic(base.replace(actuator={"kind": "ideal"}), members) is None  # nothing to bypass
    point, ideal = [(12.0, 0.1, 0.0)], base.replace(num_envs=1, replicas=1, actuator={"kind": "ideal"})
    runs = rollout_policies(base, members, point, 2, 6, seed=1)
    alone = {label: rollout_policies(ideal, [(label, name)], point, 2, 6, seed=1)[label] for label, name in members}
    assert torch.equal(runs["tracking"]["gain"], alone["tracking"]["gain"])  # tracking: as without actuators
    assert not torch.equal(runs["snell"]["gain"], alone["snell"]["gain"])  # flat-sea Snell slews through its gimbal
