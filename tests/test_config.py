"""Every option of every config group composes and validates; option files carry only keys they read."""

import pytest
from conftest import ROOT, compose_config
from omegaconf import OmegaConf

from waterair.training.config import validate

GROUPS = {
    group.name: sorted(p.stem for p in group.glob("*.yaml"))
    for group in sorted((ROOT / "conf").iterdir())
    if group.is_dir() and group.name not in ("env", "hydra", "experiment")
}
OPTIONS = [(group, option) for group, options in GROUPS.items() for option in options]
OPTIONS += [
    (f"env/{group}", p.stem)
    for group in ("sea", "sensor", "observation")
    for p in sorted((ROOT / "conf" / "env" / group).glob("*.yaml"))
]
LAUNCHERS = ["basic", "joblib", "submitit_local", "submitit_slurm"]
SELECTED = {"actor", "critic", "agent", "buffer", "noise", "reward", "logger"}
"""Groups whose options say which one they are, always under the key ``name``."""
NAMED_AS = {("reward", "pointing"): "le"}
"""Options that are another option's function with other values (the LE reward with its pointing term)."""


def test_every_group_is_covered():
    assert set(GROUPS) == {"actor", "agent", "buffer", "collector", "critic", "logger", "noise", "reward"}
    assert {"calm", "moderate", "rough"} <= {option for group, option in OPTIONS if group == "env/sea"}


@pytest.mark.parametrize("group,option", OPTIONS, ids=[f"{g}={o}" for g, o in OPTIONS])
def test_every_option_composes_and_validates(group, option):
    cfg = compose_config("config", [f"{group}={option}"])
    validate(cfg)
    if group in SELECTED:
        assert cfg[group].name == NAMED_AS.get((group, option), option)


def test_the_paper_preset_is_the_papers_table_one_override_away():
    cfg = compose_config("config", ["+experiment=paper"])
    validate(cfg)
    assert (cfg.critic.lr, cfg.actor.lr, cfg.agent.gamma, cfg.buffer.batch_size) == (1e-4, 1e-3, 0.2, 64)
    assert (cfg.noise.sigma_init, cfg.noise.sigma_end, cfg.total_frames) == (0.1, 0.02, 250_000)
    assert cfg.env.observation_extras == [] and cfg.env.latency_steps == 0 and cfg.env.action_mode == "absolute"
    assert cfg.reward.pointing == 0.0 and cfg.env.offset_range is None and cfg.agent.name == "ddpg"
    assert cfg.agent.policy_weights == "last"


def test_an_averaged_policy_without_a_target_actor_is_a_one_line_error():
    cfg = compose_config("config", ["agent.loss.delay_actor=false"])
    with pytest.raises(ValueError, match=r"^agent.policy_weights = 'average' needs the target actor"):
        validate(cfg)
    validate(compose_config("config", ["agent.loss.delay_actor=false", "agent.policy_weights=last"]))


@pytest.mark.parametrize("launcher", LAUNCHERS)
def test_every_launcher_composes(launcher):
    cfg = compose_config("config", [f"hydra/launcher={launcher}"], return_hydra_config=True)
    validate(cfg)
    assert launcher.split("_")[0] in cfg.hydra.launcher._target_.lower()


@pytest.mark.parametrize(
    "group,option,unread",
    [("reward", "linear", {"a", "b", "c", "gain", "bias", "floor"}), ("reward", "log", {"a", "b", "c", "gain"}),
     ("agent", "ddpg", {"policy_delay", "policy_noise", "noise_clip"}), ("noise", "gaussian", {"theta"}),
     ("buffer", "memory", {"scratch_dir"})],
)  # fmt: skip
def test_option_files_carry_no_key_their_option_ignores(group, option, unread):
    keys = set(OmegaConf.load(ROOT / "conf" / group / f"{option}.yaml"))
    assert not keys & unread


def test_a_loss_target_that_does_not_match_the_agent_is_a_one_line_error():
    cfg = compose_config("config", ["agent=ddpg", "agent.loss._target_=torchrl.objectives.TD3Loss"])
    with pytest.raises(ValueError, match=r"^agent.loss._target_ = 'torchrl.objectives.TD3Loss' is not allowed"):
        validate(cfg)


@pytest.mark.parametrize("name", ["default", "intensity", "paper"])
def test_each_shipped_policy_config_is_a_valid_config(name):
    validate(OmegaConf.load(ROOT / "waterair" / "assets" / f"{name}.yaml"))
