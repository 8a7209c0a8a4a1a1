"""DDPG / TD3 training of the beam-alignment agent from a Hydra config (SPEC §8).

``train(cfg, run_dir)`` reads as the list of steps it takes; the ``make_*`` helpers below it build
each piece from its config group. ``train.py`` is the thin Hydra entry point.
"""

from __future__ import annotations

import csv
import json
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path

import torch
from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf
from tensordict import TensorDict
from tensordict.nn import TensorDictModule, TensorDictSequential
from torch import nn
from torchrl.collectors import Collector
from torchrl.data import LazyMemmapStorage, LazyTensorStorage, TensorDictReplayBuffer
from torchrl.envs import Compose, InitTracker, RewardSum, TransformedEnv
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.modules import MLP, AdditiveGaussianModule, OrnsteinUhlenbeckProcessModule, ValueOperator
from torchrl.objectives import DDPGLoss, SoftUpdate, TD3Loss
from tqdm import tqdm

from waterair._validation import check_choice, check_int, check_range
from waterair.baselines import FlatSeaSnell, StraightFacing
from waterair.env import WaterAirEnv
from waterair.env_config import EnvConfig, resolve_device
from waterair.metrics import summarise
from waterair.rewards import Reward

ACTIVATIONS = {"relu": nn.ReLU, "tanh": nn.Tanh, "elu": nn.ELU}

# hydra.run.dir is ${run_dir_or:${resume},outputs/...}: a resumed run continues in its own folder.
# (oc.select would not do: it keeps resume's explicit null.) Registered at import, before Hydra
# composes the config.
OmegaConf.register_new_resolver("run_dir_or", lambda run, default: default if run is None else run, replace=True)
TRANSITION_KEYS = (
    "observation",
    "action",
    ("next", "observation"),
    ("next", "reward"),
    ("next", "done"),
    ("next", "terminated"),
)
"""What the replay buffer stores: the losses read nothing else (the env's gains stay out)."""
CHECKPOINT = "checkpoints/last.pt"


@dataclass
class Progress:
    """Counters saved in every checkpoint."""

    frames: int = 0
    updates: int = 0
    episodes: int = 0


def train(cfg: DictConfig, run_dir: Path) -> dict[str, float]:
    """Train from ``cfg`` into ``run_dir`` (resuming from its checkpoint if ``cfg.resume``); return final metrics."""
    run_dir = Path(run_dir)
    validate(cfg)
    resumed = bool(cfg.resume) and (run_dir / CHECKPOINT).exists()
    device = resolve_device(cfg.device)
    torch.manual_seed(cfg.seed)
    (run_dir / "checkpoints").mkdir(parents=True, exist_ok=True)
    (run_dir / "config.yaml").write_text(OmegaConf.to_yaml(cfg, resolve=True))

    # Create the environment, agent, exploration, optimisers and replay buffer
    env = make_env(cfg)
    actor, critic = make_actor(cfg, env, device), make_critic(cfg, env, device)
    loss, target_update = make_loss(cfg, actor, critic, env)
    exploration = make_exploration(cfg, actor, env, device)
    optim_actor, optim_critic = make_optimisers(cfg, loss)
    buffer = make_buffer(cfg, run_dir, device)
    progress = Progress()
    if resumed:
        progress = load_checkpoint(run_dir, loss, exploration, optim_actor, optim_critic, env, buffer, cfg)

    # Create the collector, the update step and the logger
    collector = make_collector(cfg, env, exploration, progress)
    update = make_update(cfg, loss, target_update, optim_actor, optim_critic)
    log = RunLog(run_dir, resume_frames=progress.frames if resumed else None)
    if not resumed:
        log.text("config", "```\n" + OmegaConf.to_yaml(cfg, resolve=True) + "\n```")

    steps_per_batch = cfg.collector.frames_per_batch // cfg.env.num_envs
    bar = tqdm(total=cfg.total_frames, initial=progress.frames, disable=not cfg.logger.progress_bar, unit="frame")
    last_checkpoint, episode_reward = progress.frames, float("nan")
    clock = time.perf_counter()
    for batch in collector:
        env_seconds = time.perf_counter() - clock
        progress.frames += batch.numel()
        exploration[-1].step(steps_per_batch)
        buffer.extend(batch.select(*TRANSITION_KEYS).reshape(-1))
        clock = time.perf_counter()
        losses = []
        if progress.frames >= cfg.collector.init_random_frames and len(buffer) >= cfg.buffer.batch_size:
            for _ in range(max(1, round(batch.numel() * cfg.collector.updates_per_frame))):
                losses.append(update(buffer.sample(), progress.updates))
                progress.updates += 1
        update_seconds = time.perf_counter() - clock
        scalars = batch_scalars(batch, losses, exploration, env_seconds, update_seconds)
        progress.episodes += int(batch["next", "done"].sum())
        log.scalars(progress.frames, scalars)
        bar.update(batch.numel())
        episode_reward = scalars.get("train/episode_reward", episode_reward)  # episodes end every few batches
        bar.set_postfix(episode_reward=f"{episode_reward:.2f}", gain_ub=f"{scalars['train/gain_ratio_ub']:.3f}")
        if progress.frames - last_checkpoint >= cfg.checkpoint.every_frames or progress.frames >= cfg.total_frames:
            save_checkpoint(run_dir, progress, loss, exploration, optim_actor, optim_critic, env, buffer, cfg)
            last_checkpoint = progress.frames
        clock = time.perf_counter()
    bar.close()
    collector.shutdown()

    # Evaluate the greedy policy against the baselines on S1 and write the final metrics
    metrics = {"frames": progress.frames, "updates": progress.updates, "episodes": progress.episodes}
    metrics.update(evaluate_against_baselines(cfg, actor))
    # The evaluation goes to TensorBoard and final_metrics.json; the CSV keeps one row per batch.
    log.scalars(progress.frames, {f"eval/{k}": v for k, v in metrics.items() if "/" in k}, csv_row=False)
    log.hparams(_hparams(cfg), {f"hparam/{k}": v for k, v in metrics.items() if k.startswith("agent/")})
    log.close()
    _write_json(run_dir / "final_metrics.json", metrics)
    return metrics


def validate(cfg: DictConfig) -> None:
    """Check every key before any work; raise ``ValueError`` naming key, value and allowed range."""
    EnvConfig.from_mapping(OmegaConf.to_container(cfg.env, resolve=True))
    Reward(**OmegaConf.to_container(cfg.reward, resolve=True))
    check_choice("device", cfg.device, ("auto", "cpu", "cuda"))
    resolve_device(cfg.device)  # cuda without a CUDA device is an error now, not after the set-up
    check_int("seed", cfg.seed, 0, 2**63 - 1)
    check_int("total_frames", cfg.total_frames, 1)
    check_range("agent.gamma", cfg.agent.gamma, 0.0, 1.0, high_open=True)
    check_range("agent.tau", cfg.agent.tau, 0.0, 1.0, low_open=True)
    check_choice("agent.name", cfg.agent.name, ("ddpg", "td3"))
    check_int("agent.policy_delay", cfg.agent.policy_delay, 1, 1000)
    check_range("agent.policy_noise", cfg.agent.policy_noise, 0.0, 10.0)
    check_range("agent.noise_clip", cfg.agent.noise_clip, 0.0, 10.0)
    for net in ("actor", "critic"):
        check_range(f"{net}.lr", cfg[net].lr, 0.0, 1.0, low_open=True)
        check_choice(f"{net}.activation", cfg[net].activation, ACTIVATIONS)
        for width in cfg[net].hidden:
            check_int(f"{net}.hidden", width, 1, 1 << 16)
    check_choice("buffer.storage", cfg.buffer.storage, ("memory", "memmap"))
    check_int("buffer.batch_size", cfg.buffer.batch_size, 1, 1 << 20)
    check_int("buffer.capacity", cfg.buffer.capacity, cfg.buffer.batch_size)
    check_choice("noise.kind", cfg.noise.kind, ("gaussian", "ou"))
    check_range("noise.sigma_init", cfg.noise.sigma_init, 0.0, 10.0)
    check_range("noise.sigma_end", cfg.noise.sigma_end, 0.0, cfg.noise.sigma_init)
    check_int("noise.annealing_frames", cfg.noise.annealing_frames, 1)
    check_range("noise.theta", cfg.noise.theta, 0.0, 10.0)
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
    check_int("checkpoint.every_frames", cfg.checkpoint.every_frames, 1)
    check_int("eval.realisations", cfg.eval.realisations, 1)
    check_int("eval.steps", cfg.eval.steps, 1)
    if cfg.resume and not Path(cfg.resume).is_dir():
        raise ValueError(f"resume = {cfg.resume!r} is not a run directory")


# --- builders ----------------------------------------------------------------------------------


def make_env(cfg: DictConfig, **overrides) -> TransformedEnv:
    """The batched environment with episode-reward and init tracking (the OU noise needs is_init)."""
    config = EnvConfig.from_mapping({**OmegaConf.to_container(cfg.env, resolve=True), **overrides})
    reward = Reward(**OmegaConf.to_container(cfg.reward, resolve=True))
    return TransformedEnv(WaterAirEnv(config, reward=reward), Compose(InitTracker(), RewardSum()))


def make_actor(cfg: DictConfig, env, device) -> TensorDictModule:
    """Deterministic actor: MLP(observation) → tanh → action in [-1, 1]."""
    sizes = env.observation_spec["observation"].shape[-1], env.action_spec.shape[-1]
    return actor_module(cfg.actor, *sizes).to(device)


def actor_module(actor_cfg, observation_size: int, action_size: int) -> TensorDictModule:
    """The actor network of an ``actor`` config group (``hidden``, ``activation``), on the CPU."""
    net = nn.Sequential(
        MLP(
            in_features=observation_size,
            out_features=action_size,
            num_cells=list(actor_cfg.hidden),
            activation_class=ACTIVATIONS[actor_cfg.activation],
        ),
        nn.Tanh(),
    )
    return TensorDictModule(net, in_keys=["observation"], out_keys=["action"])


def make_critic(cfg: DictConfig, env, device) -> ValueOperator:
    """Q(s, a): MLP on the concatenated observation and action."""
    net = MLP(
        in_features=env.observation_spec["observation"].shape[-1] + env.action_spec.shape[-1],
        out_features=1,
        num_cells=list(cfg.critic.hidden),
        activation_class=ACTIVATIONS[cfg.critic.activation],
    )
    return ValueOperator(net, in_keys=["observation", "action"]).to(device)


def make_loss(cfg: DictConfig, actor, critic, env):
    """DDPGLoss or TD3Loss with a TD(0) value estimator at ``agent.gamma``, and its soft target update."""
    if cfg.agent.name == "td3":
        loss = TD3Loss(
            actor,
            critic,
            action_spec=env.action_spec_unbatched,
            policy_noise=cfg.agent.policy_noise,
            noise_clip=cfg.agent.noise_clip,
            loss_function="l2",
        )
    else:
        loss = DDPGLoss(actor, critic, loss_function="l2", delay_actor=True, delay_value=True)
    loss.make_value_estimator(gamma=cfg.agent.gamma)
    return loss, SoftUpdate(loss, tau=cfg.agent.tau)


def make_exploration(cfg: DictConfig, actor, env, device) -> TensorDictSequential:
    """Actor followed by annealed Gaussian or Ornstein-Uhlenbeck noise (off under DETERMINISTIC)."""
    steps = max(1, cfg.noise.annealing_frames // cfg.env.num_envs)  # stepped once per env step
    spec = env.action_spec_unbatched.to(device)
    if cfg.noise.kind == "ou":
        noise = OrnsteinUhlenbeckProcessModule(
            spec=spec,
            eps_init=1.0,
            eps_end=cfg.noise.sigma_end / max(cfg.noise.sigma_init, 1e-12),
            annealing_num_steps=steps,
            theta=cfg.noise.theta,
            sigma=cfg.noise.sigma_init,
            device=device,
        )
    else:
        noise = AdditiveGaussianModule(
            spec=spec,
            sigma_init=float(cfg.noise.sigma_init),
            sigma_end=float(cfg.noise.sigma_end),
            annealing_num_steps=steps,
            device=device,
        )
    return TensorDictSequential(actor, noise)


def make_optimisers(cfg: DictConfig, loss):
    actor_params = list(loss.actor_network_params.flatten_keys().values())
    critic_params = loss.qvalue_network_params if cfg.agent.name == "td3" else loss.value_network_params
    critic_params = list(critic_params.flatten_keys().values())
    return torch.optim.Adam(actor_params, lr=cfg.actor.lr), torch.optim.Adam(critic_params, lr=cfg.critic.lr)


def make_buffer(cfg: DictConfig, run_dir: Path, device) -> TensorDictReplayBuffer:
    """Uniform replay over flattened transitions; in memory or memory-mapped on disk."""
    if cfg.buffer.storage == "memmap":
        scratch = Path(cfg.buffer.scratch_dir) if cfg.buffer.scratch_dir else run_dir / "buffer"
        storage = LazyMemmapStorage(cfg.buffer.capacity, scratch_dir=str(scratch), existsok=True)
    else:
        storage = LazyTensorStorage(cfg.buffer.capacity, device=device)
    return TensorDictReplayBuffer(storage=storage, batch_size=cfg.buffer.batch_size)


def make_collector(cfg: DictConfig, env, policy, progress: Progress) -> Collector:
    """TorchRL Collector for the frames still to go (all of them unless resuming)."""
    remaining = max(cfg.total_frames - progress.frames, cfg.collector.frames_per_batch)
    remaining = math.ceil(remaining / cfg.collector.frames_per_batch) * cfg.collector.frames_per_batch
    random_frames = max(0, cfg.collector.init_random_frames - progress.frames)
    return Collector(
        env,
        policy,
        frames_per_batch=cfg.collector.frames_per_batch,
        total_frames=remaining,
        init_random_frames=random_frames,
        auto_register_policy_transforms=False,
    )


def make_update(cfg: DictConfig, loss, target_update, optim_actor, optim_critic):
    """One gradient step on a sampled batch; the actor steps every ``agent.policy_delay`` updates."""
    value_key = "loss_qvalue" if cfg.agent.name == "td3" else "loss_value"

    def update(batch: TensorDict, count: int) -> tuple[float, float]:
        losses = loss(batch)
        # Sum only the loss_* entries: pred_value etc. still require grad (NOTES-torchrl.md).
        update_actor = count % cfg.agent.policy_delay == 0
        total = losses[value_key] + (losses["loss_actor"] if update_actor else 0.0)
        optim_actor.zero_grad(set_to_none=True)
        optim_critic.zero_grad(set_to_none=True)
        total.backward()
        optim_critic.step()
        if update_actor:
            optim_actor.step()
        target_update.step()
        return losses["loss_actor"].item(), losses[value_key].item()

    return torch.compile(update) if cfg.compile_update else update


# --- per-batch statistics, evaluation ----------------------------------------------------------


def batch_scalars(batch, losses, exploration, env_seconds: float, update_seconds: float) -> dict[str, float]:
    """TensorBoard/CSV scalars of one collected batch."""
    nxt = batch["next"]
    gain, upper = nxt["gain"].double(), nxt["gain_upper_bound"].double()
    scalars = {
        "train/mean_gain": gain.mean().item(),
        "train/gain_ratio_ub": (gain.mean() / upper.mean()).item(),
        "train/outage": (nxt["intensity"] < 0.1).double().mean().item(),
        "train/mean_reward": nxt["reward"].double().mean().item(),
        "train/noise_scale": _noise_scale(exploration[-1]),
        "time/frames_per_s": batch.numel() / max(env_seconds + update_seconds, 1e-9),
        "time/env_share": env_seconds / max(env_seconds + update_seconds, 1e-9),
    }
    done = nxt["done"].squeeze(-1)
    if done.any():
        scalars["train/episode_reward"] = nxt["episode_reward"][done].double().mean().item()
    if losses:
        scalars["loss/actor"] = sum(a for a, _ in losses) / len(losses)
        scalars["loss/critic"] = sum(c for _, c in losses) / len(losses)
    return scalars


def evaluate_against_baselines(cfg: DictConfig, actor) -> dict[str, float]:
    """Greedy actor, straight-facing and flat-Snell on the same S1 seas (``eval`` group)."""
    results = {}
    env = make_env(cfg, num_envs=cfg.eval.realisations, max_steps=cfg.eval.steps, seed=cfg.eval.seed)
    base = env.base_env
    policies = {"agent": actor, "straight_facing": StraightFacing(base), "flat_snell": FlatSeaSnell(base)}
    for name, policy in policies.items():
        env.set_seed(cfg.eval.seed)
        with set_exploration_type(ExplorationType.DETERMINISTIC), torch.no_grad():
            rollout = env.rollout(cfg.eval.steps, policy, break_when_any_done=False)
        for key, value in summarise(rollout.cpu(), base.reference_gain.cpu()).items():
            results[f"{name}/{key}"] = value
    return results


# --- checkpoints -------------------------------------------------------------------------------


def save_checkpoint(run_dir, progress, loss, exploration, optim_actor, optim_critic, env, buffer, cfg) -> Path:
    """Write ``checkpoints/last.pt`` atomically (temp file, fsync, rename)."""
    state = {
        "frames": progress.frames,
        "updates": progress.updates,
        "episodes": progress.episodes,
        "loss": loss.state_dict(),
        "exploration": exploration[-1].state_dict(),
        "optim_actor": optim_actor.state_dict(),
        "optim_critic": optim_critic.state_dict(),
        "torch_rng": torch.get_rng_state(),
        "env_rng": env.base_env._generator.get_state(),
        "observation_size": env.base_env.observation_size,
    }
    path = Path(run_dir) / CHECKPOINT
    _atomic_save(state, path)
    if cfg.checkpoint.keep_buffer:
        buffer.dumps(str(Path(run_dir) / "checkpoints" / "buffer"))
    return path


def load_checkpoint(run_dir, loss, exploration, optim_actor, optim_critic, env, buffer, cfg) -> Progress:
    """Restore everything :func:`save_checkpoint` wrote; ``torch.load(weights_only=True)`` only."""
    path = Path(run_dir) / CHECKPOINT
    state = torch.load(path, map_location="cpu", weights_only=True)
    loss.load_state_dict(state["loss"])
    exploration[-1].load_state_dict(state["exploration"])
    optim_actor.load_state_dict(state["optim_actor"])
    optim_critic.load_state_dict(state["optim_critic"])
    torch.set_rng_state(state["torch_rng"])
    env.base_env._generator.set_state(state["env_rng"])
    buffer_dir = Path(run_dir) / "checkpoints" / "buffer"
    if cfg.checkpoint.keep_buffer and buffer_dir.exists():
        buffer.loads(str(buffer_dir))
    return Progress(state["frames"], state["updates"], state["episodes"])


def _atomic_save(state: dict, path: Path) -> None:
    temporary = path.with_name(path.name + ".tmp")
    with temporary.open("wb") as handle:
        torch.save(state, handle)
        handle.flush()
        os.fsync(handle.fileno())
    temporary.replace(path)


# --- sweeps ------------------------------------------------------------------------------------


class SweepSummary(Callback):
    """At the end of a multirun, write ``summary.csv`` (one row per job) at the sweep root."""

    def on_multirun_end(self, config: DictConfig, **kwargs) -> None:
        root = Path(config.hydra.sweep.dir)
        rows = []
        for metrics_path in sorted(root.glob("*/final_metrics.json"), key=lambda p: int(p.parent.name)):
            overrides_path = metrics_path.parent / ".hydra" / "overrides.yaml"
            overrides = OmegaConf.load(overrides_path) if overrides_path.exists() else []
            rows.append(
                {
                    "job": metrics_path.parent.name,
                    "overrides": " ".join(overrides),
                    **json.loads(metrics_path.read_text()),
                }
            )
        if rows:
            columns = list(dict.fromkeys(key for row in rows for key in row))
            with (root / "summary.csv").open("w", newline="") as handle:
                writer = csv.DictWriter(handle, fieldnames=columns)
                writer.writeheader()
                writer.writerows(rows)


def _noise_scale(noise) -> float:
    for name in ("sigma", "eps"):
        value = getattr(noise, name, None)
        if isinstance(value, torch.Tensor):
            return value.float().mean().item()
    return float("nan")


def _hparams(cfg: DictConfig) -> dict:
    flat = {}
    for group in ("agent", "reward", "noise"):
        for key, value in OmegaConf.to_container(cfg[group], resolve=True).items():
            if isinstance(value, int | float | str | bool):
                flat[f"{group}.{key}"] = value
    flat["env.wind"] = cfg.env.wind
    flat["env.offset_ratio"] = cfg.env.offset_ratio
    return flat


def _write_json(path: Path, data: dict) -> None:
    temporary = path.with_name(path.name + ".tmp")
    temporary.write_text(json.dumps(data, indent=2))
    temporary.replace(path)


from waterair.run_log import RunLog  # noqa: E402  (kept last: RunLog pulls in tensorboard)
