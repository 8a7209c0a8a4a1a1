"""S6 and S7, the moving ends' studies (``+scenarios=moving``): their settings from the config, each setting's env,
and an evaluation that runs each setting as a rollout of its own and writes its rows, tables and figures."""

from __future__ import annotations

import json
import math

import pytest
import torch
from conftest import compose_config

from waterair.envs.config import EnvConfig
from waterair.evaluation.groups import reading
from waterair.evaluation.report import ROW_KEYS, write_outputs
from waterair.evaluation.rollouts import rollout_policies
from waterair.evaluation.runner import evaluate, prepare
from waterair.evaluation.scenarios import SETTING_COLUMNS, Setting, scenarios_from_config

TINY = [
    "+scenarios=moving",
    "env.sea.n_dir=8",
    "env.compile_kernel=auto",
    "bootstrap.resamples=200",
    "baselines=[beacon_tracker,kalman_tracker]",
    "scenarios.S6.winds=[12.0]",
    "scenarios.S6.speeds=[0.0,1.5]",
    "scenarios.S6.attitudes_deg=[1.0,3.0]",
    "scenarios.S6.realisations=2",
    "scenarios.S6.steps=10",
    "scenarios.S7.periods_ms=[25.0,50.0]",
    "scenarios.S7.actuators=[ideal,gimbal]",
    "scenarios.S7.seconds=0.5",
    "scenarios.S7.realisations=2",
    "workers=1",
]


def test_s6_crosses_at_each_speed_parks_on_each_crossing_and_hovers_at_each_attitude():
    (s6, s7) = scenarios_from_config(compose_config("evaluate", TINY))
    one, three = math.radians(1.0), math.radians(3.0)
    assert s6.settings == (
        Setting(10, 0.0, False, one, actuator="gimbal_fsm"),
        Setting(10, 1.5, False, one, actuator="gimbal_fsm"),
        Setting(10, 1.5, True, one, actuator="gimbal_fsm"),
        Setting(10, 0.0, False, three, actuator="gimbal_fsm"),  # 1° hovering is the speeds' first: once
    )
    assert s6.points == ((12.0, 0.1, 0.0),) and s6.divergences == (0.01,)
    assert [(s.dt, s.actuator, s.steps) for s in s7.settings] == [
        (0.025, "ideal", 20), (0.05, "ideal", 10), (0.025, "gimbal", 20), (0.05, "gimbal", 10)
    ]  # fmt: skip


def test_a_setting_changes_the_env_it_names_and_a_crossing_passes_home_half_way_through_its_rollout():
    env = EnvConfig()  # 50 ms, 500 steps: an episode of 25 s
    crossing = Setting(120, 1.5, False, 0.03, actuator="gimbal_fsm").applied(env)
    assert crossing.motion.kind == "transit" and crossing.motion.transit_speed == 1.5
    assert crossing.motion.crossing_time == pytest.approx(3.0) and crossing.motion.drone_attitude == 0.03
    assert crossing.actuator.kind == "gimbal_fsm" and crossing.dt == env.dt
    assert Setting(120, 1.5, True).applied(env).motion.kind == "parked"
    assert Setting(120, 0.0).applied(env).motion.kind == "hover"
    period = Setting(800, dt=0.005, actuator="fsm", motion="hover").applied(env, eager=True)
    assert period.dt == 0.005 and period.max_steps == 5000 and period.episode_seconds == pytest.approx(25.0)
    assert period.motion.kind == "hover" and period.actuator.kind == "fsm" and period.compile_kernel is False
    columns = Setting(120, 1.5, True, 0.03).columns(env)
    assert columns == {"drone_speed": 1.5, "drone_attitude_deg": pytest.approx(math.degrees(0.03)), "parked": True,
                       "dt": 0.05, "actuator": "ideal"}  # fmt: skip


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("+scenarios.S6.speed=1.0", r"^scenarios\.S6\.speed is not a key of scenarios\.S6; its keys: "),
        ("scenarios.S6.actuator=mirror", r"^scenarios\.S6\.actuator = 'mirror' is not allowed; choose one of ideal"),
        ("scenarios.S6.speeds=[-1.0]", r"^scenarios\.S6\.speeds\[0\] = -1(\.0)? is out of range; allowed \[0, 50\]"),
        ("scenarios.S7.periods_ms=[0.0]", r"^scenarios\.S7\.periods_ms\[0\] = 0(\.0)? is out of range"),
        ("scenarios.S7.motion=flying", r"^scenarios\.S7\.motion = 'flying' is not allowed"),
        ("scenarios.S6.steps=600", r"^scenarios\.S6\.steps = 600 is out of range; allowed \[1, 500\]"),
    ],
)
def test_a_bad_study_value_names_its_key_before_any_rollout(override, message):
    with pytest.raises(ValueError, match=message):
        prepare(compose_config("evaluate", [*TINY, override]), policies=[])


def test_each_setting_runs_as_its_own_rollout_and_the_studies_write_their_rows_tables_and_figures(tmp_path):
    cfg = compose_config("evaluate", TINY)
    result = evaluate(cfg, policies=[], progress=lambda _: None)
    plan = prepare(cfg, policies=[])
    for scenario in result.scenarios:
        for setting in scenario.settings:
            columns = setting.columns(result.env)
            reference = reading(plan.env, ["kalman_tracker"])  # the scenario's env, with what the tracker reads
            env = setting.applied(reference.replace(optics={"divergence": 0.01}), eager=True)
            alone = rollout_policies(env, [("kalman_tracker", "kalman_tracker")], scenario.points, 2, setting.steps,
                                     scenario.seed)["kalman_tracker"]  # fmt: skip
            rows = [r for r in result.rows if r["scenario"] == scenario.name and r["policy"] == "kalman_tracker"
                    and all(r[key] == columns[key] for key in SETTING_COLUMNS)]  # fmt: skip
            assert len(rows) == 1 and rows[0]["steps"] == scenario.steps
            assert rows[0]["mean_gain"] == pytest.approx(alone["gain"][:, 0].double().mean().item(), rel=1e-9)
    s6 = {(r["drone_speed"], r["parked"], r["drone_attitude_deg"]): r for r in result.rows
          if r["scenario"] == "S6" and r["policy"] == "beacon_tracker"}  # fmt: skip
    assert len(s6) == 4 and len({r["mean_gain"] for r in s6.values()}) == 4  # each setting a link of its own
    out = tmp_path / "out"
    written = {p.name for p in write_outputs(result, out, cfg, physics=False)}
    assert written == {"metrics.json", "metrics.csv", "report.md", "rate_vs_speed.png", "rate_vs_period.png"}
    assert (out / "rate_vs_speed.png").stat().st_size > 5000 and (out / "rate_vs_period.png").stat().st_size > 5000
    data = json.loads((out / "metrics.json").read_text())
    assert data["schema_version"] == 8 and set(data["rows"][0]) == set(ROW_KEYS)
    s7 = next(s for s in data["scenarios"] if s["name"] == "S7")
    assert [(s["actuator"], s["dt"], s["steps"]) for s in s7["settings"]] == [
        ("ideal", 0.025, 20), ("ideal", 0.05, 10), ("gimbal", 0.025, 20), ("gimbal", 0.05, 10)
    ]  # fmt: skip
    report = (out / "report.md").read_text()
    assert "| policy | 0 m/s, 1° drone | 1.5 m/s, 1° drone | 1.5 m/s parked, 1° drone | 0 m/s, 3° drone |" in report
    assert "U10 = 12 m/s, offset 10%, gimbal:\n\n| policy | 25 ms | 50 ms |" in report
    assert "1 mW at 520 nm, APD (M = 40) with a 1000 MHz front end" in report
    assert torch.isfinite(torch.tensor([r["rate_held"] for r in result.rows])).all()
