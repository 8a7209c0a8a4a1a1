"""PPO, DDPG, TD3 or SAC training of the beam-alignment agent from a Hydra config (docs/training.md).

``train(cfg, run_dir)`` reads as the list of steps it takes; :mod:`waterair.training.builders`
builds the shared pieces from their config groups and the algorithm that ``agent.name`` chooses
(:mod:`waterair.training.algorithms`) builds its own. ``train.py`` is the thin Hydra entry point.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path

import torch
from omegaconf import DictConfig, ListConfig, OmegaConf
from tensordict.nn.distributions.continuous import AddStateIndependentNormalScale
from tqdm import tqdm

from waterair.agents.checkpoint import load_state
from waterair.core.devices import resolve_device
from waterair.core.files import atomic_write_json, atomic_write_text
from waterair.core.threads import AUTO as AUTO_THREADS
from waterair.core.threads import choose_threads, torch_threads
from waterair.envs.controllers import CONTROLLERS, controller_for
from waterair.envs.operating_point import FIXED
from waterair.evaluation.compiling import compiled_group
from waterair.evaluation.groups import reading
from waterair.evaluation.metrics import FADE_FRACTION, METRICS
from waterair.evaluation.runner import compare_policies
from waterair.evaluation.scenarios import Scenario
from waterair.physics.link import LinkBudget, link_performance
from waterair.training.algorithms import create
from waterair.training.builders import env_config, make_actor, make_buffer, make_collector, make_env, make_link
from waterair.training.checkpoint import CHECKPOINT, Learner, Progress, load_checkpoint, save_checkpoint
from waterair.training.compiling import compile_plan
from waterair.training.config import is_group_choice, validate
from waterair.training.run_log import RunLog

FINAL_POLICIES = {"straight_facing": "straight_facing", "flat_snell": "flat_snell"}
"""Baselines the closing evaluation scores the trained agent against (label → baseline name), with the classical
controller its residual actions correct, or else the one of its sensing
(:func:`~waterair.envs.controllers.controller_for`)."""


def train(
    cfg: DictConfig,
    run_dir: Path,
    progress: Callable[[str], None] = print,
    on_checkpoint: Callable[[int], bool | None] | None = None,
    overrides: Sequence[str] = (),
) -> dict[str, float]:
    """Train from ``cfg`` into ``run_dir`` (resuming from its checkpoint if ``cfg.resume``); return final metrics.

    ``progress`` receives a line with torch's threads, one saying what runs compiled, and one when the
    closing evaluation starts and ends. ``on_checkpoint``, when given, is called with the frames done each time
    a checkpoint has been written (``run_dir/checkpoints/last.pt``); a true return ends the training there (the
    closing evaluation still runs): early stopping. The run uses ``threads`` torch threads
    (:func:`waterair.core.threads.choose_threads`); the caller's count is restored afterwards. The keys of the
    command line's ``overrides`` join the hyperparameters TensorBoard's hparams table shows (:func:`hyperparameters`).
    """
    validate(cfg)
    threads, why = choose_threads(cfg.get("threads", AUTO_THREADS))
    progress(f"Running on {threads} torch thread{'s' if threads > 1 else ''} ({why})")
    with torch_threads(threads):
        return _train(cfg, Path(run_dir), progress, on_checkpoint, overrides)


def _train(
    cfg: DictConfig,
    run_dir: Path,
    progress: Callable[[str], None],
    on_checkpoint: Callable[[int], bool | None] | None,
    overrides: Sequence[str],
) -> dict[str, float]:
    resumed = bool(cfg.resume) and (run_dir / CHECKPOINT).exists()
    device = resolve_device(cfg.device)
    torch.manual_seed(cfg.seed)
    (run_dir / "checkpoints").mkdir(parents=True, exist_ok=True)
    config_text = OmegaConf.to_yaml(cfg, resolve=True)
    config_path = run_dir / "config.yaml"
    if not config_path.exists() or config_path.read_text() != config_text:  # new, or total_frames raised
        atomic_write_text(config_path, config_text)
    # Decide the compiles (auto: whether the frames to go repay them); config.yaml keeps the setting.
    frames_done = int(load_state(run_dir / CHECKPOINT)["frames"]) if resumed else 0
    evaluation_compiles = str(cfg.env.compile_kernel).lower()  # auto: the closing evaluation decides its own
    cfg, compiles = compile_plan(cfg, cfg.total_frames - frames_done)
    progress(f"Running {compiles}")

    # Create the environment, algorithm, agent, exploration, optimisers and replay buffer
    env = make_env(cfg)
    link = make_link(cfg)
    algorithm = create(cfg)
    actor, critic = make_actor(cfg, env, device), algorithm.make_critic(env, device)
    exploration, noise = algorithm.make_exploration(actor, env, device)
    loss, target_update = algorithm.make_loss(actor, exploration, critic, env)
    optim_actor, optim_critic = algorithm.make_optimisers(loss)
    buffer = make_buffer(cfg, run_dir, device, on_policy=algorithm.on_policy)
    base = env.base_env
    learner = Learner(
        actor,
        loss,
        noise,
        optim_actor,
        optim_critic,
        base.rng,
        base.sensor_rng,
        buffer,
        base.observation_size,
        average=cfg.agent.policy_weights == "average",
        env_episodes=base.link_episodes,
    )
    counters = load_checkpoint(run_dir, learner, cfg.checkpoint.keep_buffer) if resumed else Progress()

    # Create the collector, the update and learning steps and the logger
    collector = make_collector(cfg, env, exploration, counters.frames)
    update = algorithm.make_update(loss, target_update, optim_actor, optim_critic)
    learn = algorithm.make_learn(loss, update, buffer, noise)
    log = RunLog(run_dir, resume_frames=counters.frames if resumed else None, events_dir=cfg.logger.get("dir"))
    if not resumed:
        log.text("config", "```\n" + OmegaConf.to_yaml(cfg, resolve=True) + "\n```")

    started = time.perf_counter()
    bar = tqdm(total=cfg.total_frames, initial=counters.frames, disable=not cfg.logger.progress_bar, unit="frame")
    last_checkpoint, episode_reward = counters.frames, "–"  # the last finished episode's, once there is one
    clock = time.perf_counter()
    for batch in collector:
        env_seconds = time.perf_counter() - clock
        counters.frames += batch.numel()
        clock = time.perf_counter()
        losses = learn(batch, counters)
        update_seconds = time.perf_counter() - clock
        scalars = batch_scalars(batch, losses, noise, env_seconds, update_seconds, link, algorithm.logged)
        counters.episodes += int(batch["next", "done"].sum())
        log.scalars(counters.frames, scalars)
        bar.update(batch.numel())
        if "train/episode_reward" in scalars:  # episodes end every few batches
            episode_reward = f"{scalars['train/episode_reward']:.2f}"
        bar.set_postfix(episode_reward=episode_reward, gain_ub=f"{scalars['train/gain_ratio_ub']:.3f}")
        if counters.frames - last_checkpoint >= cfg.checkpoint.every_frames or counters.frames >= cfg.total_frames:
            save_checkpoint(run_dir, counters, learner, cfg.checkpoint.keep_buffer)
            last_checkpoint = counters.frames
            if on_checkpoint is not None and on_checkpoint(counters.frames):
                break
        clock = time.perf_counter()
    bar.close()
    collector.shutdown()

    # Evaluate the greedy policy against the baselines on the training point and write the final metrics
    metrics = {
        "frames": counters.frames,
        "updates": counters.updates,
        "episodes": counters.episodes,
        "train_seconds": round(time.perf_counter() - started, 1),  # this process's loop (a resumed run: since resuming)
    }
    clock = time.perf_counter()
    seas = f"{cfg.eval.realisations} seas × {cfg.eval.steps} steps"
    progress(f"Evaluating the greedy policy, the baselines and the classical controller on {seas} …")
    metrics.update(final_evaluation(cfg, learner.policy(), evaluation_compiles == "auto"))
    progress(f"Evaluated in {time.perf_counter() - clock:.0f} s")
    # The evaluation goes to TensorBoard and final_metrics.json; the CSV keeps one row per batch.
    evaluated = {f"eval/{k}": v for k, v in metrics.items() if "/" in k}
    log.scalars(counters.frames, evaluated, csv_row=False)
    closing = [tag for tag in evaluated if tag.startswith("eval/agent/") or tag.endswith("/ratio_to_ub")]
    log.hparams(counters.frames, hyperparameters(cfg, overrides), closing)
    log.close()
    atomic_write_json(run_dir / "final_metrics.json", metrics)
    return metrics


def batch_scalars(
    batch,
    losses,
    noise,
    env_seconds: float,
    update_seconds: float,
    link: LinkBudget | None = None,
    logged: Sequence[str] = (),
) -> dict[str, float]:
    """TensorBoard/CSV scalars of one collected batch; the link's outage and BER of ``link`` (default budget), and
    the means of the updates' ``logged`` entries (the algorithm's, after its actor and critic losses)."""
    nxt = batch["next"]
    gain, upper = nxt["gain"].double(), nxt["gain_upper_bound"].double()
    delivered = link_performance(gain, link or LinkBudget())
    scalars = {
        "train/mean_gain": gain.mean().item(),
        "train/gain_ratio_ub": (gain.mean() / upper.mean()).item(),
        "train/outage": delivered.outage.double().mean().item(),
        "train/ber": delivered.ber.mean().item(),
        "train/fade_10db": (nxt["intensity"] < FADE_FRACTION).double().mean().item(),
        "train/mean_reward": nxt["reward"].double().mean().item(),
        "train/noise_scale": _noise_scale(noise),
        "time/frames_per_s": batch.numel() / max(env_seconds + update_seconds, 1e-9),
        "time/env_share": env_seconds / max(env_seconds + update_seconds, 1e-9),
    }
    done = nxt["done"].squeeze(-1)
    if done.any():
        scalars["train/episode_reward"] = nxt["episode_reward"][done].double().mean().item()
    if losses:
        means = torch.stack(losses).double().mean(0).tolist()  # one host sync per batch
        scalars["loss/actor"], scalars["loss/critic"] = means[:2]
        scalars.update(zip(logged, means[2:], strict=True))
        if "loss/kl" in logged:  # PPO's passes end early once the policy moved by target_kl: how many it took
            scalars["train/updates"] = len(losses)
    return scalars


def final_evaluation(cfg: DictConfig, actor, auto_compile: bool = False) -> dict[str, float]:
    """The greedy actor, straight-facing and flat-Snell on the same seas at the training wind and offset.

    Evaluation's own runner and metrics (``eval`` group: realisations, steps, seed); keys are
    ``<policy>/<metric>`` with the policy ``agent``, ``straight_facing``, ``flat_snell``, the classical
    controller (its residual base where that is one, else the one of its sensing) or ``upper_bound``.
    ``auto_compile``: each group compiles when its frames repay it
    (:func:`waterair.evaluation.compiling.compiled_group`), else as training ran.
    """
    geometry = cfg.env.geometry
    point = ((float(cfg.env.sea.wind), float(geometry.offset_ratio), float(geometry.offset_azimuth_deg)),)
    scenario = Scenario("train", "training point", None, point, cfg.eval.realisations, cfg.eval.steps, cfg.eval.seed)
    config = env_config(cfg)
    controller = controller_for(config.observation_extras)
    if config.action_mode == "residual" and config.residual_base in CONTROLLERS:  # the one it corrects
        controller = config.residual_base
    references = {**FINAL_POLICIES, controller: controller}
    # The references point in absolute tilts (a residual action's range need not reach their pointing), read
    # one frame of what they need and have no residual base to compute (flat-sea Snell's reads nothing): the
    # interface evaluate.py runs them in, so that evaluate.py on this run loads their compiled step from
    # torch's cache. Same seed, same seas: the two rollouts share one upper bound.
    bare = config.replace(action_mode="absolute", residual_base="flat_snell", observation_extras=(), frames=1)
    reference = reading(bare, references)
    link = make_link(cfg, config)
    if auto_compile:  # each of the two groups compiles when its own frames repay it, as in evaluate.py
        frames = cfg.eval.realisations * cfg.eval.steps
        reference = compiled_group(reference, frames * len(references))[0]
        config = compiled_group(config, frames)[0]
    results = compare_policies(reference, references, scenario, link=link, beside=[(config, {"agent": actor})])
    keep = (*METRICS, "mean_gain_lo", "mean_gain_hi")
    return {f"{label}/{key}": values[key] for label, values in results.items() for key in keep}


def _noise_scale(noise) -> float:
    """The exploration noise's present scale: annealed σ (Gaussian), ε (OU), or PPO's learned σ."""
    for name in ("sigma", "eps"):
        value = getattr(noise, name, None)
        if isinstance(value, torch.Tensor):
            return value.float().mean().item()
    if isinstance(noise, AddStateIndependentNormalScale):
        return noise.state_independent_scale.detach().exp().mean().item()
    return float("nan")


HPARAM_KEYS = ("seed", "total_frames", "actor.lr", "critic.lr", *(f"env.{name}" for name in FIXED))
"""Keys TensorBoard's hparams table shows for every run, beside the agent, reward and noise groups' and each key
of the command line (a resumed run's command line is ``resume=...``: these and the groups' keys are what it shows)."""


def hyperparameters(cfg: DictConfig, overrides: Sequence[str] = ()) -> dict[str, int | float | str | bool]:
    """The run's hyperparameters for TensorBoard's hparams table: the agent, reward and noise groups' keys,
    :data:`HPARAM_KEYS`, the sea's wind and the offset, and the keys of ``overrides`` (``agent.gamma=0.9`` as
    ``agent.gamma``, a group choice ``env/sensor=ideal`` as ``env/sensor``) with their values in ``cfg``. Keys whose
    value is null are left out (the table takes numbers, strings and booleans); a list is shown as its text."""
    keys = [f"{group}.{key}" for group in ("agent", "reward", "noise") for key in cfg[group]]
    keys += [*HPARAM_KEYS, "env.sea.wind", "env.geometry.offset_ratio"]
    found: dict[str, int | float | str | bool] = {}
    for override in overrides:
        key, _, value = override.lstrip("+~").partition("=")
        if key.split(".")[0].split("/")[0] in ("hydra", "resume"):
            continue
        if is_group_choice(override):  # a group's option (agent=td3, env/sensor=ideal), by its name
            found[key] = value
        elif key not in keys:
            keys.append(key)
    for key in keys:
        value = OmegaConf.select(cfg, key)
        if isinstance(value, DictConfig | ListConfig):
            value = OmegaConf.to_container(value, resolve=True)
        if isinstance(value, list | tuple):
            value = str(value)
        if isinstance(value, int | float | str | bool):
            found.setdefault(key, value)
    return found
