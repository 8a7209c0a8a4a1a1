"""Sensing (docs/environment.md): latency, noise, gating, presets, and the classical controllers."""

import dataclasses
import math

import pytest
import torch
from conftest import compose_config, paper_physics
from omegaconf import OmegaConf
from torchrl.envs.utils import check_env_specs

from waterair.envs.baselines import FlatSeaSnell
from waterair.envs.config import SENSOR_KEYS, EnvConfig
from waterair.envs.controllers import AoATracker, IntensityDither
from waterair.envs.env import WaterAirEnv
from waterair.envs.noise import stream_keys
from waterair.envs.sensors import PACKET_PARTS, Sensor, SensorSettings, intensity_feature, intensity_from_feature
from waterair.envs.state import Packet, Readings

SMALL = {"seed": 3, **paper_physics(n_freq=16, n_dir=8)}  # calibrated on the paper's sea and channel
QUADRANT = ("spot", "spot_valid", "history", "action_history", "geometry")


def rollout(steps=30, policy=None, **keys):
    env = WaterAirEnv(**{**SMALL, "num_envs": 6, "observation_extras": QUADRANT, **keys})
    if policy is None:
        generator = torch.Generator().manual_seed(1)
        actions = 0.05 * torch.randn(steps, 6, 4, generator=generator)
        td, out = env.reset(), []
        for action in actions:
            td = env.step(td.set("action", action))["next"]
            out.append(td["observation"])
        return env, torch.stack(out, dim=1)
    return env, env.rollout(steps, policy(env), break_when_any_done=False)["next", "observation"]


@pytest.mark.parametrize("latency", [1, 3])
def test_with_latency_k_the_sensor_readings_are_the_ideal_ones_k_steps_earlier(latency):
    env, ideal = rollout()
    _, late = rollout(latency_steps=latency)
    layout = env.config.observation_layout
    for name in layout:
        part = layout[name]
        if name in PACKET_PARTS:
            torch.testing.assert_close(late[:, latency:, part], ideal[:, :-latency, part], rtol=0, atol=0)
        else:  # time, own actions and geometry are the controller's own knowledge: never late
            torch.testing.assert_close(late[..., part], ideal[..., part], rtol=0, atol=0)


def test_the_ideal_sensor_reports_the_true_intensity_and_spot():
    env = WaterAirEnv(**SMALL, num_envs=5, observation_extras=("spot", "spot_valid"))
    td = env.reset()
    td = env.step(td.set("action", torch.zeros(5, 4)))["next"]
    observation = td["observation"]
    torch.testing.assert_close(env.observation_part(observation, "intensity")[:, 0], intensity_feature(td["intensity"]))
    lit = env.observation_part(observation, "spot_valid")[:, 0] > 0
    assert lit.any()
    assert (env.observation_part(observation, "spot")[~lit] == 0).all()


def test_below_the_gating_threshold_the_spot_reads_nothing_and_the_tracker_falls_back_to_flat_snell():
    # No alignment leaves little light at the receiver; a threshold of 2 (twice calm-sea) gates every reading.
    env = WaterAirEnv(**SMALL, num_envs=4, observation_extras=("spot", "spot_valid"), spot_threshold=2.0)
    td = env.step(env.reset().set("action", torch.zeros(4, 4)))["next"]
    observation = td["observation"]
    assert (env.observation_part(observation, "spot") == 0).all()
    assert (env.observation_part(observation, "spot_valid") == 0).all()
    tracker, flat = AoATracker(env)(td.clone())["action"], FlatSeaSnell(env)(td.clone())["action"]
    torch.testing.assert_close(tracker, flat)


def test_a_packet_travels_in_the_order_of_its_parts():
    assert (*Readings._fields, "history") == PACKET_PARTS and Packet._fields == ("readings", "history")


def test_the_sensor_settings_are_the_sensing_keys():
    assert tuple(field.name for field in dataclasses.fields(SensorSettings)) == SENSOR_KEYS
    assert SensorSettings() == SensorSettings(**EnvConfig().sensing)  # the defaults: the ideal sensor


def test_noise_spread_matches_the_configuration():
    count = 100_000
    settings = SensorSettings(intensity_noise=0.05, intensity_noise_floor=0.002, spot_noise_rad=0.001)
    sensor = Sensor(settings, 0.17, torch.Generator().manual_seed(0))
    ones = torch.ones(count, dtype=torch.float64)
    keys = stream_keys(count, 1)
    noise = sensor.draw(keys, torch.float64, torch.device("cpu"))
    relative = sensor.intensity(ones, noise) - 1.0  # relative 0.05 and floor 0.002 add in quadrature at I = 1
    assert relative.std().item() == pytest.approx(math.hypot(0.05, 0.002), rel=0.05)
    floor_only = Sensor(SensorSettings(intensity_noise_floor=0.002), 0.17, torch.Generator().manual_seed(1))
    floor_noise = floor_only.draw(keys, torch.float64, torch.device("cpu"))
    assert (floor_only.intensity(10 * ones, floor_noise) - 10).std().item() == pytest.approx(0.002, rel=0.05)
    lit = torch.ones(count, dtype=torch.bool)
    reading, valid = sensor.spot(torch.zeros(count, 2, dtype=torch.float64), lit, ones, noise)
    assert valid.all()
    expected = 0.001 / math.tan(0.17)  # 1 mrad of angle, in spot units
    assert reading.std(0).tolist() == pytest.approx([expected, expected], rel=0.05)
    saturating = Sensor(SensorSettings(intensity_saturation=4.0), 0.17, torch.Generator())
    assert saturating.draw(keys[:2], torch.float32, torch.device("cpu")) is None  # noiseless: draws nothing
    assert saturating.intensity(torch.tensor([1.0, 7.0]), None).tolist() == [1.0, 4.0]


def test_noisy_rollouts_are_reproducible_bit_for_bit_and_keep_the_seas():
    keys = {"intensity_noise": 0.05, "intensity_noise_floor": 1e-3, "spot_noise_rad": 1e-3, "latency_steps": 1}
    _, first = rollout(**keys)
    _, again = rollout(**keys)
    assert torch.equal(first, again)
    noisy_env = WaterAirEnv(**SMALL, num_envs=6, **keys)
    ideal_env = WaterAirEnv(**SMALL, num_envs=6)
    assert torch.equal(noisy_env.surface.phase, ideal_env.surface.phase)  # noise has its own generator


def test_intensity_feature_round_trips():
    intensity = torch.tensor([0.0, 1e-4, 0.3, 1.0, 2.5], dtype=torch.float64)
    torch.testing.assert_close(intensity_from_feature(intensity_feature(intensity)), intensity)


@pytest.mark.parametrize("preset", ["paper", "intensity", "quadrant"])
@pytest.mark.parametrize("num_envs", [1, 16])
def test_every_observation_preset_passes_the_spec_check(preset, num_envs):
    keys = OmegaConf.to_container(compose_config("config", [f"env/observation={preset}"]).env, resolve=True)
    # eager: the specs do not depend on compiling (tests/test_compiled_step.py compares the two)
    config = EnvConfig.from_mapping(
        {**keys, "num_envs": num_envs, "compile_kernel": False, **paper_physics(n_freq=16, n_dir=8)}
    )
    env = WaterAirEnv(config)
    check_env_specs(env)
    sizes = {"paper": 8, "intensity": 8 + 4 + 16, "quadrant": 8 + 2 + 1 + 2}
    assert config.frame_size == sizes[preset] and config.frames == 2  # train.py stacks two frames
    assert env.observation_spec["observation"].shape == (num_envs, 2 * sizes[preset])


def test_geometry_reads_the_drone_position_over_the_vertical_distance():
    geometry = {"offset_ratio": 0.3, "offset_azimuth_deg": 90}
    env = WaterAirEnv(**SMALL, num_envs=2, observation_extras=("geometry",), geometry=geometry)
    geometry = env.observation_part(env.reset()["observation"], "geometry")
    torch.testing.assert_close(geometry, torch.tensor([[0.0, 0.3], [0.0, 0.3]]), atol=1e-6, rtol=0)


def test_on_a_nearly_calm_sea_the_aoa_tracker_reaches_the_upper_bound():
    # A long, gentle swell (U10 0.5 m/s over 1e7 m: slopes of a few mrad): the one step of delay costs little.
    env = WaterAirEnv(
        num_envs=16,
        seed=0,
        observation_extras=("spot", "spot_valid"),
        **paper_physics(wind=0.5, fetch=1e7, n_freq=32, n_dir=16),
    )
    out = env.rollout(100, AoATracker(env), break_when_any_done=False)["next"]
    ratio = out["gain"].double().mean() / out["gain_upper_bound"].double().mean()
    assert ratio >= 0.99


@pytest.mark.slow
def test_the_controllers_beat_flat_snell_at_12_m_s():
    """The prototype's guide values: about 0.96 (quadrant) and 0.80 (intensity only) of UB, flat-Snell 0.70."""
    env = WaterAirEnv(num_envs=32, seed=4, observation_extras=("spot", "spot_valid"), **paper_physics())
    ratios = {}
    for policy in (AoATracker, IntensityDither, FlatSeaSnell):
        env.set_seed(4)
        out = env.rollout(100, policy(env), break_when_any_done=False)["next"]  # 5 s of sea, acquisition included
        ratios[policy.name] = (out["gain"].double().mean() / out["gain_upper_bound"].double().mean()).item()
    assert ratios["aoa_tracker"] > 0.93 and ratios["intensity_dither"] > 0.75
    assert ratios["intensity_dither"] > ratios["flat_snell"] + 0.05, ratios


def test_rotating_the_whole_scene_leaves_flat_snell_and_the_upper_bound_unchanged():
    """Drone azimuth and wind direction turned by the same angle: the same link, seen rotated."""
    traces = []
    for angle in (0.0, 120.0):
        env = WaterAirEnv(
            num_envs=24,
            seed=9,
            offset_azimuth_values=(angle,),
            wind_direction_values=(angle,),
            **paper_physics(n_freq=32, n_dir=16),
        )
        out = env.rollout(60, FlatSeaSnell(env), break_when_any_done=False)["next"]
        traces.append((out["gain"].double(), out["gain_upper_bound"].double()))
    (gain_a, upper_a), (gain_b, upper_b) = traces
    torch.testing.assert_close(upper_b.mean(), upper_a.mean(), rtol=1e-3, atol=0)
    torch.testing.assert_close(gain_b.mean(), gain_a.mean(), rtol=1e-3, atol=0)
    physics = {"geometry": {"offset_azimuth_deg": 120.0}, **paper_physics(n_freq=32, n_dir=16)}
    unrotated_sea = WaterAirEnv(num_envs=24, seed=9, **physics)
    assert not torch.allclose(
        upper_a, unrotated_sea.rollout(60, break_when_any_done=False)["next", "gain_upper_bound"].double()
    )


def test_per_link_azimuth_and_wind_direction_are_drawn_from_their_ranges():
    env = WaterAirEnv(**SMALL, num_envs=64, offset_azimuth_range=(0.0, 360.0), wind_direction_range=(-90.0, 90.0))
    rx = env.reset()["rx_position"]
    azimuth = torch.rad2deg(torch.atan2(rx[:, 1], rx[:, 0])) % 360
    assert azimuth.std() > 60  # spread around the circle, not all at 0
    torch.testing.assert_close(torch.linalg.vector_norm(rx[:, :2], dim=-1), torch.full((64,), 2.0), rtol=1e-5, atol=0)
    heading = torch.rad2deg(torch.atan2(env.surface.ky, env.surface.kx))  # per harmonic: wind ± 90°
    assert heading.abs().max() <= 180.0 + 1e-3 and heading.std() > 30


def test_in_delta_mode_late_telemetry_does_not_disturb_a_pointing_policy():
    """Policies steer from the commanded tilt, not from the (late) pointing telemetry in the observation."""
    traces = []
    for latency in (0, 2):
        physics = {**SMALL, **paper_physics(n_freq=16, n_dir=8, wind=4.0), "geometry": {"offset_ratio": 0.5}}
        env = WaterAirEnv(**physics, num_envs=8, action_mode="delta", latency_steps=latency)
        traces.append(env.rollout(40, FlatSeaSnell(env), break_when_any_done=False)["next", "intensity"])
    assert torch.equal(traces[0], traces[1])


@pytest.mark.parametrize("latency", [0, 1])
def test_the_intensity_dither_takes_no_probe_from_the_parked_gimbals_reading(latency):
    """Its first fit waits for three probes of its own: until then it points at flat-sea Snell plus the
    dither triangle; the reading the reset's parked gimbals took (lit at this near offset) is not one."""
    seen = []

    class Recorded(IntensityDither):
        def directions(self, tensordict):
            tx, rx = super().directions(tensordict)
            seen.append((tx[:, :2] - FlatSeaSnell.directions(self, tensordict)[0][:, :2]).clone())
            return tx, rx

    env = WaterAirEnv(**{**SMALL, "num_envs": 6, "latency_steps": latency, "geometry": {"offset_ratio": 0.05}})
    td = env.reset()
    assert (intensity_from_feature(td["observation"][:, env.config.observation_layout["intensity"]]) > 1e-3).all()
    env.rollout(latency + 5, Recorded(env), auto_reset=False, tensordict=td, break_when_any_done=False)
    radius = 0.12 * env.optics.divergence
    first_fit = latency + IntensityDither.PROBES  # parked decisions, then the ones gathering three own probes
    for k, offset in enumerate(seen[:first_fit]):
        angle = torch.tensor(2.0 * math.pi * (k % 3) / 3)
        dither = radius * torch.stack((torch.cos(angle), torch.sin(angle))).to(offset.dtype)
        torch.testing.assert_close(offset, dither.expand_as(offset), rtol=0, atol=1e-6)
    assert (seen[first_fit] - seen[0]).abs().max() > 1e-4  # then the fit steers


def test_the_intensity_dithers_fit_finds_the_gaussians_peak_at_a_narrow_beam_and_refuses_probes_on_a_line():
    """Three float32 probes (as the observation carries them) of a Gaussian of known peak, on the dither triangle
    0.4 ω_D from it: the fit, solved in float64, finds the peak to 2·10⁻⁵ ω_D at every divergence (in float32 it
    was 6·10⁻⁴ ω_D off at 5 mrad, where the system's tilt columns are about 4·10⁴). Two probes at one tilt (the
    pointing held while a reading was lost) leave no fit, and no error: in float32 the determinant's rounding
    passed its threshold and the solve stopped on a singular matrix on some CPUs."""
    env = WaterAirEnv(**{**SMALL, "num_envs": 4})
    dither = IntensityDither(env)
    divergence = torch.tensor([0.005, 0.01, 0.05, 0.1], dtype=torch.float64)
    peak = torch.tensor([[0.26, 0.25], [0.3, -0.06], [0.1, 0.2], [-0.2, 0.3]], dtype=torch.float64)
    target = peak + 0.4 * divergence[:, None] * torch.tensor([0.6, -0.8], dtype=torch.float64)
    angles = 2.0 * math.pi * torch.arange(3, dtype=torch.float64) / 3
    tilt = target[:, None] + dither.radius * divergence[:, None, None] * torch.stack((angles.cos(), angles.sin()), -1)
    log_intensity = -5.0 - 0.5 * (4.0 / divergence**2)[:, None] * ((tilt - peak[:, None]) ** 2).sum(-1)
    dither.probes = torch.cat((tilt, log_intensity.unsqueeze(-1)), -1).float()
    dither.count = torch.full((4,), IntensityDither.PROBES)
    best, usable = dither._fit(target.float(), divergence)
    assert usable.all()
    assert ((best.double() - peak).norm(dim=-1) / divergence).max() < 2e-5
    dither.probes[:, 1] = dither.probes[:, 0]
    best, usable = dither._fit(target.float(), divergence)
    assert not usable.any()
