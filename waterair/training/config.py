"""Validation of the composed training config, once, before any work (docs/training.md lists every key).

Every error is a ``ValueError`` whose one-line message names the key, the value and the allowed
range. Each option of a group is checked for exactly the keys it carries.
"""

from __future__ import annotations

from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from waterair.agents.networks import ACTIVATIONS, ACTORS
from waterair.agents.per_end import PER_END, per_end_columns
from waterair.agents.recurrent import CELLS
from waterair.core.devices import resolve_device
from waterair.core.threads import AUTO as AUTO_THREADS
from waterair.core.threads import check_threads
from waterair.core.validation import check_choice, check_int, check_range
from waterair.envs.config import EnvConfig
from waterair.envs.kernel import DIVERGENCE_SPAN
from waterair.envs.link import link_budget
from waterair.envs.rewards import Reward
from waterair.training.algorithms import ALGORITHMS
from waterair.training.compiling import CHOICES as COMPILE_CHOICES
from waterair.training.compiling import recompiles_every_call

CONF_DIR = Path(__file__).resolve().parents[2] / "conf"
"""The repository's Hydra config directory (the package is installed in place)."""
POLICY_WEIGHTS = ("average", "last")
"""What the saved and evaluated policy is: the actor's Polyak average (its target network), or its last iterate."""
NOISES = ("gaussian", "ou")
BUFFERS = ("memory", "memmap")
NETWORKS = ("mlp",)
"""The ``critic`` group's options (the ``actor``'s: :data:`waterair.agents.networks.ACTORS`)."""

# The config's own resolvers, registered at import, before Hydra composes the config. "This or that" (oc.select
# would not do: it keeps an explicit null): hydra.run.dir is ${or_else:${resume},outputs/...}, so that a resumed run
# continues in its own folder, and a group's key of the operating point takes env.<name> where it is set
# (env/sea/moderate.yaml: wind: ${or_else:${..wind},12.0}). The training's range of that quantity is off then
# (conf/config.yaml: wind_range: ${unless_set:${.wind},[4.0,20.0]}); docs/environment.md, "The operating point".
OmegaConf.register_new_resolver("or_else", lambda given, default: default if given is None else given, replace=True)
OmegaConf.register_new_resolver("unless_set", lambda given, value: value if given is None else None, replace=True)
# A Slurm job asks for one GPU when the run asks for cuda (hydra.launcher.gpus_per_node, docs/training.md).
# the divergences every link may draw with env/observation=beacon: the span the divergence feature is scaled over
OmegaConf.register_new_resolver("divergence_span", lambda: list(DIVERGENCE_SPAN), replace=True)
OmegaConf.register_new_resolver("gpus_for_device", lambda device: 1 if device == "cuda" else None, replace=True)


def is_group_choice(override: str) -> bool:
    """``group=option`` or ``+group=option`` (``agent=td3``, ``env/sensor=ideal``) for a config group of ours or of
    Hydra's, rather than a key's value."""
    key = override.lstrip("+~").split("=")[0]
    return key.startswith("hydra/") or (CONF_DIR / key).is_dir()


def validate(cfg: DictConfig) -> None:
    """Check every key before any work; raise ``ValueError`` naming key, value and allowed range."""
    values = OmegaConf.to_container(cfg.env, resolve=True)
    for key, value in (("env.compile_kernel", values.get("compile_kernel")), ("compile_update", cfg.compile_update)):
        check_choice(key, str(value).lower(), COMPILE_CHOICES)
    env = EnvConfig.from_mapping({**values, "compile_kernel": False})  # true, false or auto: decided at the start
    # a run saved before the link group has none: its link metrics use the default budget
    link = link_budget(OmegaConf.to_container(cfg.link, resolve=True) if "link" in cfg else None, env)
    Reward.from_mapping(OmegaConf.to_container(cfg.reward, resolve=True), link=link)
    resolve_device(cfg.device)  # cuda without a CUDA device is an error now, not after the set-up
    check_threads(cfg.get("threads", AUTO_THREADS))  # a run saved before the key: auto
    check_int("seed", cfg.seed, 0, 2**63 - 1)
    check_int("total_frames", cfg.total_frames, 1)
    _check_agent(cfg)
    check_choice("actor.name", cfg.actor.name, ACTORS)
    if cfg.actor.name in CELLS:
        check_int("actor.state_size", cfg.actor.get("state_size"), 1, 4096)
        check_int("actor.layers", cfg.actor.get("layers"), 1, 8)
    if cfg.actor.name == PER_END:
        check_int("actor.return_steps", cfg.actor.get("return_steps"), 0, 1000)
        per_end_columns(env.observation_layout, env.frames, cfg.actor.return_steps)  # every part has its end
        if str(cfg.compile_update).lower() == "true" and recompiles_every_call(cfg):
            raise ValueError(
                f"compile_update = true cannot compile actor=per_end's update with agent={cfg.agent.name}: TorchRL's "
                "MultiAgentMLP would recompile it at every call; use auto or false (its update runs eagerly)"
            )
    check_choice("critic.name", cfg.critic.name, NETWORKS)
    for net in ("actor", "critic"):
        check_range(f"{net}.lr", cfg[net].lr, 0.0, 1.0, low_open=True)
        check_choice(f"{net}.activation", cfg[net].activation, ACTIVATIONS)
        if not OmegaConf.is_list(cfg[net].hidden) and not isinstance(cfg[net].hidden, list | tuple):
            raise ValueError(f"{net}.hidden = {cfg[net].hidden!r} must be a list of layer widths, e.g. [256, 256]")
        for width in cfg[net].hidden:
            check_int(f"{net}.hidden", width, 1, 1 << 16)
    if not isinstance(cfg.actor.zero_output, bool):
        raise ValueError(f"actor.zero_output = {cfg.actor.zero_output!r} must be true or false")
    check_choice("buffer.name", cfg.buffer.name, BUFFERS)
    check_int("buffer.batch_size", cfg.buffer.batch_size, 1, 1 << 20)
    check_int("buffer.capacity", cfg.buffer.capacity, cfg.buffer.batch_size)
    _check_noise(cfg.noise)
    _check_collector(cfg)
    check_choice("logger.name", cfg.logger.name, ("tensorboard",))
    if cfg.logger.get("dir") is not None and not isinstance(cfg.logger.dir, str):  # a run saved before the key: none
        raise ValueError(f"logger.dir = {cfg.logger.dir!r} must be a folder's path, or null")
    check_int("checkpoint.every_frames", cfg.checkpoint.every_frames, 1)
    check_int("eval.realisations", cfg.eval.realisations, 1)
    check_int("eval.steps", cfg.eval.steps, 1, cfg.env.max_steps)
    check_int("eval.seed", cfg.eval.seed, 0, 2**63 - 1)


def _check_agent(cfg: DictConfig) -> None:
    """The keys every agent has, then the chosen algorithm's own (:meth:`Algorithm.check`)."""
    agent = cfg.agent
    check_choice("agent.name", agent.name, ALGORITHMS)
    check_range("agent.gamma", agent.gamma, 0.0, 1.0, high_open=True)
    check_choice("agent.policy_weights", agent.policy_weights, POLICY_WEIGHTS)
    algorithm = ALGORITHMS[agent.name]
    check_choice("agent.loss._target_", agent.loss._target_, (algorithm.loss_target,))
    algorithm.check(cfg)


def _check_noise(noise: DictConfig) -> None:
    check_choice("noise.name", noise.name, NOISES)
    check_range("noise.sigma_init", noise.sigma_init, 0.0, 10.0)
    check_range("noise.sigma_end", noise.sigma_end, 0.0, noise.sigma_init)
    check_int("noise.annealing_frames", noise.annealing_frames, 1)
    if noise.name == "ou":
        check_range("noise.theta", noise.theta, 0.0, 10.0)


def _check_collector(cfg: DictConfig) -> None:
    num_envs = cfg.env.num_envs
    frames_per_batch = check_int("collector.frames_per_batch", cfg.collector.frames_per_batch, num_envs)
    if frames_per_batch % num_envs:
        raise ValueError(
            f"collector.frames_per_batch = {frames_per_batch} is not allowed; it must be a multiple of "
            f"env.num_envs = {num_envs}"
        )
    if cfg.total_frames % frames_per_batch:
        raise ValueError(
            f"total_frames = {cfg.total_frames} is not allowed; it must be a multiple of "
            f"collector.frames_per_batch = {frames_per_batch} so that a run collects exactly that many frames"
        )
    check_int("collector.init_random_frames", cfg.collector.init_random_frames, 0)
    check_range("collector.updates_per_frame", cfg.collector.updates_per_frame, 0.0, 64.0, low_open=True)
