"""Gymnasium views (optional extra)."""

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium", reason="the gym extra is installed by `make test`")
from gymnasium.utils.env_checker import check_env  # noqa: E402

from waterair.envs.gym import WaterAirGymEnv, WaterAirVectorEnv  # noqa: E402

SMALL = {"sea": {"n_wavenumbers": 12, "n_dir": 8}}


def test_single_env_passes_gymnasium_check_env():
    env = WaterAirGymEnv(**SMALL, max_steps=20)
    check_env(env, skip_render_check=True)
    obs, info = env.reset(seed=3)
    assert obs.shape == (8,) and obs.dtype == np.float32
    assert set(info) == {"gain", "gain_upper_bound", "intensity", "path_valid"}


def test_single_env_truncates_after_max_steps():
    env = WaterAirGymEnv(**SMALL, max_steps=5)
    env.reset(seed=0)
    flags = [env.step(env.action_space.sample())[3] for _ in range(5)]
    assert flags == [False, False, False, False, True]


def test_vector_env_steps_and_autoresets_in_the_same_step():
    env = WaterAirVectorEnv(num_envs=3, max_steps=4, **SMALL)
    obs, _ = env.reset(seed=1)
    assert obs.shape == (3, 8)
    for _ in range(4):
        obs, reward, terminated, truncated, info = env.step(np.zeros((3, 4), dtype=np.float32))
        assert reward.shape == (3,) and np.isfinite(reward).all()
    assert truncated.all() and not terminated.any()
    assert info["_final_obs"].all()
    assert np.allclose(obs[:, -1], 0.0)  # reset links restart at relative time 0
    assert np.allclose(info["final_obs"][:, -1], 1.0)  # the final observation is at t = T_episode
