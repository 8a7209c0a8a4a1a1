"""SAC (waterair.training.algorithms.sac) on a toy bandit: its temperature learned toward the target entropy, its
policy's mean the actor a policy file holds, its config checked."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest
import torch
from conftest import compose_config
from tensordict import TensorDict
from torchrl.data import Bounded, Composite, Unbounded
from torchrl.objectives import SACLoss

from waterair.agents.networks import make_actor
from waterair.training.algorithms.sac import SAC
from waterair.training.config import validate

TARGET = (0.3, -0.2)
"""The toy bandit's best action: its reward is −|a − TARGET|², whatever the observation."""


def toy_env(batch: int = 256) -> SimpleNamespace:
    """What SAC reads of an environment: its observation and action specs (3 observed values, 2 actions)."""
    action = Bounded(-1.0, 1.0, shape=(2,))
    return SimpleNamespace(
        observation_spec=Composite(observation=Unbounded(shape=(batch, 3)), shape=(batch,)),
        action_spec=action.expand(batch, 2),
        action_spec_unbatched=action,
    )


def toy_batch(generator: torch.Generator, batch: int = 256) -> TensorDict:
    """Uniform random actions on random observations, each step its own episode (as the replay holds them)."""
    observation = torch.randn(batch, 3, generator=generator)
    action = 2 * torch.rand(batch, 2, generator=generator) - 1
    reward = -(action - torch.tensor(TARGET)).square().sum(-1, keepdim=True)
    flags = torch.zeros(batch, 1, dtype=torch.bool)
    following = {"observation": torch.randn(batch, 3, generator=generator), "reward": reward, "done": flags,
                 "terminated": flags}  # fmt: skip
    return TensorDict({"observation": observation, "action": action, "next": following}, batch_size=[batch])


def trained(sigma: float, updates: int = 400):
    """SAC built as the loop builds it on the toy bandit, its policy starting at scale ``sigma``, after ``updates``
    updates: (entropy at the start, entropy at the end, α at the end, α's start, the target entropy, the pieces)."""
    cfg = compose_config("config", ["agent=sac", f"noise.sigma_init={sigma}", f"noise.sigma_end={sigma}",
                                    "agent.alpha_lr=0.01", "agent.loss.alpha_init=0.1", "actor.hidden=[16,16]",
                                    "critic.hidden=[16,16]", "actor.lr=0.01", "critic.lr=0.01",
                                    "compile_update=false"])  # fmt: skip
    validate(cfg)
    torch.manual_seed(0)
    env, algorithm = toy_env(), SAC(cfg)
    actor = make_actor(3, 2, cfg.actor.hidden, cfg.actor.activation, cfg.actor.zero_output)
    critic = algorithm.make_critic(env, "cpu")
    exploration, _ = algorithm.make_exploration(actor, env, "cpu")
    loss, target_update = algorithm.make_loss(actor, exploration, critic, env)
    update = algorithm.make_update(loss, target_update, *algorithm.make_optimisers(loss))
    generator = torch.Generator().manual_seed(1)
    out = [update(toy_batch(generator), count) for count in range(updates)]
    entropy = SAC.logged.index("train/entropy") + 2
    alpha = SAC.logged.index("train/alpha") + 2
    return (
        out[0][entropy].item(),
        out[-1][entropy].item(),
        out[-1][alpha].item(),
        loss.target_entropy.item(),
        (actor, exploration),
    )


@pytest.mark.parametrize("sigma", [0.5, 0.003])
def test_the_temperature_moves_the_policy_s_entropy_toward_its_target(sigma):
    """Far above the target entropy (σ 0.5) the temperature falls and the reward narrows the policy; far below it
    (σ 0.003) the temperature rises and widens it. Either way the entropy ends nearer the target than it started."""
    start, end, alpha, target, _ = trained(sigma)
    assert target == -2.0  # auto: −1 per action component
    assert (start > target) == (sigma == 0.5), (start, target)
    if start > target:
        assert alpha < 0.1
    else:
        assert alpha > 0.1
    assert abs(end - target) < 0.5 * abs(start - target), (start, end, target)


def test_the_policy_s_mean_is_the_actor_and_the_actor_learns_the_bandit_s_best_action():
    *_, (actor, exploration) = trained(0.1)
    observation = TensorDict({"observation": torch.randn(64, 3, generator=torch.Generator().manual_seed(2))}, [64])
    mean = actor(observation.clone())["action"]
    with torch.no_grad():
        distribution = exploration.get_dist(observation.clone())
    torch.testing.assert_close(distribution.deterministic_sample, mean)
    assert (mean - torch.tensor(TARGET)).abs().mean() < 0.05  # the zero-started actor's is 0.25


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("agent.policy_weights=average", r"agent=sac saves the actor it learns"),
        ("agent.loss.alpha_init=0", r"agent\.loss\.alpha_init"),
        ("agent.alpha_lr=-1", r"agent\.alpha_lr"),
        ("noise=ou", r"agent=sac learns its action noise"),
        ("agent.loss.target_entropy=1000", r"agent\.loss\.target_entropy"),
    ],
)
def test_a_bad_sac_key_names_itself(override, message):
    with pytest.raises(ValueError, match=message):
        validate(compose_config("config", ["agent=sac", override]))


def test_the_auto_target_entropy_is_minus_one_per_action_component():
    assert math.isclose(trained(0.1, updates=1)[3], -2.0)


def built(gamma: float):
    """SAC's loss as the loop builds it on the toy bandit at discount ``gamma``, its networks seeded alike."""
    cfg = compose_config("config", ["agent=sac", f"agent.gamma={gamma}", "actor.hidden=[16,16]",
                                    "critic.hidden=[16,16]", "compile_update=false"])  # fmt: skip
    validate(cfg)
    torch.manual_seed(0)
    env, algorithm = toy_env(), SAC(cfg)
    actor = make_actor(3, 2, cfg.actor.hidden, cfg.actor.activation, cfg.actor.zero_output)
    exploration, _ = algorithm.make_exploration(actor, env, "cpu")
    return algorithm.make_loss(actor, exploration, algorithm.make_critic(env, "cpu"), env)[0]


def test_at_discount_zero_the_critics_target_is_the_reward_without_the_next_states_work():
    """What TorchRL's SACLoss computes at discount 0, r + 0 · V(s') with the next state's actions and target
    critics, is the reward, which the loss now takes as it is: the same target and critic loss to the bit; at
    another discount the loss computes its target as TorchRL does."""
    loss = built(0.0)
    batch = toy_batch(torch.Generator().manual_seed(2))
    assert "_compute_target_v2" in vars(loss)  # this loss's own target
    theirs = SACLoss._compute_target_v2(loss, batch)
    assert torch.equal(loss._compute_target_v2(batch), theirs)
    assert torch.equal(theirs, batch["next", "reward"].squeeze(-1))
    ours_loss = loss.qvalue_v2_loss(batch)[0]
    del loss._compute_target_v2
    assert torch.equal(ours_loss, loss.qvalue_v2_loss(batch)[0])
    assert "_compute_target_v2" not in vars(built(0.9))
