"""Recurrent actors (actor=gru|lstm): the state carried and reset, collected and replayed, saved and evaluated."""

import copy

import pytest
import torch
from conftest import TINY, compose_config, rejection, reloaded_scores
from tensordict import TensorDict
from torchrl.collectors import Collector
from torchrl.modules import set_recurrent_mode

from waterair.agents.networks import actor_for
from waterair.agents.recurrent import StepMemory, is_recurrent, state_keys
from waterair.training import train
from waterair.training.algorithms import create
from waterair.training.algorithms.ppo import PPO
from waterair.training.builders import make_actor, make_buffer, make_env
from waterair.training.export import export_policy

SIZES = {"observation": 5, "state": 6, "hidden": [7]}
STARTS = (0, 4)
"""The steps of the known sequence at which an episode starts (``is_init``)."""


def small_actor(cell: str):
    torch.manual_seed(3)
    network = {"name": cell, "state_size": SIZES["state"], "layers": 1, "hidden": SIZES["hidden"],
               "activation": "tanh", "zero_output": False}  # fmt: skip
    return actor_for(network, SIZES["observation"], 4)


def reference_actions(actor, observations: torch.Tensor, starts) -> torch.Tensor:
    """The actions of ``actor`` on ``observations`` [T, n] in float64, by the cell's equations written out (PyTorch's
    GRU and LSTM documentation), the state zeroed at ``starts``."""
    memory, head = actor[0], copy.deepcopy(actor[1].module).double()
    cell = memory.gru if hasattr(memory, "gru") else memory.lstm
    w_ih, w_hh = cell.weight_ih_l0.double(), cell.weight_hh_l0.double()
    b_ih, b_hh = cell.bias_ih_l0.double(), cell.bias_hh_l0.double()
    h = c = torch.zeros(SIZES["state"], dtype=torch.float64)
    actions = []
    for t, x in enumerate(observations.double()):
        if t in starts:
            h = c = torch.zeros_like(h)
        gi, gh = w_ih @ x + b_ih, w_hh @ h + b_hh
        if hasattr(memory, "gru"):
            (ri, zi, ni), (rh, zh, nh) = gi.chunk(3), gh.chunk(3)
            r, z = torch.sigmoid(ri + rh), torch.sigmoid(zi + zh)
            n = torch.tanh(ni + r * nh)
            h = (1 - z) * n + z * h
        else:
            i, f, g, o = (gi + gh).chunk(4)
            c = torch.sigmoid(f) * c + torch.sigmoid(i) * torch.tanh(g)
            h = torch.sigmoid(o) * torch.tanh(c)
        actions.append(head(h))
    return torch.stack(actions)


@pytest.mark.parametrize("cell", ["gru", "lstm"])
def test_a_recurrent_actor_carries_its_state_from_step_to_step_and_zeros_it_where_an_episode_starts(cell):
    """A known sequence, stepped as a collector steps it (the state passed on through ``("next", ...)``): the actions
    are the cell's equations' in float64 with the state zeroed at each ``is_init``; run over the whole sequence at once
    (PPO's recurrent mode) they are the same; and the state matters: not zeroed, the second episode acts otherwise."""
    actor = small_actor(cell)
    torch.manual_seed(4)
    observations = torch.randn(8, SIZES["observation"])
    is_init = torch.tensor([t in STARTS for t in range(8)]).unsqueeze(-1)
    with torch.no_grad():
        stepped, state = [], {}
        for t in range(8):
            step = {"observation": observations[t : t + 1], "is_init": is_init[t : t + 1], **state}
            out = actor(TensorDict(step, [1]))
            stepped.append(out["action"][0])
            state = {key: out["next", key] for key in state_keys(cell)}
        stepped = torch.stack(stepped)
        with set_recurrent_mode(True):
            sequence = TensorDict({"observation": observations[None], "is_init": is_init[None]}, [1, 8])
            whole = actor(sequence)["action"][0]
        carried = reference_actions(actor, observations, STARTS[:1])
    expected = reference_actions(actor, observations, STARTS)
    torch.testing.assert_close(stepped.double(), expected, rtol=1e-5, atol=1e-6)
    torch.testing.assert_close(whole.double(), expected, rtol=1e-5, atol=1e-6)
    assert (carried[4:] - expected[4:]).abs().max() > 1e-3  # a reset changes what follows
    torch.testing.assert_close(carried[:4], expected[:4])


def recurrent_cfg(*overrides):
    return compose_config("config", [*TINY, "total_frames=800", "threads=1", "actor=gru", "actor.state_size=8",
                                     "actor.hidden=[16]", *overrides])  # fmt: skip


def test_the_environment_declares_the_state_and_zeros_it_at_each_reset():
    """With a recurrent actor the training env carries its state: at every step it is what the step before passed
    on, except at an episode's first step, where it is zero (episodes of 4 steps over 10)."""
    cfg = recurrent_cfg("env.max_steps=4", "eval.steps=4")
    env = make_env(cfg)
    actor = make_actor(cfg, env, "cpu")
    with torch.no_grad():
        rollout = env.rollout(10, actor, break_when_any_done=False)
    state, passed_on, starts = rollout["recurrent_state"], rollout["next", "recurrent_state"], rollout["is_init"]
    assert starts[:, ::4].all() and starts.sum() == 3 * env.batch_size[0]
    assert (state[starts.squeeze(-1)] == 0).all()
    assert (passed_on.abs().amax(dim=(-1, -2)) > 0).all()
    later = ~starts[:, 1:].squeeze(-1)
    assert torch.equal(state[:, 1:][later], passed_on[:, :-1][later])


def collected_batch(cfg):
    """One batch of the algorithm's exploration on the training env, and the pieces that collected it."""
    env = make_env(cfg)
    algorithm = create(cfg)
    actor, critic = make_actor(cfg, env, "cpu"), algorithm.make_critic(env, "cpu")
    exploration, noise = algorithm.make_exploration(actor, env, "cpu")
    loss, _ = algorithm.make_loss(actor, exploration, critic, env)
    collector = Collector(env, exploration, frames_per_batch=cfg.collector.frames_per_batch, total_frames=-1,
                          auto_register_policy_transforms=False)  # fmt: skip
    batch = next(iter(collector))
    collector.shutdown()
    return batch, algorithm, actor, exploration, loss


def test_ppo_learns_from_whole_links_whose_log_probabilities_are_those_collected():
    """PPO's minibatches of a recurrent actor are whole links, each once per pass, and in recurrent mode the policy
    gives every collected action the log-probability it was collected with: the ratio starts at 1, as for an MLP.
    (Replaying the flattened steps, each from a zero state, would not.)"""
    # 50-step rows, episodes start mid-row; the output layer drawn at random, so that the actions depend on the state
    cfg = recurrent_cfg("env.max_steps=30", "eval.steps=20", "actor.zero_output=false")
    batch, _, _, exploration, _ = collected_batch(cfg)
    assert batch.shape == (8, 50) and batch["is_init"][:, 1:].any()
    minibatches = PPO.minibatches(batch, 4)
    assert [m.shape for m in minibatches] == [(2, 50)] * 4
    assert sorted(torch.cat([m["observation"][:, 0, 0] for m in minibatches]).tolist()) == sorted(
        batch["observation"][:, 0, 0].tolist()
    )
    with torch.no_grad(), set_recurrent_mode(True):
        for minibatch in minibatches:
            log_prob = exploration.get_dist(minibatch.clone()).log_prob(minibatch["action"])
            torch.testing.assert_close(log_prob, minibatch["action_log_prob"], rtol=1e-4, atol=1e-4)
        flat = batch.reshape(-1, 1).exclude("recurrent_state")  # each step from a zero state
        forgetting = exploration.get_dist(flat).log_prob(flat["action"]).reshape(8, 50)
    assert (forgetting - batch["action_log_prob"]).abs().max() > 1e-2


@pytest.mark.parametrize("agent", ["ddpg", "sac"])
def test_the_replay_holds_each_transition_with_the_state_it_was_collected_from(agent, tmp_path):
    """An off-policy agent's replay stores a recurrent actor's state at both steps of every transition: the next
    step's is the actor's memory run on the observation from this step's (zero at an episode's start)."""
    cfg = recurrent_cfg(f"agent={agent}", "actor=lstm", "env.max_steps=30", "eval.steps=20")
    batch, algorithm, actor, exploration, loss = collected_batch(cfg)
    buffer = make_buffer(cfg, tmp_path, "cpu", on_policy=False)
    noise = algorithm.make_exploration(actor, make_env(cfg), "cpu")[1]
    learn = algorithm.make_learn(loss, lambda sample, count: torch.zeros(2), buffer, noise)
    progress = type("Progress", (), {"frames": 400, "updates": 0})()
    learn(batch, progress)
    stored = buffer.storage.get(range(len(buffer)))
    keys = state_keys("lstm")
    assert len(stored) == 400 and {*keys, "is_init"} <= set(stored.keys())
    with torch.no_grad():
        replayed = actor[0](stored.select("observation", "is_init", *keys).clone())
    for key in keys:
        torch.testing.assert_close(replayed["next", key], stored["next", key])
        assert (stored[key][stored["is_init"].squeeze(-1)] == 0).all()


@pytest.mark.slow
def test_an_exported_recurrent_policy_scores_what_it_scored_in_training(tmp_path):
    """A short PPO run of a GRU actor: its checkpoint and its exported policy file, evaluated afresh on the closing
    evaluation's seas (each rollout's state from zero), score what the run scored."""
    cfg = recurrent_cfg()
    metrics = train(cfg, tmp_path / "run", progress=lambda line: None)
    exported = export_policy(tmp_path / "run", tmp_path / "policy")
    for path in (tmp_path / "run" / "checkpoints" / "last.pt", exported):
        assert is_recurrent(reloaded_scores(cfg, metrics, path))


@pytest.mark.parametrize(
    "overrides, message",
    [
        (["actor=gru", "actor.state_size=0"], "actor.state_size = 0 is out of range"),
        (["actor=lstm", "actor.layers=9"], "actor.layers = 9 is out of range"),
        (["actor.name=rnn"], "actor.name = 'rnn' is not allowed; choose one of mlp, gru, lstm"),
    ],
)
def test_a_recurrent_actors_bad_keys_name_themselves(overrides, message):
    assert message in rejection("train.py", overrides)


def test_an_evaluations_recurrent_policy_acts_on_a_link_as_it_would_beside_any_other_links():
    """StepMemory, as evaluate.py steps a recurrent policy: its state carried between calls, zero at the first, each
    block of 64 rows with its own rows' state; six links score the same to the bit alone and as the last six of 70
    (the second block; the blocks keep a matrix product's row count, and so its rounding, as RowBlocks does)."""
    torch.manual_seed(3)
    network = {"name": "lstm", "state_size": 64, "layers": 1, "hidden": [256, 256], "activation": "relu"}
    actor = actor_for(network, 34, 4)  # the defaults' sizes: smaller ones take the same kernel at any row count
    torch.manual_seed(7)
    observations = torch.randn(5, 70, 34)
    alone, among = StepMemory(actor), StepMemory(actor)
    with torch.no_grad():
        for t in range(5):
            few = alone(TensorDict({"observation": observations[t, 64:]}, [6]))["action"]
            many = among(TensorDict({"observation": observations[t]}, [70]))["action"]
            assert torch.equal(few, many[64:])
    assert few.abs().max() > 0.01  # the output layer drawn at random: actions to compare
