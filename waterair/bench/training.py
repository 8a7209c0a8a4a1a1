"""Training benchmark: ``python -m waterair.bench training`` (see :mod:`waterair.bench`).

* **update**: one DDPG update of the default configuration (batch 64, 256 × 256 MLPs, Adam, soft
  target update) in our pipeline (TorchRL ``DDPGLoss`` on a ``TensorDictReplayBuffer`` sample),
  eager and compiled, against the same networks and math written as bare PyTorch (tensors indexed
  from preallocated storage), with the eager update's breakdown (sample, loss, backward and
  optimiser steps, target update).
* **train**: frames per second of ``train.py``'s loop on the default configuration (PPO) and with
  ``agent=ddpg`` (collector, replay, updates at 0.25 per frame), from its own per-batch timings
  after the compile warm-up, and the wall time of the whole run;
* **sb3**: Stable-Baselines3 DDPG on our Gymnasium view of the same environment, at DDPG's updates
  per frame, networks, batch and learning rates, if ``stable_baselines3`` can be imported; it is
  compared with our DDPG.
"""

from __future__ import annotations

import copy
import csv
import statistics
import tempfile
import time
from pathlib import Path

import torch
from hydra import compose, initialize_config_dir
from torch import nn

from waterair.bench.sb3 import sb3_ddpg
from waterair.training.builders import (
    TRANSITION_KEYS,
    make_actor,
    make_buffer,
    make_critic,
    make_env,
    make_loss,
    make_optimisers,
    make_update,
)
from waterair.training.config import CONF_DIR

BUFFER_FILL = 20_000


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
    actor, critic = make_actor(cfg, env, "cpu"), make_critic(cfg, env, "cpu")
    loss, target_update = make_loss(cfg, actor, None, critic, env)  # DDPG learns the actor itself
    optim_actor, optim_critic = make_optimisers(cfg, loss)
    with tempfile.TemporaryDirectory() as scratch:
        buffer = make_buffer(cfg, Path(scratch), "cpu")
        _fill(buffer, env, BUFFER_FILL)
        record: dict = {}
        for compiled in (False, True):
            cfg.compile_update = compiled
            update = make_update(cfg, loss, target_update, optim_actor, optim_critic)
            for i in range(30):  # warm-up (and the compile)
                update(buffer.sample(), i)
            record["ours_compiled_ms" if compiled else "ours_eager_ms"] = _median_ms(
                lambda update=update: update(buffer.sample(), 0), updates
            )
        record["breakdown_eager_ms"] = _breakdown(buffer, loss, target_update, optim_actor, optim_critic, updates)
        record["bare_ms"] = bench_bare(cfg, env.base_env.observation_size, buffer, updates)
    record["ratio_eager"] = record["ours_eager_ms"] / record["bare_ms"]
    record["ratio_compiled"] = record["ours_compiled_ms"] / record["bare_ms"]
    return record


def _breakdown(buffer, loss, target_update, optim_actor, optim_critic, count: int) -> dict:
    parts = {"sample": [], "loss": [], "backward_and_steps": [], "target_update": []}
    for _ in range(count):
        t0 = time.perf_counter()
        batch = buffer.sample()
        t1 = time.perf_counter()
        losses = loss(batch)
        t2 = time.perf_counter()
        optim_actor.zero_grad(set_to_none=True)
        optim_critic.zero_grad(set_to_none=True)
        (losses["loss_value"] + losses["loss_actor"]).backward()
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


def bench_train(frames: int, overrides: list[str]) -> dict:
    """``train()`` on the default configuration for ``frames`` frames: steady frames/s and wall time."""
    from waterair.training.loop import train

    with tempfile.TemporaryDirectory() as run_dir:
        cfg = compose_training(
            [
                f"total_frames={frames}",
                f"checkpoint.every_frames={frames}",
                "eval.realisations=2",
                "eval.steps=10",
                "logger.progress_bar=false",
                *overrides,
            ]
        )
        start = time.perf_counter()
        train(cfg, Path(run_dir), progress=lambda line: None)
        wall = time.perf_counter() - start
        with open(Path(run_dir) / "metrics.csv", newline="") as handle:
            rows = list(csv.DictReader(handle))
    rates = [float(row["time/frames_per_s"]) for row in rows]
    steady = rates[len(rates) // 4 :]  # past the compile warm-up
    return {"frames": frames, "overrides": overrides, "frames_per_s": statistics.median(steady), "wall_s": wall}


def bench_sb3(frames: int) -> dict | None:
    """Stable-Baselines3 DDPG (:func:`waterair.bench.sb3.sb3_ddpg`) on one link of the environment
    ``agent=ddpg`` trains on, timed over ``frames`` frames after a warm-up past its first updates."""
    model = sb3_ddpg(compose_training(["agent=ddpg"]))
    if model is None:
        return None
    model.learn(3000)
    start = time.perf_counter()
    model.learn(frames, reset_num_timesteps=False)
    return {"frames": frames, "frames_per_s": frames / (time.perf_counter() - start)}


COMPILED = ["env.compile_kernel=true", "compile_update=true"]
"""The compiled rows compile whatever their frames (``auto`` would not at these budgets)."""


def bench_training(updates: int, frames: int, sb3_frames: int) -> dict:
    record = {"benchmark": "training", "update": bench_update(updates)}
    record["train"] = bench_train(frames, COMPILED)
    record["train_eager"] = bench_train(frames, ["env.compile_kernel=false", "compile_update=false"])
    record["train_ddpg"] = bench_train(frames, ["agent=ddpg", *COMPILED])
    record["sb3"] = bench_sb3(sb3_frames)
    if record["sb3"] is not None:
        record["train_over_sb3"] = record["train_ddpg"]["frames_per_s"] / record["sb3"]["frames_per_s"]
    return record


def training_table(record: dict) -> str:
    u = record["update"]
    lines = [
        "| quantity | value |",
        "|---|---|",
        f"| DDPG update, ours eager | {u['ours_eager_ms']:.2f} ms |",
        f"| DDPG update, ours compiled | {u['ours_compiled_ms']:.2f} ms |",
        f"| DDPG update, bare PyTorch | {u['bare_ms']:.2f} ms |",
        f"| ratio ours / bare (eager, compiled) | {u['ratio_eager']:.2f}, {u['ratio_compiled']:.2f} |",
        "| eager breakdown (ms) | " + ", ".join(f"{k} {v:.2f}" for k, v in u["breakdown_eager_ms"].items()) + " |",
        f"| train.py frames/s (defaults: PPO) | {record['train']['frames_per_s']:,.0f} |",
        f"| train.py frames/s (PPO, eager env and update) | {record['train_eager']['frames_per_s']:,.0f} |",
        f"| train.py frames/s (agent=ddpg) | {record['train_ddpg']['frames_per_s']:,.0f} |",
    ]
    if record["sb3"] is not None:
        lines.append(f"| SB3 DDPG frames/s | {record['sb3']['frames_per_s']:,.0f} |")
        lines.append(f"| train.py DDPG / SB3 DDPG | {record['train_over_sb3']:.1f} |")
    else:
        lines.append("| SB3 DDPG | not installed |")
    return "\n".join(lines)
