"""The update's own pieces against TorchRL's: the soft target update as one foreach lerp, DDPG's target at discount
0 without the target networks, Adam fused only for an eager update, a batch's samples (a PPO pass's) in one draw."""

from types import SimpleNamespace

import pytest
import torch
from conftest import ONE_PATH, TINY, compose_config
from tensordict import TensorDict
from torchrl.objectives import SoftUpdate
from torchrl.objectives.value import TD0Estimator

from waterair.training.algorithms.ddpg import DDPG, RewardTarget, direct_losses
from waterair.training.algorithms.off_policy import PolyakUpdate
from waterair.training.algorithms.ppo import PPO
from waterair.training.builders import make_actor, make_buffer, make_env


def ddpg_pieces(*overrides, seed=0):
    """A DDPG config on the paper's one path, its env, and its loss and target update built as the loop builds them
    (the networks drawn from ``seed``)."""
    cfg = compose_config("config", [*TINY, "agent=ddpg", *ONE_PATH, "env.num_envs=4", *overrides])
    env = make_env(cfg)
    torch.manual_seed(seed)
    algorithm = DDPG(cfg)
    actor, critic = make_actor(cfg, env, "cpu"), algorithm.make_critic(env, "cpu")
    loss, target_update = algorithm.make_loss(actor, None, critic, env)
    return cfg, env, algorithm, loss, target_update


def replay(env, algorithm, frames: int = 64):
    """A replay buffer holding ``frames`` of random transitions."""
    buffer = make_buffer(algorithm.cfg, None, "cpu", on_policy=False)
    buffer.extend(env.rollout(frames // env.batch_size[0]).reshape(-1))
    return buffer


def nudge(loss, scale: float = 0.1) -> None:
    """Move the online parameters (as an optimiser step would) so that a soft update has something to do."""
    with torch.no_grad():
        for parameter in loss.parameters():
            parameter.add_(scale * torch.randn_like(parameter))


def targets(loss) -> dict:
    return {key: value.clone() for key, value in loss.state_dict().items() if key.startswith("target_")}


def test_the_foreach_soft_update_moves_every_target_as_torchrl_s_does_bit_for_bit():
    cfg, _, _, ours, polyak = ddpg_pieces()
    _, _, _, theirs, _ = ddpg_pieces()
    assert isinstance(polyak, PolyakUpdate)
    reference = SoftUpdate(theirs, tau=cfg.agent.tau)
    for step in range(3):
        torch.manual_seed(step)
        nudge(ours)
        torch.manual_seed(step)
        nudge(theirs)
        before = targets(ours)
        polyak.step()
        reference.step()
        after, expected = targets(ours), targets(theirs)
        assert len(after) == 12 and set(after) == set(expected)  # the actor's and the critic's 3 layers, each W and b
        for key, value in after.items():
            assert torch.equal(value, expected[key]), key
            assert not torch.equal(value, before[key]), f"{key} did not move"


def test_the_soft_update_still_moves_the_loss_s_targets_after_a_checkpoint_is_loaded_into_it():
    _, _, _, loss, polyak = ddpg_pieces()
    state = {key: value + 1.0 for key, value in loss.state_dict().items()}
    loss.load_state_dict(state)  # as a resumed run does
    nudge(loss)
    online = {k: v.clone() for k, v in loss.state_dict().items() if k.startswith("actor_network_params")}
    polyak.step()
    for key, value in online.items():
        target = loss.state_dict()[f"target_{key}"]
        loaded = state[f"target_{key}"]
        torch.testing.assert_close(target, loaded + (1 - polyak.eps) * (value - loaded), rtol=1e-6, atol=1e-7)
        assert not torch.equal(target, loaded)


def test_at_discount_0_ddpg_s_target_is_the_reward_without_the_target_networks():
    _, env, algorithm, loss, _ = ddpg_pieces(seed=1)
    assert isinstance(loss.value_estimator, RewardTarget)
    _, _, _, torchrl_loss, _ = ddpg_pieces(seed=1)
    torchrl_loss.make_value_estimator(gamma=0.0)  # TorchRL's own TD(0), which evaluates the target networks
    assert type(torchrl_loss.value_estimator) is TD0Estimator
    for module in (loss, torchrl_loss):  # the same draws: both losses hold the same parameters
        torch.manual_seed(2)
        nudge(module)
    batch = replay(env, algorithm).sample(16)
    ours, theirs = loss(batch.clone()), torchrl_loss(batch.clone())
    for key in ("loss_value", "loss_actor", "target_value"):
        assert torch.equal(ours[key], theirs[key]), key
    torch.testing.assert_close(ours["target_value"], batch["next", "reward"].squeeze(-1), rtol=0, atol=0)
    ours["loss_value"].backward()
    theirs["loss_value"].backward()
    for (key, mine), other in zip(loss.named_parameters(), torchrl_loss.parameters(), strict=True):
        assert (mine.grad is None) == (other.grad is None), key
        assert mine.grad is None or torch.equal(mine.grad, other.grad), key
    # targets made NaN: TorchRL's 0 · NaN poisons its loss; ours never reads them
    with torch.no_grad():
        for params in (loss.target_value_network_params, torchrl_loss.target_value_network_params):
            params.apply_(lambda tensor: tensor.fill_(float("nan")))
    assert torch.isfinite(loss(batch.clone())["loss_value"])
    assert torch.isnan(torchrl_loss(batch.clone())["loss_value"])


@pytest.mark.parametrize("loss_function", ["l2", "smooth_l1"])
def test_the_direct_eager_losses_and_their_gradients_are_torchrl_s(loss_function):
    """The eager update's losses at discount 0, on the networks' own modules, against TorchRL's ``DDPGLoss`` on the
    same batch: the same two values, and after one backward of their sum the same gradient for every parameter
    (the critic's from the value loss alone: the actor's loss leaves it out as TorchRL's detached copies do)."""
    _, env, algorithm, loss, _ = ddpg_pieces(f"agent.loss.loss_function={loss_function}", seed=3)
    direct = direct_losses(loss)
    assert direct is not None and algorithm.loss_terms(loss).__qualname__ == direct.__qualname__
    torch.manual_seed(4)
    nudge(loss)
    batch = replay(env, algorithm).sample(16)
    actor_loss, value_loss = direct(batch.clone())
    theirs = loss(batch.clone())
    assert torch.equal(actor_loss, theirs["loss_actor"]) and torch.equal(value_loss, theirs["loss_value"])

    def gradients(total) -> dict:
        loss.zero_grad(set_to_none=True)
        total.backward()
        return {key: p.grad.clone() for key, p in loss.named_parameters() if p.grad is not None}

    mine, expected = gradients(actor_loss + value_loss), gradients(theirs["loss_actor"] + theirs["loss_value"])
    assert set(mine) == set(expected) and len(mine) == 12  # the online actor's and critic's, 3 layers each
    for key, grad in mine.items():
        torch.testing.assert_close(grad, expected[key], rtol=1e-6, atol=1e-8, msg=key)
    assert all(p.requires_grad for p in loss.value_network_params.values(True, True))  # given back


@pytest.mark.parametrize("override", ["agent.gamma=0.2", "compile_update=true"])
def test_the_update_keeps_torchrl_s_loss_where_the_direct_one_would_differ_or_compiles(override):
    _, _, algorithm, loss, _ = ddpg_pieces(override)
    terms = algorithm.loss_terms(loss)
    assert "direct_losses" not in terms.__qualname__
    if override.startswith("agent.gamma"):
        assert direct_losses(loss) is None  # its target needs the target networks


def test_a_nonzero_discount_keeps_torchrl_s_estimator():
    _, _, _, loss, _ = ddpg_pieces("agent.gamma=0.2")
    assert type(loss.value_estimator) is TD0Estimator and float(loss.value_estimator.gamma) == pytest.approx(0.2)


@pytest.mark.parametrize("compiled", [False, True])
def test_adam_is_fused_only_for_an_eager_update(compiled):
    _, _, algorithm, loss, _ = ddpg_pieces(f"compile_update={str(compiled).lower()}")
    for optimiser in algorithm.make_optimisers(loss):
        assert bool(optimiser.param_groups[0]["fused"]) is not compiled


def test_a_batch_s_updates_each_get_their_own_sample_of_the_replay():
    cfg, env, algorithm, loss, _ = ddpg_pieces("collector.frames_per_batch=64", "collector.init_random_frames=0")
    buffer = replay(env, algorithm, frames=128)
    seen: list[TensorDict] = []
    noise = SimpleNamespace(step=lambda steps: None)
    learn = algorithm.make_learn(loss, lambda batch, count: seen.append(batch) or torch.zeros(2), buffer, noise)
    progress = SimpleNamespace(frames=64, updates=0)
    learn(env.rollout(16), progress)
    per_batch = round(64 * cfg.collector.updates_per_frame)
    assert len(seen) == per_batch == progress.updates == 16
    assert all(batch.batch_size == torch.Size([cfg.buffer.batch_size]) for batch in seen)
    stored = buffer[: len(buffer)]["observation"]
    for batch in seen:  # every row is one of the replay's
        assert (batch["observation"][:, None] == stored[None]).all(-1).any(-1).all()
    assert len({tuple(batch["index"].tolist()) for batch in seen}) == per_batch  # each its own draw


def test_each_ppo_pass_is_one_permutation_of_the_batch_in_whole_minibatches():
    # 400 frames in minibatches of 64: 6 a pass, the 16 rows left over wait for the next pass's shuffle
    overrides = [*TINY, *ONE_PATH, "agent=ppo", "env.num_envs=8", "collector.init_random_frames=0"]
    cfg = compose_config("config", [*overrides, "agent.target_kl=null"])
    env = make_env(cfg)
    algorithm = PPO(cfg)
    actor, critic = make_actor(cfg, env, "cpu"), algorithm.make_critic(env, "cpu")
    exploration, noise = algorithm.make_exploration(actor, env, "cpu")
    loss, _ = algorithm.make_loss(actor, exploration, critic, env)
    buffer = make_buffer(cfg, None, "cpu", on_policy=True)
    seen: list[TensorDict] = []
    learn = algorithm.make_learn(loss, lambda batch, count: seen.append(batch) or torch.zeros(3), buffer, noise)
    with torch.no_grad():
        batch = env.rollout(50, exploration)  # [8, 50]: one collected batch
    learn(batch, SimpleNamespace(frames=400, updates=0))
    per_pass = 400 // 64
    assert len(seen) == per_pass * 10 and all(minibatch.batch_size == torch.Size([64]) for minibatch in seen)
    for first in range(0, len(seen), per_pass):
        rows = torch.cat([minibatch["index"] for minibatch in seen[first : first + per_pass]])
        assert rows.unique().numel() == per_pass * 64  # no row twice within a pass
    assert not torch.equal(seen[0]["index"], seen[per_pass]["index"])  # each pass its own shuffle
