"""Each end on its own (actor=per_end): what each end's network reads, and a run that trains, saves and reloads it."""

import pytest
import torch
from conftest import TINY, compose_config, rejection, reloaded_scores
from tensordict import TensorDict
from torch import nn
from torchrl.modules import MLP, MultiAgentMLP

from waterair.agents.networks import actor_for
from waterair.agents.per_end import ACTIONS, ENDS, per_end_columns
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


def test_a_policy_file_of_an_mlp_per_end_loads_and_acts_as_those_mlps():
    """Policy files from before the ends became TorchRL agents hold an MLP per end (``nets.tx``, ``nets.rx``) and each
    end's columns (``tx_columns``); loaded into today's actor, it acts as those MLPs on their own columns, though the
    two ends read different numbers of columns (the narrower one padded)."""
    actor, config = per_end_actor(frames=2, return_steps=1)
    columns = per_end_columns(config.observation_layout, config.frames, 1)
    assert len(columns["tx"]) != len(columns["rx"])
    torch.manual_seed(7)
    nets = {
        end: MLP(in_features=len(c), out_features=2, num_cells=[16], activation_class=nn.Tanh)
        for end, c in columns.items()
    }
    earlier = {f"module.0.{end}_columns": torch.tensor(cols) for end, cols in columns.items()}
    earlier |= {
        f"module.0.nets.{end}.{key}": value for end, net in nets.items() for key, value in net.state_dict().items()
    }
    actor.load_state_dict(earlier)
    observation = torch.randn(9, config.observation_size)
    with torch.no_grad():
        expected = torch.tanh(
            torch.cat([nets[end](observation[:, torch.tensor(cols)]) for end, cols in columns.items()], dim=-1)
        )
        assert torch.allclose(actor(observation=observation), expected, rtol=0, atol=1e-6)


def test_the_per_end_actor_computes_with_the_weights_a_loss_swaps_in():
    """TorchRL's losses hold an actor's weights apart (a target actor's are a copy) and swap them in for each call;
    the ends' agents must compute with those, not with weights captured at construction (``MultiAgentMLP`` with
    ``use_td_params=False`` would: its output under zero weights stays what it was)."""
    actor, config = per_end_actor(frames=2, return_steps=1)
    observation = torch.randn(4, config.observation_size)
    zeros = TensorDict.from_module(actor, as_module=True).data.clone().zero_()
    with torch.no_grad():
        assert actor(observation=observation).abs().max() > 1e-3
        with zeros.to_module(actor):
            assert actor(observation=observation).abs().max() == 0.0


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
        ends = actor.module.module[0]
        assert isinstance(ends.agents, MultiAgentMLP) and not ends.agents.centralized
        assert (ends.mask.sum(-1) < env_config(cfg).observation_size).all()


@pytest.mark.parametrize(
    "overrides, message",
    [
        (["actor=per_end", "actor.return_steps=-1"], "actor.return_steps = -1 is out of range"),
        (
            ["actor=per_end", "agent=sac", "compile_update=true"],
            "compile_update = true cannot compile actor=per_end's update with agent=sac",
        ),
        (
            ["actor=per_end", "env/observation=intensity"],
            "actor=per_end cannot say which end observes action_history",
        ),
    ],
)
def test_per_end_bad_keys_name_themselves(overrides, message):
    assert message in rejection("train.py", overrides)
