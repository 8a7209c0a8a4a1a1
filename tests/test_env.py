"""The TorchRL environment (docs/environment.md): specs, actions, resets, seeding, finiteness."""

import pytest
import torch
from tensordict import TensorDict
from torchrl.envs.utils import check_env_specs

from waterair.core.devices import resolve_device
from waterair.envs.config import EnvConfig
from waterair.envs.env import WaterAirEnv
from waterair.envs.sensors import intensity_feature

SMALL_SEA = {"n_wavenumbers": 12, "n_dir": 8}  # the default sea (measured slopes) and channel (full), coarse


def small_env(**kwargs) -> WaterAirEnv:
    return WaterAirEnv(**{"seed": 0, "sea": SMALL_SEA, **kwargs})


@pytest.mark.parametrize("num_envs", [1, 16])
@pytest.mark.parametrize("action_mode", ["absolute", "delta"])
@pytest.mark.parametrize("extras", [(), ("spot", "history")])
def test_check_env_specs(num_envs, action_mode, extras):
    env = small_env(num_envs=num_envs, action_mode=action_mode, observation_extras=extras)
    check_env_specs(env)
    assert env.observation_spec["observation"].shape == (num_envs, 8 + (2 + 4) * bool(extras))
    assert env.action_spec.shape == (num_envs, 4)
    assert env.reward_spec.shape == (num_envs, 1)
    assert env.full_done_spec["truncated"].shape == (num_envs, 1)


def test_one_line_construction_uses_defaults():
    env = WaterAirEnv(num_envs=4, sea={"wind": 8.0, **SMALL_SEA}, device="cpu")
    assert env.batch_size == (4,)
    assert env.config.sea.wind == 8.0 and env.config.sea.fetch == 2.0e4 and env.config.max_steps == 500


@pytest.mark.slow
@pytest.mark.parametrize("wind", [4.0, 12.0, 25.0])
def test_long_random_rollouts_are_finite_and_below_the_upper_bound(wind):
    env = WaterAirEnv(num_envs=32, sea={"wind": wind, "n_wavenumbers": 24, "n_dir": 8}, seed=1, max_steps=150)
    rollout = env.rollout(150, break_when_any_done=False)  # 7.5 s of 32 seas at each wind
    nxt = rollout["next"]
    for key in ("observation", "reward", "gain", "gain_upper_bound", "intensity"):
        assert torch.isfinite(nxt[key]).all(), key
    assert (nxt["gain"] <= nxt["gain_upper_bound"] * (1 + 1e-5)).all()
    assert nxt["path_valid"].float().mean() > 0.97
    assert nxt["truncated"][:, -1].all() and not nxt["truncated"][:, :-1].any()


def test_actions_are_clipped_and_nan_is_rejected():
    env = small_env(num_envs=2)
    td = env.reset()
    td["action"] = torch.tensor([[5.0, 0.0, 0.0, -7.0], [1.0, 0.0, 0.0, -1.0]])
    out = env.step(td)["next"]["observation"]
    torch.testing.assert_close(out[0], out[1])
    # |v| is limited to sin(max_tilt): a (1, 1) action does not tilt further than (1, 0) does
    td = env.reset()
    td["action"] = torch.tensor([[1.0, 1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]])
    obs = env.step(td)["next"]["observation"]
    assert torch.linalg.vector_norm(obs[:, :2], dim=-1).max() <= env.config.max_tilt + 1e-6
    td["action"] = torch.tensor([[float("nan"), 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]])
    with pytest.raises(ValueError, match="NaN"):
        env.step(td)


def test_delta_mode_respects_the_slew_limit():
    env = small_env(num_envs=1, action_mode="delta", max_slew_deg_s=20.0, dt=0.05)
    td = env.reset()
    td["action"] = torch.tensor([[1.0, 0.0, 0.0, 0.0]])
    tilts = []
    for _ in range(3):
        td = env.step(td)["next"].set("action", td["action"])
        tilts.append(td["observation"][0, 0].item())
    step = torch.sin(torch.deg2rad(torch.tensor(1.0))).item()  # 20 deg/s × 0.05 s
    assert tilts == pytest.approx([step, 2 * step, 3 * step], rel=1e-5)


def test_partial_reset_changes_exactly_the_masked_links():
    env = small_env(num_envs=6)
    td = env.reset()
    td["action"] = torch.zeros(6, 4)
    for _ in range(3):
        td = env.step(td)["next"].set("action", torch.full((6, 4), 0.2))
    before_phase = env.surface.phase.clone()
    before_obs = td["observation"].clone()
    mask = torch.tensor([True, False, False, True, False, False]).unsqueeze(-1)
    # As in step_and_maybe_reset: rows not being reset are carried over from the input.
    out = env.reset(td.clone().set("_reset", mask))
    rows = mask.squeeze(-1)
    assert not torch.allclose(env.surface.phase[rows], before_phase[rows])
    torch.testing.assert_close(env.surface.phase[~rows], before_phase[~rows])
    torch.testing.assert_close(out["observation"][~rows], before_obs[~rows])
    assert (out["observation"][rows, -1] == 0).all()  # relative time restarted
    assert (env.state.steps[rows] == 0).all() and (env.state.steps[~rows] == 3).all()
    assert not out["done"].any()


def test_a_reset_row_and_a_stepped_row_are_recorded_by_the_same_function(monkeypatch):
    """The reset and the step go through kernel.record (the readings, the measurement, the stored warm start): a
    reset of some rows records those rows only, and writes every entry of their state (StepState.write_rows)."""
    from waterair.envs import kernel

    recorded, real = [], kernel.record
    monkeypatch.setattr(kernel, "record", lambda c, tilts, *args, **kw: recorded.append(len(tilts[0])) or real(
        c, tilts, *args, **kw))  # fmt: skip
    env = small_env(num_envs=6, intensity_noise=0.05, latency_steps=1)
    td = env.reset()
    td = env.step(td.set("action", torch.zeros(6, 4)))["next"]
    env.reset(td.clone().set("_reset", torch.tensor([False, True, False, False, True, False]).unsqueeze(-1)))
    assert recorded == [6, 6, 6, 2]  # built (all rows), reset (all), a step (all), two rows reset
    assert (env.state.steps == torch.tensor([1, 0, 1, 1, 0, 1])).all()
    assert (env.state.packets[[1, 4], 0] == env.state.packets[[1, 4], 1]).all()  # the first packet in every slot
    assert (env.state.time[[1, 4]] == 0).all() and (env.state.tx_tilt[[1, 4]] == 0).all()


def test_same_seed_same_rollout_different_seed_differs():
    def run(seed):
        env = small_env(num_envs=3)
        env.set_seed(seed)
        torch.manual_seed(123)  # random actions come from the global generator
        return env.rollout(20)

    a, b, c = run(5), run(5), run(6)
    torch.testing.assert_close(a["next", "gain"], b["next", "gain"])
    torch.testing.assert_close(a["next", "observation"], b["next", "observation"])
    assert not torch.allclose(a["next", "gain"], c["next", "gain"])


def test_step_writes_measurements_outside_the_observation():
    env = small_env(num_envs=4)
    td = env.reset()
    td["action"] = torch.zeros(4, 4)
    nxt = env.step(td)["next"]
    for key in ("gain", "gain_upper_bound", "intensity", "path_valid", "alpha_d", "alpha_a", "departure", "arrival"):
        assert key in nxt.keys()
    torch.testing.assert_close(nxt["intensity"], nxt["gain"] / env.state.reference_gain)
    torch.testing.assert_close(nxt["observation"][:, 6], intensity_feature(nxt["intensity"]))


def test_domain_randomisation_draws_per_link_values():
    env = small_env(num_envs=64, wind_range=(4.0, 20.0), offset_range=(0.0, 0.5))
    offsets = torch.linalg.vector_norm(env.state.rx_position[:, :2], dim=-1) / 20.0
    assert offsets.min() >= 0 and offsets.max() <= 0.5 and offsets.std() > 0.05
    variance = env.surface.variance()
    assert variance.max() > 5 * variance.min()  # 4 vs 20 m/s seas differ a lot


def test_per_link_values_cycle_through_scenario_points():
    winds, offsets = (4.0, 12.0, 20.0), (0.0, 0.25, 0.5)
    env = small_env(num_envs=6, wind_values=winds, offset_values=offsets)
    measured = torch.linalg.vector_norm(env.state.rx_position[:, :2] - env.state.tx_position[:, :2], dim=-1) / 20.0
    torch.testing.assert_close(measured, torch.tensor(offsets * 2), atol=1e-6, rtol=0)
    variance = env.surface.variance().double()
    # link i and link i + 3 share a point; the variance grows with the wind at every point (m0 ∝ U² here)
    assert (variance[1] > 3 * variance[0]) and (variance[2] > variance[1])
    assert (variance[4] > 3 * variance[3]) and (variance[5] > variance[4])
    # G_0 is computed per link from that link's own offset
    assert env.state.reference_gain[0] > env.state.reference_gain[1] > env.state.reference_gain[2]
    torch.testing.assert_close(env.state.reference_gain[:3], env.state.reference_gain[3:])


def test_replicas_share_their_seas_and_points_but_not_their_pointing():
    env = small_env(num_envs=6, replicas=3, offset_values=(0.3, 0.4))  # far enough that no alignment gets ~0
    td = env.reset()
    for k in (1, 2):
        for name in ("omega", "kx", "ky", "amplitude", "phase"):
            assert torch.equal(getattr(env.surface, name)[2 * k : 2 * k + 2], getattr(env.surface, name)[:2]), name
        torch.testing.assert_close(env.state.rx_position[2 * k : 2 * k + 2], env.state.rx_position[:2], rtol=0, atol=0)
    # the two distinct links are two points of one realisation: the same phases (paired), their own offsets
    assert torch.equal(env.surface.phase[0], env.surface.phase[1])
    assert not torch.equal(env.state.rx_position[0], env.state.rx_position[1])
    # different actions on identical seas: the same paths (and G_UB), different gains
    action = torch.zeros(6, 4)
    action[2:4] = env.action_for_pointing(td["departure"][2:4], -td["arrival"][2:4])
    td["action"] = action
    nxt = env.step(td)["next"]
    torch.testing.assert_close(nxt["gain_upper_bound"][2:4], nxt["gain_upper_bound"][:2], rtol=0, atol=0)
    assert (nxt["gain"][2:4] > 10 * nxt["gain"][:2]).all()


def test_replicas_measure_what_each_link_alone_measures():
    """The channel lights the replicas' pointing-independent lattice once per link (the bound's search too):
    each replica, pointed its own way for a few steps, measures what the same link alone measures."""
    links, replicas = 2, 3
    together = small_env(num_envs=links * replicas, replicas=replicas, offset_values=(0.1, 0.4))
    alone = small_env(num_envs=links, offset_values=(0.1, 0.4))
    generator = torch.Generator().manual_seed(1)
    actions = [0.5 * torch.rand(links * replicas, 4, generator=generator) - 0.25 for _ in range(3)]
    measured = {}
    for k in range(replicas):
        alone.set_seed(7)
        td = alone.reset()
        for action in actions:
            td["action"] = action[k * links : (k + 1) * links]
            td = alone.step(td)["next"]
        measured[k] = td
    together.set_seed(7)
    td = together.reset()
    assert torch.equal(together.surface.phase[:links], alone.surface.phase)  # the same seas
    for action in actions:
        td["action"] = action
        td = together.step(td)["next"]
    for k in range(replicas):
        rows = slice(k * links, (k + 1) * links)
        for key in ("gain", "gain_upper_bound", "intensity", "departure", "arrival"):
            torch.testing.assert_close(td[key][rows], measured[k][key], rtol=1e-5, atol=1e-12, msg=key)
    assert not torch.allclose(td["gain"][:links], td["gain"][links : 2 * links])  # pointed differently


def test_a_reset_mask_resets_the_replicas_of_a_link_together():
    env = small_env(num_envs=4, replicas=2)
    env.reset()
    together = torch.tensor([True, False, True, False]).unsqueeze(-1)
    env.reset(TensorDict({"_reset": together}, batch_size=[4]))
    with pytest.raises(ValueError, match=r"replicas of a link together \(env.replicas = 2: link i with link i \+ 2"):
        env.reset(TensorDict({"_reset": torch.tensor([True, False, False, False]).unsqueeze(-1)}, batch_size=[4]))


def test_spot_extra_is_zero_without_light_and_centred_when_aligned():
    env = small_env(num_envs=2, observation_extras=("spot",))
    td = env.reset()
    # link 0 follows the path exactly (receiver along −u_a); link 1 looks far away
    rx_dir = -td["arrival"]
    tx_dir = td["departure"]
    action = env.action_for_pointing(tx_dir, rx_dir)
    action[1] = torch.tensor([0.0, 0.0, 1.0, 1.0])
    td["action"] = action
    spot = env.step(td)["next"]["observation"][:, 8:10]
    assert spot[0].abs().max() < 0.5
    assert (spot[1] == 0).all()


@pytest.mark.parametrize(
    "kwargs,key",
    [
        ({"num_envs": 0}, "env.num_envs"),
        ({"dt": 0.0}, "env.dt"),
        ({"dt": -0.05}, "env.dt"),
        ({"action_mode": "velocity"}, "env.action_mode"),
        ({"sea": {"wind": -1.0}}, "env.sea.wind"),
        ({"max_tilt_deg": 95.0}, "env.max_tilt_deg"),
        ({"observation_extras": ("camera",)}, "env.observation_extras"),
        ({"wind_range": (5.0, 2.0)}, "env.wind_range[1]"),
        ({"wind_values": (12.0, 0.0)}, "env.wind_values[1]"),
        ({"offset_values": (0.1, 11.0)}, "env.offset_values[1]"),
        ({"num_envs": 6, "replicas": 4}, "env.replicas"),
        ({"solver": "bisection"}, "env.solver"),
        ({"optics": {"half_fov": 2.0}}, "env.optics.half_fov"),
    ],
)
def test_config_errors_name_key_value_and_range(kwargs, key):
    with pytest.raises(ValueError) as info:
        EnvConfig(**kwargs)
    message = str(info.value)
    assert message.startswith(f"{key} = "), message
    assert "allowed" in message or "choose one of" in message


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"wind_values": (), "offset_values": None}, "env.wind_values = \\[\\] must list"),
        ({"wind_values": (8.0,), "wind_range": (4.0, 20.0)}, "env.wind_values and env.wind_range are both set"),
        ({"wind_values": (8.0, 12.0), "offset_values": (0.1,)}, "env.wind_values has 2 entries"),
    ],
)
def test_per_link_values_must_be_consistent(kwargs, match):
    with pytest.raises(ValueError, match=match):
        EnvConfig(**kwargs)


def test_cuda_without_a_cuda_device_is_a_clear_error(monkeypatch):
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    assert resolve_device("auto") == torch.device("cpu")
    with pytest.raises(ValueError, match="device = 'cuda' is not available on this machine"):
        resolve_device("cuda")


def test_unknown_config_key_is_an_error():
    with pytest.raises(ValueError, match="env.wnd is not a known key"):
        EnvConfig().replace(wnd=3.0)


def test_observation_layout_names_every_part_in_order():
    config = EnvConfig(observation_extras=("history", "spot"), history_length=3)
    layout = config.observation_layout
    assert list(layout) == ["tx_pointing", "rx_pointing", "intensity", "time", "spot", "history"]
    assert [(part.start, part.stop) for part in layout.values()] == [(0, 3), (3, 6), (6, 7), (7, 8), (8, 10), (10, 13)]
    assert config.observation_size == 13
    env = small_env(num_envs=3, observation_extras=("spot",))
    observation = env.reset()["observation"]
    torch.testing.assert_close(env.observation_part(observation, "rx_pointing"), observation[:, 3:6])
    assert (env.observation_part(observation, "rx_pointing")[:, 2] == -1).all()  # straight down at reset


def test_every_action_mode_and_residual_base_the_config_allows_is_one_entry_of_the_steps_registries():
    from waterair.envs import bases, config, kernel

    assert set(kernel.ACTION_MODES) == set(config.ACTION_MODES)
    assert set(bases.RESIDUAL_BASES) == set(config.RESIDUAL_BASES)
