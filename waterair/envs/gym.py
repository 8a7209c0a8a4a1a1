"""Gymnasium views of :class:`waterair.envs.env.WaterAirEnv` for Stable-Baselines3 / CleanRL users.

* :class:`WaterAirGymEnv`: one link as a ``gymnasium.Env`` (passes ``check_env``).
* :class:`WaterAirVectorEnv`: B links as a ``gymnasium.vector.VectorEnv`` stepping one batched
  environment, with same-step autoreset (finished links are reset inside ``step``; their last
  observation is in ``info["final_obs"]``).

Observations are float32 NumPy arrays; ``info`` carries gain, upper bound, intensity and path
validity. Requires the ``gym`` extra (``pip install waterair[gym]``).
"""

from __future__ import annotations

import gymnasium
import numpy as np
import torch
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv

from waterair.envs.config import EnvConfig
from waterair.envs.env import WaterAirEnv
from waterair.envs.rewards import Reward

INFO_KEYS = ("gain", "gain_upper_bound", "intensity", "path_valid")
OBSERVATION_BOUNDS = (-10.0, 10.0)
"""Every observation entry lies here: unit pointing components and actions in [-1, 1], relative time
in [0, 1], the intensity feature (0 for no light, ≈ 1 at calm-sea level; G_UB / G_0 stays near 1
because the model has no focusing), the spot within ±1 inside the receiver's FOV (plus its noise),
and the geometry, the offset ratio (≤ 10) in each component."""


class WaterAirGymEnv(gymnasium.Env):
    """A single water-air link; same config keys as :class:`WaterAirEnv` (``num_envs`` is 1)."""

    metadata = {"render_modes": []}

    def __init__(self, config: EnvConfig | None = None, *, reward: Reward | None = None, **overrides):
        self.env = WaterAirEnv(config, reward=reward, **{**overrides, "num_envs": 1, "dtype": "float32"})
        size = self.env.observation_size
        self.observation_space = spaces.Box(*OBSERVATION_BOUNDS, shape=(size,), dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(4,), dtype=np.float32)
        self._td = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is not None:
            self.env.set_seed(seed)
        self._td = self.env.reset()
        return _numpy(self._td["observation"][0]), _info(self._td, 0)

    def step(self, action):
        self._td["action"] = torch.as_tensor(np.asarray(action, dtype=np.float32)).reshape(1, 4)
        nxt = self.env.step(self._td)["next"]
        self._td = nxt
        return (
            _numpy(nxt["observation"][0]),
            float(nxt["reward"][0, 0]),
            bool(nxt["terminated"][0, 0]),
            bool(nxt["truncated"][0, 0]),
            _info(nxt, 0),
        )


class WaterAirVectorEnv(VectorEnv):
    """B water-air links as one Gymnasium vector environment (same-step autoreset)."""

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.SAME_STEP}

    def __init__(self, config: EnvConfig | None = None, **overrides):
        self.env = WaterAirEnv(config, **{**overrides, "dtype": "float32"})
        self.num_envs = self.env.batch_size[0]
        size = self.env.observation_size
        self.single_observation_space = spaces.Box(*OBSERVATION_BOUNDS, shape=(size,), dtype=np.float32)
        self.single_action_space = spaces.Box(-1.0, 1.0, shape=(4,), dtype=np.float32)
        self.observation_space = spaces.Box(*OBSERVATION_BOUNDS, shape=(self.num_envs, size), dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(self.num_envs, 4), dtype=np.float32)
        self._td = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            self.env.set_seed(seed)
        self._td = self.env.reset()
        return _numpy(self._td["observation"]), _infos(self._td)

    def step(self, actions):
        self._td["action"] = torch.as_tensor(np.asarray(actions, dtype=np.float32)).reshape(self.num_envs, 4)
        nxt = self.env.step(self._td)["next"]
        reward, terminated, truncated = (_numpy(nxt[key].squeeze(-1)) for key in ("reward", "terminated", "truncated"))
        obs, info = _numpy(nxt["observation"]), _infos(nxt)
        done = nxt["done"].squeeze(-1)
        if done.any():
            info["final_obs"], info["_final_obs"] = obs.copy(), _numpy(done)
            nxt = self.env.reset(nxt.clone().set("_reset", done.unsqueeze(-1)))
            obs = _numpy(nxt["observation"])
        self._td = nxt
        return obs, reward, terminated, truncated, info


def _numpy(tensor: torch.Tensor) -> np.ndarray:
    return tensor.detach().cpu().numpy()


def _info(td, row: int) -> dict:
    return {key: _numpy(td[key][row]).item() for key in INFO_KEYS}


def _infos(td) -> dict:
    return {key: _numpy(td[key]) for key in INFO_KEYS}
