"""Each end on its own (actor=per_end): what each end's network reads, and a run that trains, saves and reloads it."""

import pytest
import torch
from conftest import TINY, compose_config, rejection, reloaded_scores

from waterair.agents.networks import actor_for
from waterair.agents.per_end import ACTIONS, ENDS
from waterair.envs.config import EnvConfig
from waterair.training import train
from waterair.training.builders import env_config
from waterair.training.export import export_policy

BEACON = ("spot", "spot_valid", "beacon", "beacon_valid", "geometry", "divergence")


def per_end_actor(frames: int, return_steps: int):
    config = EnvConfig(num_envs=1, observation_extras=BEACON, frames=frames, compile_kernel=False)
    network = {"name": "per_end", "return_steps": return_steps, "hidden": [16], "activation": "tanh",
               "zero_output": False}  # fmt: skip
    torch.manual_seed(5)
    return actor_for(network, config.observation_size, 4, config), config


def moved(config: EnvConfig, end: str, frame: int) -> torch.Tensor:
    """A unit step in every column of ``end``'s own readings in one frame (newest first)."""
    step = torch.zeros(config.observation_size)
    for name in ENDS[end]:
        if name in config.observation_layout:
            part = config.observation_layout[name]
            step[frame * config.frame_size + part.start : frame * config.frame_size + part.stop] = 1.0
    return step


@pytest.mark.parametrize("return_steps", [0, 1, 2, 3])
def test_an_end_reads_the_other_ends_readings_only_through_the_return_channel(return_steps):
    """Three frames (newest first): a change of the drone's readings in a frame newer than the return channel's
    latency leaves the transmitter's actions as they were, and one in an older frame reaches them; likewise the other
    way. An end's own readings reach its actions in every frame. With the latency at 3 (≥ the frames) nothing of
    the other end arrives."""
    actor, config = per_end_actor(frames=3, return_steps=return_steps)
    torch.manual_seed(6)
    observation = torch.randn(1, config.observation_size)

    def actions(x: torch.Tensor) -> torch.Tensor:
        with torch.no_grad():
            return actor(observation=x)[0]

    base = actions(observation)
    for end, other in (("tx", "rx"), ("rx", "tx")):
        for frame in range(3):
            mine = actions(observation + moved(config, end, frame)) - base
            assert mine[ACTIONS[end]].abs().max() > 1e-4
            theirs = actions(observation + moved(config, other, frame)) - base
            arrived = theirs[ACTIONS[end]].abs().max() > 1e-4
            assert arrived == (frame >= return_steps), (end, frame)


def test_per_end_trains_saves_and_reloads_to_what_it_scored(tmp_path):
    """A short PPO run of per-end actors (the critic reads everything): its checkpoint and its exported policy, each
    reloaded with the training config's layout (its ``env.compile_kernel`` auto, as train.py saves it), score what
    the run scored."""
    cfg = compose_config("config", [*TINY, "total_frames=800", "threads=1", "actor=per_end", "actor.hidden=[16]"])
    metrics = train(cfg, tmp_path / "run", progress=lambda line: None)
    saved = tmp_path / "run" / "config.yaml"  # as train.py saves it by default: the env's compiles left to decide
    assert "compile_kernel: false" in saved.read_text()
    saved.write_text(saved.read_text().replace("compile_kernel: false", "compile_kernel: auto"))
    exported = export_policy(tmp_path / "run", tmp_path / "policy")
    for path in (tmp_path / "run" / "checkpoints" / "last.pt", exported):
        actor = reloaded_scores(cfg, metrics, path)
        assert actor.module.module[0].nets["tx"][0].in_features < env_config(cfg).observation_size


@pytest.mark.parametrize(
    "overrides, message",
    [
        (["actor=per_end", "actor.return_steps=-1"], "actor.return_steps = -1 is out of range"),
        (
            ["actor=per_end", "env/observation=intensity"],
            "actor=per_end cannot say which end observes action_history",
        ),
    ],
)
def test_per_end_bad_keys_name_themselves(overrides, message):
    assert message in rejection("train.py", overrides)
