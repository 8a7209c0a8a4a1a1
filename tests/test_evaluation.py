"""evaluate.py and waterair.evaluation: schema, figures, same seas, the upper bound, checkpoint errors."""

import json
import math
import re
from pathlib import Path

import pytest
import torch
from conftest import compose_config, rejection
from omegaconf import OmegaConf

from waterair.agents.checkpoint import CheckpointError, policy_state, save_policy
from waterair.agents.networks import make_actor
from waterair.envs.operating_point import FIXED
from waterair.evaluation.comparisons import COMPARISON_KEYS
from waterair.evaluation.figures import even_strides, physics_figures
from waterair.evaluation.metrics import METRICS
from waterair.evaluation.per_divergence import serving
from waterair.evaluation.policies import (
    SHIPPED,
    TRAINED_ON,
    LearnedPolicy,
    latest_run,
    load_policy,
    shipped_policy,
    trained_on,
)
from waterair.evaluation.report import ROW_KEYS, write_outputs
from waterair.evaluation.rollouts import rollout_policies
from waterair.evaluation.runner import compare_policies, evaluate, prepare
from waterair.physics.sea import ElfouhailySea, JonswapSea
from waterair.training import train
from waterair.training.builders import env_config
from waterair.training.export import CHECK, export_policy, short_check

TRAIN_TINY = [
    "env.num_envs=8",
    "env.sea.n_dir=8",
    "env.max_steps=50",
    "total_frames=800",
    "collector.frames_per_batch=400",
    "collector.init_random_frames=400",
    "checkpoint.every_frames=800",
    "eval.realisations=2",
    "eval.steps=10",
    "logger.progress_bar=false",
    "buffer.capacity=2000",
    "actor.hidden=[32,32]",
    "critic.hidden=[32,32]",
    "compile_update=false",  # compiling costs more than this tiny run takes
    "env.compile_kernel=false",
]
EVAL_TINY = [
    "env.sea.n_dir=8",
    "env.compile_kernel=false",
    "bootstrap.resamples=200",
    "scenarios.S1.realisations=3",
    "scenarios.S1.steps=12",
    "scenarios.S2.offset_ratios=[0.0,0.2]",
    "scenarios.S2.realisations=2",
    "scenarios.S2.steps=8",
    "scenarios.S3.winds=[6.0,12.0]",
    "scenarios.S3.realisations=2",
    "scenarios.S3.steps=8",
    "scenarios.S4.azimuths_deg=[0.0,90.0]",
    "scenarios.S4.realisations=2",
    "scenarios.S4.steps=8",
    "scenarios.S5=null",  # its own test
    "workers=1",  # in the test's process; processes of their own: test_workers.py
]
S5_TINY = [
    "scenarios.S1=null",
    "scenarios.S2=null",
    "scenarios.S3=null",
    "scenarios.S4=null",
    "scenarios.S5.divergences_mrad=[10.0,50.0]",
    "scenarios.S5.winds=[20.0]",
    "scenarios.S5.offset_ratios=[0.1,0.5]",
    "scenarios.S5.realisations=2",
    "scenarios.S5.steps=8",
    "scenarios.S5.power_sweep.powers_w=[1.0e-5,1.0e-4,1.0e-3,1.0e-2]",
]
FIGURES = (
    "gain_vs_time",
    "ber_vs_time",
    "gain_vs_offset",
    "sigma_diff_vs_offset",
    "outage_vs_offset",
    "gain_vs_wind",
    "outage_vs_wind",
    "gain_vs_azimuth",
    "elfouhaily_spectrum",  # the default sea's
    "wave_surface",
)


def eval_cfg(*overrides):
    """The tiny evaluation config; S5 stays in when ``overrides`` set one of its keys."""
    study = any(o.lstrip("+").startswith("scenarios.S5.") for o in overrides)
    tiny = [o for o in EVAL_TINY if not (study and o == "scenarios.S5=null")]
    return compose_config("evaluate", [*tiny, *overrides])


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """A run directory trained for 800 frames with a 32×32 actor."""
    run_dir = tmp_path_factory.mktemp("run")
    train(compose_config("config", TRAIN_TINY), run_dir)
    return run_dir


def write_policy(
    path: Path, observation_size: int, extras=(), with_config=True, divergence=None, seed=0, **env
) -> Path:
    """A policy file with a random 16×16 actor for ``observation_size`` inputs (and a config beside it, with the
    ``env`` keys given and the beam divergence it was trained at where ``divergence`` is given)."""
    actor_cfg = OmegaConf.create({"hidden": [16, 16], "activation": "relu"})
    torch.manual_seed(seed)
    save_policy(path, policy_state(make_actor(observation_size, 4, [16, 16], "relu"), observation_size, None))
    if with_config:
        env = {"observation_extras": list(extras), "max_steps": 500, "sea": {"wind": 12.0}, **env}
        if divergence is not None:
            env["optics"] = {"divergence": divergence}
        OmegaConf.save(OmegaConf.create({"agent": {"name": "ddpg"}, "actor": actor_cfg, "env": env}),
                       path.with_suffix(".yaml"))  # fmt: skip
    return path


def latencies(groups) -> dict[str, int]:
    """Each member's latency: its replica's (``env.replica_sensing``)."""
    out = {}
    for config, members in groups:
        configs = config.replica_configs()
        out |= {label: configs[k % len(configs)].latency_steps for k, (label, _) in enumerate(members)}
    return out


def test_sensing_decides_whose_sensor_a_learned_policy_and_its_controllers_use(tiny_run):
    trained = prepare(eval_cfg(f"run={tiny_run}"))
    ((_, config, _),) = trained.learned
    assert config.latency_steps == 1 and config.intensity_noise == 0.05 and trained.env.latency_steps == 0
    late = [
        f"{name} (1-step latency, noisy, saturating)"
        for name in ("prediction_bound", "beacon_tracker", "kalman_tracker", "aoa_tracker", "intensity_dither")
    ]
    # the bound and the controllers with the policy's sensing are replicas of the baselines' group that sense their
    # own way
    (config, members), (_, [(label, _)]) = trained.groups
    assert [name for name, _ in members][-5:] == late and label == trained.policies[0].label
    assert latencies(trained.groups) == {name: int(name in late or name == label) for name in latencies(trained.groups)}
    assert config.latency_steps == 0 and config.replica_configs()[-1].intensity_saturation == 4.0
    scenario = prepare(eval_cfg(f"run={tiny_run}", "sensing=scenario"))
    assert scenario.learned[0][1].latency_steps == 0
    assert set(latencies(scenario.groups).values()) == {0} and len(scenario.groups) == 2
    with pytest.raises(ValueError, match=r"^sensing = 'mine' is not allowed"):
        prepare(eval_cfg(f"run={tiny_run}", "sensing=mine"))


@pytest.mark.slow
def test_evaluation_of_a_run_writes_the_schema_every_figure_and_the_report(tiny_run, tmp_path):
    cfg = eval_cfg(f"run={tiny_run}")
    result = evaluate(cfg, progress=lambda _: None)
    written = write_outputs(result, tmp_path, cfg)
    assert {p.name for p in written} >= {"metrics.json", "metrics.csv", "report.md"}

    data = json.loads((tmp_path / "metrics.json").read_text())
    assert data["schema_version"] == 8
    assert data["link"]["power_w"] == 0.05 and data["link"]["fec_power"] == pytest.approx(3.16e-8, rel=0.01)
    labels = [p["label"] for p in data["policies"]]
    references = ["tracking", "prediction_bound", "beacon_tracker", "kalman_tracker", "aoa_tracker"]
    references += ["intensity_dither", "flat_snell", "straight_facing", "no_alignment"]
    # the run trained with the realistic sensor (train.py's default): the prediction bound and the classical
    # controllers also run with its sensing, beside it, while the scenario's sensor stays ideal for the references
    realistic = [
        f"{name} (1-step latency, noisy, saturating)"
        for name in ("prediction_bound", "beacon_tracker", "kalman_tracker", "aoa_tracker", "intensity_dither")
    ]
    assert labels[0] == "upper_bound" and labels[2:] == references + realistic
    assert data["policies"][1]["kind"] == "learned" and data["policies"][1]["frames"] == 800
    points = {"S1": 1, "S2": 2, "S3": 2, "S4": 2}
    assert {s["name"]: len(s["points"]) for s in data["scenarios"]} == points
    assert len(data["rows"]) == sum(points.values()) * len(labels)
    for row in data["rows"]:
        assert set(row) == set(ROW_KEYS)
        for name in (*METRICS, "rate_held", "rate_held_999"):
            assert row[f"{name}_lo"] <= row[name] + 1e-12 and row[name] <= row[f"{name}_hi"] + 1e-12, (row, name)
        assert all(math.isfinite(row[name]) for name in ("ber", "outage", "rate")), row
        assert 0.0 <= row["ber"] <= 0.5 and 0.0 <= row["outage"] <= 1.0 and row["rate"] >= 0.0, row
        # the upper bound's outage is at most every policy's: the same seas, the most light at each step
        bound = next(r for r in data["rows"] if r["policy"] == "upper_bound" and _same_point(r, row))
        assert bound["outage"] <= row["outage"] and bound["ber"] <= row["ber"] + 1e-15, row
    # the learned policy against the controller its residual actions correct (realistic[2], the Kalman tracker),
    # sensing as it does, at every point
    assert [(c["scenario"], c["policy"], c["base"]) for c in data["comparisons"]] == [
        (name, labels[1], realistic[2]) for name, count in points.items() for _ in range(count)
    ]
    for comparison in data["comparisons"]:
        assert set(comparison) == set(COMPARISON_KEYS)
        row = next(r for r in data["rows"] if r["policy"] == labels[1] and _same_point(r, comparison))
        base = next(r for r in data["rows"] if r["policy"] == realistic[2] and _same_point(r, comparison))
        assert comparison["ratio_to_ub_diff"] == pytest.approx(row["ratio_to_ub"] - base["ratio_to_ub"], abs=1e-12)
        assert comparison["ratio_to_ub_diff_lo"] <= comparison["ratio_to_ub_diff"] <= comparison["ratio_to_ub_diff_hi"]
        assert (comparison["rate_held"], comparison["base_rate_held"]) == (row["rate_held"], base["rate_held"])
    csv_lines = (tmp_path / "metrics.csv").read_text().splitlines()
    assert csv_lines[0].split(",") == list(ROW_KEYS) and len(csv_lines) == 1 + len(data["rows"])

    report = (tmp_path / "report.md").read_text()
    for name in FIGURES:
        png = tmp_path / f"{name}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 5000, name
        assert f"]({name}.png)" in report
    assert labels[1] in report
    s1 = next(r for r in data["rows"] if r["scenario"] == "S1" and r["policy"] == labels[1])
    assert "| outage | mean BER | rate (Mbit/s) |" in report and "in outage below P_r = 31.6 nW" in report
    assert f"| {s1['outage']:.3%} [" in report and f"| {s1['ber']:.2g} | {s1['rate'] / 1e6:.3g} |" in report
    # S1's 12 steps of 50 ms: 10 of acquisition and 2 of tracking, reported apart; S2's 8 are all acquisition
    acquired = f"| {labels[1]} | {s1['acquisition_ratio_to_ub']:.3f} | {s1['acquisition_rate'] / 1e6:.3g} |"
    assert acquired in report and math.isfinite(s1["tracking_rate_held_999"])
    s2 = next(r for r in data["rows"] if r["scenario"] == "S2" and r["policy"] == labels[1])
    assert s2["acquisition_ratio_to_ub"] == s2["ratio_to_ub"] and math.isnan(s2["tracking_rate_held_999"])
    assert "Acquisition (the first 0.5 s of each realisation) and tracking (the rest) apart" in report
    assert "## Learned policies against their classical bases" in report
    assert (
        f"| S1 | 12 m/s, 10% | {labels[1]} | {realistic[2]} | {data['comparisons'][0]['ratio_to_ub_diff']:+.4f} ["
        in report
    )


def _same_point(a: dict, b: dict) -> bool:
    return all(a[key] == b[key] for key in ("scenario", "wind", "offset_ratio", "offset_azimuth_deg", "divergence"))


def _keeping_figures(monkeypatch) -> list:
    """The figures the report saves, kept open (matplotlib's) after they are written."""
    from waterair.evaluation import plots

    saved, close = [], plots.plt.close
    monkeypatch.setattr(plots.plt, "close", lambda figure=None: saved.append(figure) if figure is not None else close())
    return saved


def test_the_divergence_study_writes_its_tables_figures_and_power_sweep_on_its_own_link(tmp_path, monkeypatch):
    policy = write_policy(tmp_path / "policy.pt", observation_size=8)
    cfg = eval_cfg(f"checkpoint={policy}", *S5_TINY, "baselines=[flat_snell,aoa_tracker,no_alignment]")
    result = evaluate(cfg, progress=lambda _: None)
    out = tmp_path / "out"
    saved = _keeping_figures(monkeypatch)
    written = {p.name for p in write_outputs(result, out, cfg, physics=False)}
    assert written == {"metrics.json", "metrics.csv", "outage_vs_power.csv", "report.md", "rate_vs_divergence_20ms.png",
                       "outage_vs_power.png"}  # fmt: skip
    for figure in saved:  # as drawn: every axis label within its own panel's height, so none runs into another's
        figure.canvas.draw()
        for ax in (ax for ax in figure.axes if ax.get_ylabel()):
            label, panel = ax.yaxis.label.get_window_extent(), ax.get_window_extent()
            assert label.height <= panel.height, ax.get_ylabel()
    for name in ("rate_vs_divergence_20ms", "outage_vs_power"):
        assert (out / f"{name}.png").stat().st_size > 5000
    data = json.loads((out / "metrics.json").read_text())
    (study,) = data["scenarios"]
    assert study["divergences"] == [0.01, 0.05] and study["link"] == {"cutoff_hz": 1.0e9, "power_w": 0.001}
    labels = [p["label"] for p in data["policies"]]
    assert len(data["rows"]) == 2 * 2 * len(labels) == 2 * 2 * 5
    for row in data["rows"]:
        # the received power is the mean gain through the study's own link at the row's divergence, by hand
        w = row["divergence"] * math.sqrt(1 + (5.2e-7 / (math.pi * row["divergence"] ** 2)) ** 2)  # ω_D' (eq. 9.2)
        a_det = math.pi * 0.05**2 / 4 * math.sin(0.17) ** 2  # eq. 9.3, n_c = 1
        per_gain = 0.9 * 1.0e-3 * 2 / (math.pi * w**2) * a_det  # T_f P_t (J_0/P_t) A_det
        by_hand = 10 * math.log10(row["mean_gain"] * per_gain * 1e3) if row["mean_gain"] > 0 else -math.inf
        assert row["received_power_dbm"] == pytest.approx(by_hand, abs=1e-9)
        assert 0.0 <= row["rate_held"] <= row["rate"] / 0.99 + 1e-6 and row["rate"] <= 2.0e9  # the 1 GHz front end
        assert row["rate_held_999"] <= row["rate_held"]
        bound = next(r for r in data["rows"] if r["policy"] == "upper_bound" and _same_point(r, row))
        assert row["received_power_dbm"] <= bound["received_power_dbm"] + 1e-4
    # each policy's best divergence is where its mean rate is highest
    for best in study["best_divergence"]:
        rates = {r["divergence"]: r["rate"] for r in data["rows"] if r["policy"] == best["policy"]
                 and r["offset_ratio"] == best["offset_ratio"]}  # fmt: skip
        assert best["rate"] == max(rates.values()) and rates[best["divergence"]] == best["rate"]
    # outage against power: never rises with power, and at the study's own 1 mW it is the row's outage
    sweep = data["power_sweep"]
    assert len(sweep) == len(labels) * 2 * 4
    for label in labels:
        for offset in (0.1, 0.5):
            curve = [r for r in sweep if r["policy"] == label and r["offset_ratio"] == offset]
            assert [r["power_w"] for r in curve] == [1.0e-5, 1.0e-4, 1.0e-3, 1.0e-2]
            assert all(a["outage"] >= b["outage"] for a, b in zip(curve, curve[1:], strict=False)), curve
            row = result.row("S5", label, (20.0, offset, 0.0), 0.05)
            assert curve[2]["outage"] == row["outage"]
    assert curve[0]["outage"] == 1.0  # no light: never above the FEC limit
    report = (out / "report.md").read_text()
    assert "1 mW at 520 nm, APD (M = 40) with a 1000 MHz front end" in report
    assert "### Each policy's best divergence" in report and "### Outage against transmit power" in report
    learned = labels[1]  # what it gains over flat-sea Snell and the quadrant tracker, each at its best divergence
    assert f"| 20 | 10% | {learned} | flat_snell | " in report and f"| 20 | 50% | {learned} | aoa_tracker | " in report


def test_policies_trained_per_divergence_act_as_one_each_at_its_own_divergence(tmp_path):
    residual = {"action_mode": "residual", "residual_base": "flat_snell", "residual_deg": 2.0}  # some light at each
    narrow = write_policy(tmp_path / "narrow.pt", observation_size=8, divergence=0.01, seed=1, **residual)
    wide = write_policy(tmp_path / "wide.pt", observation_size=8, divergence=0.05, seed=2, **residual)
    study = [*S5_TINY, "baselines=[flat_snell]", "scenarios.S5.power_sweep=null", "labels=[mine]"]
    alone = {
        d: evaluate(eval_cfg(f"checkpoint={p}", *study), progress=lambda _: None)
        for d, p in ((0.01, narrow), (0.05, wide))
    }
    study[-1] = "labels=[mine,mine]"
    both = evaluate(eval_cfg(f"checkpoint=[{wide},{narrow}]", *study), progress=lambda _: None)
    assert [p["label"] for p in both.policies] == ["upper_bound", "mine", "flat_snell"]
    assert [(m["divergence"], Path(m["source"]).name) for m in both.policies[1]["per_divergence"]] == [
        (0.01, "narrow.pt"), (0.05, "wide.pt")]  # fmt: skip
    for divergence, other in ((0.01, 0.05), (0.05, 0.01)):
        for offset in (0.1, 0.5):
            point = (20.0, offset, 0.0)
            got = both.row("S5", "mine", point, divergence)
            # each divergence's own policy acts there: the same numbers as evaluated alone, not the other's
            assert got["ratio_to_ub"] == alone[divergence].row("S5", "mine", point, divergence)["ratio_to_ub"]
            assert got["ratio_to_ub"] != alone[other].row("S5", "mine", point, divergence)["ratio_to_ub"]
    # trained at the same divergence, or without a config saying which: two policies, told apart
    twice = prepare(eval_cfg(f"checkpoint=[{narrow},{narrow}]", "labels=[mine,mine]"))
    assert [p.label for p in twice.policies] == ["mine", "mine #2"]


def test_the_policy_acting_at_a_divergence_is_the_one_trained_nearest_on_a_log_scale():
    def trained(label, divergence):
        return LearnedPolicy(label, None, OmegaConf.create({"env": {"optics": {"divergence": divergence}}}))

    five, twenty, lone = trained("a", 0.005), trained("a", 0.02), trained("b", 0.05)
    policies = [five, twenty, lone]
    assert serving(policies, 0.009) == [five, lone]  # 1.8× from 5 mrad, 2.2× from 20
    assert serving(policies, 0.01) == [twenty, lone]  # 2× from each: the wider beam
    assert serving(policies, 0.1) == [twenty, lone]  # the lone policy acts everywhere


def test_the_report_says_what_a_policy_was_trained_on_each_draws_range_or_its_one_value():
    # the shipped default draws every condition per link: the report names each range, as its config holds it
    shipped = OmegaConf.to_container(OmegaConf.load(shipped_policy("default").with_suffix(".yaml")), resolve=True)
    assert trained_on(shipped["env"]) == {draw: shipped["env"][draw] for draw in TRAINED_ON}
    assert trained_on(shipped["env"])["divergence_range"] == [0.005, 0.1]
    # a run at one point: the values the ranges would replace, by their nested keys
    point = ["env.wind_range=null", "env.divergence_range=null", "env.sea.wind=8", "env.optics.divergence=0.01"]
    env = OmegaConf.to_container(compose_config("config", point), resolve=True)["env"]
    said = trained_on(env)
    assert said["sea.wind"] == 8.0 and said["optics.divergence"] == 0.01
    assert "wind_range" not in said and "divergence_range" not in said and said["offset_range"] == env["offset_range"]


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("scenarios.S5.link.power_w=-1", r"^scenarios\.S5\.link\.power_w = -1"),
        ("scenarios.S5.power_sweep.wind=12.0", r"^scenarios\.S5\.power_sweep\.wind = 12 must be one of"),
        ("scenarios.S5.divergences_mrad=[0.1]", r"^scenarios\.S5\.divergences_mrad\[0\] = 0\.1 is out of range"),
        ("+scenarios.S5.link.colour=1", r"^scenarios\.S5\.link\.colour is not a known key"),
    ],
)
def test_the_divergence_study_rejects_bad_values_naming_their_key(override, message):
    with pytest.raises(ValueError, match=message):
        prepare(eval_cfg(*S5_TINY, override))


@pytest.mark.slow
def test_every_policy_sees_the_same_seas_and_stays_under_the_upper_bound(tiny_run, tmp_path):
    # A second learned policy with the spot extra runs in its own environment (another interface):
    # its seas must still be the very same, because every group is seeded with the scenario's seed.
    spot = write_policy(tmp_path / "spot.pt", observation_size=10, extras=("spot",))
    result = evaluate(eval_cfg(f"run={tiny_run}", f"checkpoint={spot}"), progress=lambda _: None)
    kinds = [p["kind"] for p in result.policies]
    assert kinds == ["bound", "learned", "learned"] + ["baseline"] * (9 + 5)  # + the sensed ones with the run's sensing
    for scenario, traces in result.traces.items():
        # one bound per step for every row, under every policy's gain (the most any replica found)
        bound = traces["upper_bound"]["gain_upper_bound"]
        for label, trace in traces.items():
            assert torch.equal(trace["gain_upper_bound"], bound), (scenario, label)
            assert (trace["gain"] <= bound).all(), (scenario, label)
            if label not in ("upper_bound", "prediction_bound"):  # the bound's gain is the bound; the prediction
                # bound points about as near the present path as the search starts, and finds more on 11 % of steps
                assert (trace["gain"] < bound).double().mean() > 0.9, (scenario, label)
        # different policies did act differently on those seas
        assert not torch.equal(traces["straight_facing"]["gain"], traces["no_alignment"]["gain"])
    for row in result.rows:
        if row["policy"] == "upper_bound":
            assert row["ratio_to_ub"] == 1.0 and row["sigma2_diff"] == 0.0
        else:
            assert row["ratio_to_ub"] <= 1.0


def test_one_batch_for_all_policies_gives_the_same_numbers_as_one_rollout_each(tmp_path):
    policy = write_policy(tmp_path / "policy.pt", observation_size=8)
    lines = {True: [], False: []}
    skip = ("scenarios.S3=null", "scenarios.S4=null")
    results = [
        evaluate(eval_cfg(f"checkpoint={policy}", f"batch_policies={together}", *skip), progress=lines[together].append)
        for together in (True, False)
    ]
    # its processes, then one progress line per rollout, each with its own duration: S1 and S2 × one batch (the
    # baselines, the controllers and the policy, which reads its own columns of their observation), or × 10
    # policies one at a time
    assert all(lines[together].pop(0).startswith("Evaluating in 1 process of ") for together in lines)
    assert len(lines[True]) == 2 * 1 and len(lines[False]) == 2 * 10
    assert all(re.search(r": .+ in \d+ s \(eager\)$", line) for line in lines[True] + lines[False]), lines
    assert len(results[0].rows) == len(results[1].rows) == (1 + 2) * 11
    for batched, alone in zip(results[0].rows, results[1].rows, strict=True):
        assert batched["policy"] == alone["policy"]
        for name in METRICS:
            assert batched[name] == pytest.approx(alone[name], rel=1e-5, abs=1e-12), (batched["policy"], name)


def test_the_controllers_with_a_policys_sensor_score_beside_the_baselines_as_alone(tiny_run):
    """The classical controllers with the tiny run's sensor (one step late, noisy, saturating) run as replicas of
    the baselines' group that sense their own way, each reading its replica's latency and noise: every policy's
    metrics as in a rollout of its own, its sensor the whole batch's."""
    skip = ("scenarios.S2=null", "scenarios.S3=null", "scenarios.S4=null")
    runs = [evaluate(eval_cfg(f"run={tiny_run}", f"batch_policies={together}", *skip)) for together in (True, False)]
    sensed = [row["policy"] for row in runs[0].rows if "1-step latency" in row["policy"]]
    assert len(sensed) == 5 and len(runs[0].rows) == len(runs[1].rows)
    for batched, alone in zip(runs[0].rows, runs[1].rows, strict=True):
        assert batched["policy"] == alone["policy"]
        for name in METRICS:
            assert batched[name] == pytest.approx(alone[name], rel=1e-5, abs=1e-12), (batched["policy"], name)


def test_missing_and_corrupt_checkpoints_give_one_line_naming_the_file(tmp_path):
    missing = tmp_path / "nope.pt"
    with pytest.raises(CheckpointError) as info:
        load_policy(missing)
    assert str(info.value) == f"checkpoint {missing} does not exist"

    corrupt = tmp_path / "corrupt.pt"
    corrupt.write_bytes(b"this is not a torch file" * 10)
    with pytest.raises(CheckpointError) as info:
        load_policy(corrupt)
    assert str(info.value).startswith(f"checkpoint {corrupt} is not a torch file (")
    assert "\n" not in str(info.value)

    foreign = tmp_path / "foreign.pt"
    torch.save({"weights": torch.zeros(3)}, foreign)
    with pytest.raises(CheckpointError, match="is a torch file but not a waterair policy"):
        load_policy(foreign)

    truncated = tmp_path / "truncated.pt"
    whole = write_policy(tmp_path / "whole.pt", observation_size=8, with_config=False).read_bytes()
    truncated.write_bytes(whole[: len(whole) // 2])
    with pytest.raises(CheckpointError) as info:
        load_policy(truncated)
    assert str(info.value) == f"checkpoint {truncated} is truncated or damaged ({len(whole) // 2} bytes)"

    model = tmp_path / "model.pt"
    torch.save(torch.nn.Linear(2, 2), model)  # a whole module, not a state dictionary
    with pytest.raises(CheckpointError, match="is a torch file holding objects, not only tensors"):
        load_policy(model)

    newer = tmp_path / "newer.pt"
    torch.save({**torch.load(tmp_path / "whole.pt", weights_only=True), "format": "waterair-policy/9"}, newer)
    with pytest.raises(CheckpointError, match=r"format 'waterair-policy/9'; this waterair reads 'waterair-policy/1'"):
        load_policy(newer)


def test_incompatible_observation_size_names_the_file_and_both_sizes(tmp_path):
    # Trained with 10 observations (spot extra) but no config beside it: the evaluation env gives 8.
    policy = write_policy(tmp_path / "spot_policy.pt", observation_size=10, with_config=False)
    with pytest.raises(CheckpointError) as info:
        evaluate(eval_cfg(f"checkpoint={policy}"), progress=lambda _: None)
    message = str(info.value)
    assert str(policy) in message and "size 10" in message and "gives 8" in message and "\n" not in message


def test_weights_that_do_not_fit_the_configured_network_are_a_clear_error(tmp_path):
    policy = write_policy(tmp_path / "p.pt", observation_size=8, with_config=False)  # 16×16, config says 256×256
    with pytest.raises(CheckpointError) as info:
        evaluate(eval_cfg(f"checkpoint={policy}"), progress=lambda _: None)
    assert str(info.value) == (
        f"checkpoint {policy}: its actor has layers [16x8, 16x16, 4x16], but actor=mlp with hidden = [256, 256] "
        "builds [256x8, 256x256, 4x256]"
    )


@pytest.mark.parametrize(
    "override,key",
    [
        ("scenarios.S2.offset_ratios=[0.0,-0.1]", "scenarios.S2.offset_ratios[1]"),
        ("scenarios.S3.winds=[0.0]", "scenarios.S3.winds[0]"),
        ("scenarios.S1.steps=600", "scenarios.S1.steps"),
        ("scenarios.S1.realisations=0", "scenarios.S1.realisations"),
        ("baselines=[oracle]", "baselines"),
        ("device=tpu", "device"),
        ("bootstrap.level=1.0", "bootstrap.level"),
    ],
)
def test_invalid_evaluation_config_exits_before_any_rollout_with_one_line(override, key, tmp_path):
    policy = write_policy(tmp_path / "policy.pt", observation_size=8)
    overrides = [*EVAL_TINY, f"checkpoint={policy}", override, f"hydra.run.dir={tmp_path}"]
    assert rejection("evaluate.py", overrides).startswith(f"error: {key} = ")
    assert not (tmp_path / "metrics.json").exists()


def test_cli_missing_checkpoint_is_one_line(tmp_path):
    missing = tmp_path / "missing.pt"
    line = rejection("evaluate.py", [f"checkpoint={missing}", f"hydra.run.dir={tmp_path}"])
    assert line == f"error: checkpoint {missing} does not exist" and not any(tmp_path.iterdir())


@pytest.mark.slow
def test_exported_policy_acts_like_the_run_it_came_from(tiny_run, tmp_path):
    exported = export_policy(tiny_run, tmp_path / "policy")
    assert (tmp_path / "policy.yaml").exists() and (tmp_path / "policy_metrics.json").exists()
    assert exported.stat().st_size < (tiny_run / "checkpoints" / "last.pt").stat().st_size / 2
    run, export = load_policy(tiny_run / "checkpoints" / "last.pt"), load_policy(exported)
    size = run.file.observation_size
    observation = torch.randn(5, size)
    actors = [p.actor(None, size) for p in (run, export)]
    outputs = [a.module(observation) for a in actors]
    torch.testing.assert_close(outputs[0], outputs[1], rtol=0, atol=0)
    assert export.file.frames == 800 and export.config.actor.hidden == [32, 32]


def test_latest_run_is_the_newest_checkpoint(tmp_path):
    for name, stamp in (("2026-01-01/10-00-00", 100), ("2026-01-02/09-00-00", 300), ("2026-01-03/08-00-00", 200)):
        checkpoint = tmp_path / "outputs" / "train" / name / "checkpoints" / "last.pt"
        checkpoint.parent.mkdir(parents=True)
        checkpoint.write_bytes(b"x")
        import os

        os.utime(checkpoint, (stamp, stamp))
    assert latest_run(tmp_path) == tmp_path / "outputs" / "train" / "2026-01-02" / "09-00-00"
    with pytest.raises(CheckpointError, match="no run with checkpoints/last.pt"):
        latest_run(tmp_path / "empty")


BEACON_KEYS = ("beacon", "beacon_noise_rad", "beacon_threshold")
"""The env keys of the drone's beacon (docs/model.md §4.9)."""
LATER_KEYS = (*BEACON_KEYS, "divergence_range", "divergence_values", "residual_beams", "replica_actions",
              "replica_sensing", *FIXED, "draws", "link_offset", "actuator", "actuated", "motion")  # fmt: skip
"""The env keys that came after ``intensity`` and ``paper`` were trained: the beacon's (their sensors read none),
each link's own divergence (they were trained at one, ``optics.divergence``), the transmitter's residual in
beam widths, how each replica acts and senses, the operating point, where the draws come from, the ends'
actuators and whether they act, and how the ends move. Their defaults (null; no actuators; still ends) are how they
were trained, but for the draws': they were trained on the generator's stream (``env.draws=stream``), keyed draws'
default came after them. ``default``, re-earned on the moving ends, holds them all."""


@pytest.mark.parametrize("name", list(SHIPPED))
def test_each_shipped_policy_loads_matches_its_metrics_and_has_the_documented_config(name):
    path = shipped_policy(name)
    assert "actor" in torch.load(path, weights_only=True)
    policy = load_policy(path)
    # trained with the documented defaults (and its preset): the same keys and values as conf/ composes today
    documented = OmegaConf.to_container(compose_config("config", list(SHIPPED[name])), resolve=True)
    trained = OmegaConf.to_container(policy.config, resolve=True)
    if "link" not in trained:  # the link budget came after `paper` was trained: its config has none
        documented.pop("link")
    if "dir" not in trained["logger"]:  # the events' folder came after them all: null, where they wrote theirs
        assert documented["logger"].pop("dir") is None
    for key in LATER_KEYS:  # what a policy trained before them lacks, today's config holds at its default
        if key not in trained["env"]:
            documented["env"].pop(key)
    # whether to compile and on how many threads change the speed, not the policy: they were trained compiled,
    # before the threads key, and the default is now auto for both
    for config in (trained, documented):
        config.pop("compile_update"), config["env"].pop("compile_kernel"), config.pop("threads", None)
    assert policy.label == f"{documented['agent']['name']} {name}"
    assert trained == documented
    assert policy.file.frames == documented["total_frames"]
    metrics = json.loads(path.with_name(f"{name}_metrics.json").read_text())
    assert metrics["frames"] == policy.file.frames
    check = short_check(path)
    assert check == pytest.approx(metrics["check"], rel=1e-3)
    # on the check's seas, the paper's baseline scores below every shipped policy
    config = env_config(policy.config, compile_kernel=False, device="cpu", action_mode="absolute")
    references = {"straight_facing": "straight_facing", "flat_snell": "flat_snell"}
    baselines = compare_policies(config, references, CHECK)
    assert check["ratio_to_ub"] > baselines["straight_facing"]["ratio_to_ub"] + 0.02
    if name == "default":  # re-earned on the measured-slope sea and the full channel: ahead of flat-sea Snell
        assert config.channel.name == "full" and config.sea.spectrum == "elfouhaily"
        assert check["ratio_to_ub"] > baselines["flat_snell"]["ratio_to_ub"] + 0.01


@pytest.mark.parametrize(
    ("sea", "names"),
    [
        (JonswapSea(wind=8.0, n_freq=8, n_dir=4), ["jonswap_spectrum", "jonswap_directional", "wave_surface"]),
        (ElfouhailySea(wind=8.0, n_wavenumbers=8, n_dir=4), ["elfouhaily_spectrum", "wave_surface"]),
    ],
)
def test_the_physics_figures_draw_the_sea_evaluated_on_each_sea(sea, names, tmp_path):
    written = physics_figures(tmp_path, sea)
    assert [path.stem for path in written] == names
    assert all(path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for path in written)


@pytest.mark.parametrize(("rows", "cols"), [(121, 91), (120, 90), (7, 50), (2, 400)])
def test_a_surfaces_tiles_are_all_of_one_size_and_at_most_fifty_a_side(rows, cols):
    """matplotlib pads a surface's ragged tiles with uninitialised memory that it projects (a nondeterministic
    overflow warning): each stride divides the intervals, the smallest that does with at most 50 tiles. The
    physics figures' grids (121 × 121, 121 × 91) tile at stride 3 and 2; 120 points would need 7 (119 = 7 × 17),
    where matplotlib's default, 3, leaves a last tile of 2."""
    rstride, cstride = even_strides(rows, cols)
    for n, stride in ((rows, rstride), (cols, cstride)):
        assert (n - 1) % stride == 0 and (n - 1) / stride <= 50
        assert all((n - 1) % smaller or (n - 1) / smaller > 50 for smaller in range(1, stride))
    if (rows, cols) == (121, 91):
        assert (rstride, cstride) == (3, 2)


def test_learned_policies_that_observe_and_act_otherwise_join_the_groups_of_their_step_and_do_as_alone():
    """The shipped policies: ``paper`` observes fewer parts than the baselines, ``default`` and ``intensity`` act as
    residuals (on the beacon tracker, on flat-sea Snell) and observe two frames of their own parts. Each joins
    the baselines' group (their step is its own but for how they sense: ``paper`` the ideal sensor, the others their
    realistic one, beside the controllers with it) and reads, acts, senses and scores there as in a rollout of its
    own: the same gains to float32 rounding (the group also reads the beacon, which a lattice's sums share with the
    uplink)."""
    plan = prepare(eval_cfg())
    ((config, members),) = plan.groups
    labels = [label for label, _ in members]
    assert labels[-3:] == ["ppo default", "ppo intensity", "ddpg paper"] and config.frames == 2
    late = {label for label, replica in zip(labels, config.replica_configs(), strict=True) if replica.latency_steps}
    assert late == {"ppo default", "ppo intensity", *(label for label in labels if "1-step latency" in label)}
    assert config.latency_steps == 0 and len(late) == 7
    assert [dict(a).get("action_mode") for a in config.replica_actions] == [None] * 14 + ["residual"] * 2 + [None]
    points = [(12.0, 0.1, 0.0), (20.0, 0.3, 45.0)]
    together = {}
    for config, members in plan.groups:
        together.update(rollout_policies(config, members, points, 2, 10, 7))
    for policy, config, actor in plan.learned:
        alone = rollout_policies(config, [(policy.label, actor)], points, 2, 10, 7)[policy.label]
        for key in ("gain", "intensity"):
            torch.testing.assert_close(together[policy.label][key], alone[key], rtol=1e-5, atol=1e-9)
    assert not torch.allclose(together["ppo default"]["gain"], together["ppo intensity"]["gain"])
