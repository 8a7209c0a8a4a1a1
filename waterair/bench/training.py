"""Training benchmark: ``python -m waterair.bench training`` (see :mod:`waterair.bench`).

The whole suite runs on the torch threads of ``--threads`` (``auto``: train.py's rule,
:func:`waterair.core.threads.choose_threads`), each training run in a fresh process as train.py
would start it.

* **update**: one DDPG update (batch 64, 256 × 256 MLPs, Adam, soft target update) in our
  pipeline (TorchRL ``DDPGLoss`` on a ``TensorDictReplayBuffer`` sample), eager and compiled,
  against the same networks and math written as bare PyTorch (tensors indexed from preallocated
  storage), with the eager update's breakdown (sample, loss, backward and optimiser steps, target
  update). At the default run's updates per frame, the bare update alone bounds a loop's frames/s.
* **runs**: ``train()`` on the default configuration (PPO) for a short and a long run, eager and
  compiled: frames per second of collection, of the updates and of the whole loop (collection plus
  updates), over the whole run (the compiles included) and after its first batch, and the wall time
  of the call (set-up, compiles and a two-sea closing evaluation included); ``agent=ddpg``
  compiled for the long run;
* **sb3**: Stable-Baselines3 DDPG on our Gymnasium view of the same environment, at the default
  run's updates per frame, with DDPG's networks, batch and learning rates, if
  ``stable_baselines3`` can be imported;
* **load**: the short default run (and SB3) again with a busy single-threaded Python loop beside
  it, which the suite starts and stops: frames/s loaded over quiet, at torch's own thread count
  (one per CPU, the behaviour before ``threads``) and at ``--threads``.
"""

from __future__ import annotations

import copy
import csv
import json
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import torch
from hydra import compose, initialize_config_dir
from torch import nn

from waterair.bench.common import COLLECTOR_OFF, last_line_of_fresh_python
from waterair.bench.sb3 import sb3_ddpg
from waterair.core.process import set_up_process
from waterair.core.threads import choose_threads, torch_threads
from waterair.training.algorithms.ddpg import DDPG
from waterair.training.algorithms.off_policy import TRANSITION_KEYS
from waterair.training.builders import make_actor, make_buffer, make_env
from waterair.training.compiling import compile_plan
from waterair.training.config import CONF_DIR

BUFFER_FILL = 20_000
TORCH_THREADS = torch.get_num_threads()
"""torch's own intra-op thread count in this process before the suite changes it: one per CPU it sees
(or ``OMP_NUM_THREADS``), what every run used before the ``threads`` key."""
COMPILED = ["env.compile_kernel=true", "compile_update=true"]
EAGER = ["env.compile_kernel=false", "compile_update=false"]


def compose_training(overrides: list[str]):
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        return compose(config_name="config", overrides=overrides)


def _fill(buffer, env, count: int) -> None:
    """Random transitions from the environment (the update's cost does not depend on their values)."""
    td = env.reset()
    while len(buffer) < count:
        td = env.rand_step(td)
        buffer.extend(td.select(*TRANSITION_KEYS).reshape(-1))
        td = td["next"]


def _median_ms(fn, count: int) -> float:
    samples = []
    for _ in range(count):
        start = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - start)
    return 1e3 * statistics.median(samples)


def bench_update(updates: int) -> dict:
    """Per-update milliseconds: our pipeline eager and compiled, its breakdown, and bare PyTorch."""
    cfg = compose_training(["agent=ddpg", "device=cpu", "env.compile_kernel=false"])
    env = make_env(cfg)
    ddpg = DDPG(cfg)
    actor, critic = make_actor(cfg, env, "cpu"), ddpg.make_critic(env, "cpu")
    loss, target_update = ddpg.make_loss(actor, None, critic, env)  # DDPG learns the actor itself
    with tempfile.TemporaryDirectory() as scratch:
        buffer = make_buffer(cfg, Path(scratch), "cpu", on_policy=DDPG.on_policy)
        _fill(buffer, env, BUFFER_FILL)
        batch = cfg.buffer.batch_size
        record: dict = {}
        for compiled in (False, True):
            cfg.compile_update = compiled  # read by make_optimisers and make_update (ddpg holds this cfg)
            optim_actor, optim_critic = ddpg.make_optimisers(loss)
            if not compiled:
                terms = ddpg.loss_terms(loss)  # what the eager update computes its losses with
                breakdown = _breakdown(buffer, batch, terms, target_update, optim_actor, optim_critic, updates)
                record["breakdown_eager_ms"] = breakdown
            update = ddpg.make_update(loss, target_update, optim_actor, optim_critic)
            for i in range(30):  # warm-up (and the compile)
                update(buffer.sample(batch), i)
            record["ours_compiled_ms" if compiled else "ours_eager_ms"] = _median_ms(
                lambda update=update: update(buffer.sample(batch), 0), updates
            )
        record["bare_ms"] = bench_bare(cfg, env.base_env.observation_size, buffer, updates)
    record["ratio_eager"] = record["ours_eager_ms"] / record["bare_ms"]
    record["ratio_compiled"] = record["ours_compiled_ms"] / record["bare_ms"]
    return record


def _breakdown(buffer, size: int, terms, target_update, optim_actor, optim_critic, count: int) -> dict:
    parts = {"sample": [], "loss": [], "backward_and_steps": [], "target_update": []}
    for _ in range(count):
        t0 = time.perf_counter()
        batch = buffer.sample(size)
        t1 = time.perf_counter()
        actor_loss, value_loss = terms(batch)
        t2 = time.perf_counter()
        optim_actor.zero_grad(set_to_none=True)
        optim_critic.zero_grad(set_to_none=True)
        (value_loss + actor_loss).backward()
        optim_critic.step()
        optim_actor.step()
        t3 = time.perf_counter()
        target_update.step()
        t4 = time.perf_counter()
        for key, value in zip(parts, (t1 - t0, t2 - t1, t3 - t2, t4 - t3), strict=True):
            parts[key].append(value)
    return {key: 1e3 * statistics.median(values) for key, values in parts.items()}


def bench_bare(cfg, observation_size: int, buffer, updates: int) -> float:
    """The same DDPG update in bare PyTorch: MLPs, targets, Adam, Polyak averaging; ms per update."""
    storage = buffer[: len(buffer)]
    obs, action = storage["observation"], storage["action"]
    next_obs, reward = storage["next", "observation"], storage["next", "reward"]
    done = storage["next", "terminated"].float()

    def mlp(inputs: int, outputs: int, hidden, last=None) -> nn.Sequential:
        layers, size = [], inputs
        for width in hidden:
            layers += [nn.Linear(size, width), nn.ReLU()]
            size = width
        layers.append(nn.Linear(size, outputs))
        if last is not None:
            layers.append(last)
        return nn.Sequential(*layers)

    actor = mlp(observation_size, 4, cfg.actor.hidden, nn.Tanh())
    critic = mlp(observation_size + 4, 1, cfg.critic.hidden)
    actor_target, critic_target = copy.deepcopy(actor), copy.deepcopy(critic)
    optim_actor = torch.optim.Adam(actor.parameters(), lr=cfg.actor.lr)
    optim_critic = torch.optim.Adam(critic.parameters(), lr=cfg.critic.lr)
    pairs = list(zip(actor_target.parameters(), actor.parameters(), strict=True))
    pairs += list(zip(critic_target.parameters(), critic.parameters(), strict=True))
    gamma, tau, batch = cfg.agent.gamma, cfg.agent.tau, cfg.buffer.batch_size

    def update() -> None:
        index = torch.randint(0, obs.shape[0], (batch,))
        o, a, o2, r, d = obs[index], action[index], next_obs[index], reward[index], done[index]
        with torch.no_grad():
            target = r + gamma * (1 - d) * critic_target(torch.cat((o2, actor_target(o2)), -1))
        value_loss = (critic(torch.cat((o, a), -1)) - target).pow(2).mean()
        for p in critic.parameters():
            p.requires_grad_(False)
        actor_loss = -critic(torch.cat((o, actor(o)), -1)).mean()
        for p in critic.parameters():
            p.requires_grad_(True)
        optim_actor.zero_grad(set_to_none=True)
        optim_critic.zero_grad(set_to_none=True)
        (value_loss + actor_loss).backward()
        optim_critic.step()
        optim_actor.step()
        with torch.no_grad():
            torch._foreach_lerp_([t for t, _ in pairs], [s for _, s in pairs], tau)

    for _ in range(30):
        update()
    return _median_ms(update, updates)


def bench_training(
    updates: int,
    short_frames: int,
    long_frames: int,
    sb3_frames: int,
    threads: int | str,
    load: bool = True,
    overrides: tuple[str, ...] = (),
) -> dict:
    """Every measurement of the module docstring, in this order, on the threads ``threads`` chooses;
    ``overrides`` (train.py's, e.g. ``env/channel=single_path``) apply to every run, SB3's included."""
    count, why = choose_threads(threads)
    extra = list(overrides)
    record: dict = {"benchmark": "training", "overrides": extra}
    record["threads"] = {"setting": threads, "count": count, "why": why, "torch_default": TORCH_THREADS}
    default = compose_training(extra)
    utd = float(default.collector.updates_per_frame)
    with torch_threads(count):
        record["update"] = bench_update(updates)
        record["update"]["updates_per_frame"] = utd
        record["update"]["bare_bound_frames_per_s"] = 1e3 / (utd * record["update"]["bare_ms"])
        record["runs"] = []
        for frames in (short_frames, long_frames):
            plan, auto = compile_plan(default, frames)  # what train.py would choose for this run
            for mode, switches in (("eager", EAGER), ("compiled", COMPILED)):
                row = train_run(frames, [*extra, *switches, f"threads={threads}"])
                chosen = plan.compile_update == (mode == "compiled")
                record["runs"].append({"mode": mode, "auto": auto, "default": chosen, **row})
        record["train_ddpg"] = train_run(long_frames, [*extra, "agent=ddpg", *COMPILED, f"threads={threads}"])
        record["sb3"] = bench_sb3(sb3_frames, utd, extra)
        if load:
            settings = [str(TORCH_THREADS)] + ([str(threads)] if str(threads) != str(TORCH_THREADS) else [])
            record["load"] = bench_load(short_frames, settings, sb3_frames, utd, extra)
    if record["sb3"] is not None:
        for row in record["runs"]:
            row["over_sb3"] = row["loop_frames_per_s"] / record["sb3"]["frames_per_s"]
    return record


def train_run(frames: int, overrides: list[str]) -> dict:
    """``train()`` on the default configuration with ``overrides`` for ``frames`` frames, in a fresh process."""
    args = json.dumps({"frames": frames, "overrides": overrides})
    child = COLLECTOR_OFF + "import sys; from waterair.bench.training import run_in_child; run_in_child(sys.argv[1])"
    return json.loads(last_line_of_fresh_python(child, [args], f"the training run {overrides}"))


def run_in_child(args: str) -> None:
    """The child of :func:`train_run`: one run, then its timings as the last line of stdout (JSON).

    Collection and update seconds are the loop's own per-batch timings (``metrics.csv``); the first
    batch holds the compiles, if any. Its imports done, their objects are frozen, as train.py freezes its own
    (:func:`~waterair.core.process.set_up_process`; :func:`train_run` starts it with the collector off).
    """
    from waterair.training.loop import train

    set_up_process()
    request = json.loads(args)
    frames, overrides = request["frames"], request["overrides"]
    with tempfile.TemporaryDirectory() as run_dir:
        cfg = compose_training(
            [f"total_frames={frames}", f"checkpoint.every_frames={frames}", "eval.realisations=2", "eval.steps=10"]
            + ["logger.progress_bar=false", *overrides]
        )
        lines: list[str] = []
        start = time.perf_counter()
        metrics = train(cfg, Path(run_dir), progress=lines.append)
        wall = time.perf_counter() - start
        with open(Path(run_dir) / "metrics.csv", newline="") as handle:
            rows = list(csv.DictReader(handle))
    batch = cfg.collector.frames_per_batch
    seconds = [batch / float(row["time/frames_per_s"]) for row in rows]
    collect = [s * float(row["time/env_share"]) for s, row in zip(seconds, rows, strict=True)]
    update = [s - c for s, c in zip(seconds, collect, strict=True)]
    record = {"frames": frames, "overrides": overrides, "threads": lines[0], "compiles": lines[1], "wall_s": wall}
    record["updates_per_frame"] = metrics["updates"] / frames
    for part, values in (("collect", collect), ("update", update), ("loop", seconds)):
        record[f"{part}_frames_per_s"] = frames / sum(values)
        record[f"{part}_after_first_batch_frames_per_s"] = (
            (frames - batch) / sum(values[1:]) if len(values) > 1 else None
        )
    print(json.dumps(record))


def bench_sb3(frames: int, updates_per_frame: float, overrides: list[str] | None = None) -> dict | None:
    """Stable-Baselines3 DDPG (:func:`waterair.bench.sb3.sb3_ddpg`) on one link of the environment
    ``agent=ddpg`` trains on (with ``overrides``) at ``updates_per_frame``, timed over ``frames`` frames
    after a warm-up past its first updates."""
    settings = [*(overrides or []), "agent=ddpg", f"collector.updates_per_frame={updates_per_frame}"]
    model = sb3_ddpg(compose_training(settings))
    if model is None:
        return None
    model.learn(3000)
    start = time.perf_counter()
    model.learn(frames, reset_num_timesteps=False)
    return {
        "frames": frames,
        "updates_per_frame": updates_per_frame,
        "frames_per_s": frames / (time.perf_counter() - start),
    }


def bench_load(
    frames: int, settings: list[str], sb3_frames: int, updates_per_frame: float, overrides: list[str] | None = None
) -> dict:
    """The default run (with ``overrides``) of ``frames`` frames at each thread setting, quiet then beside a
    busy process, and SB3."""
    record: dict = {"frames": frames, "rows": []}
    extra = list(overrides or [])
    for setting in settings:
        quiet = train_run(frames, [*extra, f"threads={setting}"])
        with busy_process():
            loaded = train_run(frames, [*extra, f"threads={setting}"])
        ratio = loaded["loop_frames_per_s"] / quiet["loop_frames_per_s"]
        record["rows"].append({"threads": setting, "quiet": quiet, "loaded": loaded, "loaded_over_quiet": ratio})
    quiet_sb3 = bench_sb3(sb3_frames, updates_per_frame, extra)
    if quiet_sb3 is not None:
        with busy_process():
            loaded_sb3 = bench_sb3(sb3_frames, updates_per_frame, extra)
        ratio = loaded_sb3["frames_per_s"] / quiet_sb3["frames_per_s"]
        record["sb3"] = {"quiet": quiet_sb3, "loaded": loaded_sb3, "loaded_over_quiet": ratio}
    return record


@contextmanager
def busy_process() -> Iterator[None]:
    """A single-threaded Python loop in its own process for the duration of the block."""
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        yield
    finally:
        busy.kill()
        busy.wait()


def training_table(record: dict) -> str:
    u, t = record["update"], record["threads"]
    lines = [
        f"torch threads: {t['count']} ({t['why']}); torch's own default here: {t['torch_default']}",
        f"overrides of every run: {' '.join(record.get('overrides', [])) or 'none (the defaults)'}",
        "",
        "| quantity | value |",
        "|---|---|",
        f"| DDPG update, ours eager | {u['ours_eager_ms']:.2f} ms |",
        f"| DDPG update, ours compiled | {u['ours_compiled_ms']:.2f} ms |",
        f"| DDPG update, bare PyTorch | {u['bare_ms']:.2f} ms |",
        f"| ratio ours / bare (eager, compiled) | {u['ratio_eager']:.2f}, {u['ratio_compiled']:.2f} |",
        "| eager breakdown (ms) | " + ", ".join(f"{k} {v:.2f}" for k, v in u["breakdown_eager_ms"].items()) + " |",
        f"| bare update alone at {u['updates_per_frame']:.4g} updates a frame "
        f"| {u['bare_bound_frames_per_s']:,.0f} frames/s |",
        f"| train.py frames/s (agent=ddpg, compiled, {record['train_ddpg']['frames']:,} frames) "
        f"| {record['train_ddpg']['loop_frames_per_s']:,.0f} |",
    ]
    sb3 = record["sb3"]
    lines.append(
        f"| SB3 DDPG frames/s at {u['updates_per_frame']:.4g} updates a frame | {sb3['frames_per_s']:,.0f} |"
        if sb3
        else "| SB3 DDPG | not installed |"
    )
    lines += [
        "",
        "| run | frames | collection frames/s | update frames/s | whole loop frames/s | after the first batch "
        "| wall (s) | loop over SB3 |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for row in record["runs"]:
        name = f"{row['mode']}{' (auto)' if row['default'] else ''}"
        after, over = row["loop_after_first_batch_frames_per_s"], row.get("over_sb3")
        lines.append(
            f"| {name} | {row['frames']:,} | {row['collect_frames_per_s']:,.0f} | {row['update_frames_per_s']:,.0f} "
            f"| {row['loop_frames_per_s']:,.0f} | {'–' if after is None else f'{after:,.0f}'} | {row['wall_s']:.0f} "
            f"| {'–' if over is None else f'{over:.1f}'} |"
        )
    if "load" in record:
        load = record["load"]
        lines += ["", f"With a busy process beside it ({load['frames']:,} frames, the default run):", ""]
        lines += ["| threads | quiet frames/s | loaded frames/s | loaded / quiet |", "|---|---|---|---|"]
        for row in load["rows"]:
            quiet, loaded = row["quiet"]["loop_frames_per_s"], row["loaded"]["loop_frames_per_s"]
            lines.append(f"| {row['threads']} | {quiet:,.0f} | {loaded:,.0f} | {row['loaded_over_quiet']:.2f} |")
        if "sb3" in load:
            quiet, loaded = load["sb3"]["quiet"]["frames_per_s"], load["sb3"]["loaded"]["frames_per_s"]
            lines.append(f"| SB3 DDPG | {quiet:,.0f} | {loaded:,.0f} | {load['sb3']['loaded_over_quiet']:.2f} |")
    return "\n".join(lines)
