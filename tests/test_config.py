"""Every option of every config group composes and validates; option files carry only keys they read."""

import pytest
from conftest import ROOT, compose_config
from omegaconf import OmegaConf

from waterair.evaluation.policies import SHIPPED
from waterair.training.config import validate

GROUPS = {
    group.name: sorted(p.stem for p in group.glob("*.yaml"))
    for group in sorted((ROOT / "conf").iterdir())
    if group.is_dir() and group.name not in ("env", "hydra", "experiment", "study", "scenarios")  # last two: evaluate
}
OPTIONS = [(group, option) for group, options in GROUPS.items() for option in options]
OPTIONS += [
    (f"{package}/{group}", p.stem)
    for package, groups in (("env", ("sea", "sensor", "observation")), ("link", ("receiver", "background")))
    for group in groups
    for p in sorted((ROOT / "conf" / package / group).glob("*.yaml"))
]
LAUNCHERS = ["basic", "joblib", "submitit_local", "submitit_slurm"]
SELECTED = {"actor", "critic", "agent", "buffer", "noise", "reward", "logger"}
"""Groups whose options say which one they are, always under the key ``name``."""
NAMED_AS = {("reward", "pointing"): "le"}
"""Options that are another option's function with other values (the LE reward with its pointing term)."""


def test_every_group_is_covered():
    assert set(GROUPS) == {"actor", "agent", "buffer", "collector", "critic", "link", "logger", "noise", "reward"}
    assert {"calm", "moderate", "rough"} <= {option for group, option in OPTIONS if group == "env/sea"}
    assert {("link/receiver", "apd"), ("link/receiver", "pin"), ("link/background", "night")} <= set(OPTIONS)


OFF_POLICY_ONLY = {("noise", "ou")}
"""Options of other groups that only an off-policy agent reads (PPO learns its own action noise)."""


@pytest.mark.parametrize("group,option", OPTIONS, ids=[f"{g}={o}" for g, o in OPTIONS])
def test_every_option_composes_and_validates(group, option):
    agent = ["agent=ddpg"] if (group, option) in OFF_POLICY_ONLY else []
    cfg = compose_config("config", [*agent, f"{group}={option}"])
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


@pytest.mark.parametrize("agent", ["ddpg", "td3"])
def test_the_short_run_preset_changes_the_collection_and_the_saved_policy_only(agent):
    """``+experiment=short_run`` is applied after the agent option (which sets 16,000 random frames): exactly its
    four keys differ from the agent's defaults, and the result validates."""
    plain = compose_config("config", [f"agent={agent}"])
    short = compose_config("config", [f"agent={agent}", "+experiment=short_run"])
    validate(short)

    def leaves(node, prefix=""):
        if not isinstance(node, dict):
            return {prefix[:-1]: node}
        return {key: value for name, child in node.items() for key, value in leaves(child, f"{prefix}{name}.").items()}

    before, after = (leaves(OmegaConf.to_container(cfg, resolve=True)) for cfg in (plain, short))
    assert before.keys() == after.keys()
    changed = {key: (before[key], after[key]) for key in before if repr(before[key]) != repr(after[key])}
    assert changed == {
        "env.num_envs": (64, 32),
        "collector.frames_per_batch": (1600, 800),
        "collector.init_random_frames": (16000, 800),
        "agent.policy_weights": ("average", "last"),
    }


def test_an_averaged_policy_without_a_target_actor_is_a_one_line_error():
    cfg = compose_config("config", ["agent=ddpg", "agent.loss.delay_actor=false"])
    with pytest.raises(ValueError, match=r"^agent.policy_weights = 'average' needs the target actor"):
        validate(cfg)
    validate(compose_config("config", ["agent=ddpg", "agent.loss.delay_actor=false", "agent.policy_weights=last"]))


@pytest.mark.parametrize("launcher", LAUNCHERS)
def test_every_launcher_composes(launcher):
    cfg = compose_config("config", [f"hydra/launcher={launcher}"], return_hydra_config=True)
    validate(cfg)
    # submitit's launchers are ours, waiting for every job (hydra_plugins/waterair_sweeps/launchers.py)
    expected = {"submitit_local": "waterair_sweeps.launchers.locallauncher", "submitit_slurm": "slurmlauncher"}
    assert expected.get(launcher, launcher) in cfg.hydra.launcher._target_.lower()


@pytest.mark.parametrize(
    "group,option,unread",
    [("reward", "linear", {"a", "b", "c", "gain", "bias", "floor"}), ("reward", "log", {"a", "b", "c", "gain"}),
     ("reward", "snr", {"a", "b", "c", "gain", "bias", "floor"}),
     ("agent", "ddpg", {"policy_delay", "policy_noise", "noise_clip", "lmbda", "max_grad_norm"}),
     ("agent", "ppo", {"tau", "policy_delay", "policy_noise", "noise_clip"}), ("noise", "gaussian", {"theta"}),
     ("buffer", "memory", {"scratch_dir"})],
)  # fmt: skip
def test_option_files_carry_no_key_their_option_ignores(group, option, unread):
    keys = OmegaConf.load(ROOT / "conf" / group / f"{option}.yaml")
    keys = set(keys[group] if group == "agent" else keys)  # an agent option sets its learning rates too
    assert keys and not keys & unread


def test_each_agent_option_sets_its_learning_rates_and_update_schedule():
    for option in GROUPS["agent"]:
        cfg = OmegaConf.load(ROOT / "conf" / "agent" / f"{option}.yaml")
        assert set(cfg) == {"agent", "actor", "critic", "collector"}, option
        assert set(cfg.collector) == {"init_random_frames", "updates_per_frame"} and "lr" in cfg.actor, option
    assert compose_config("config", ["agent=ddpg"]).collector.init_random_frames == 16000
    assert compose_config("config", ["agent=ppo", "critic.lr=1e-3"]).critic.lr == 1e-3  # the command line wins


@pytest.mark.parametrize(
    "overrides,message",
    [
        (
            ["agent=ppo", "agent.policy_weights=average"],
            r"^agent.policy_weights = 'average' is not allowed with agent=ppo",
        ),
        (["agent=ppo", "noise=ou"], r"^agent=ppo learns its action noise, starting at noise.sigma_init; noise=ou"),
        (["agent=ppo", "noise.sigma_end=0.01"], r"^agent=ppo learns its action noise.*sigma_end = 0.01"),
        (["agent=ppo", "buffer.batch_size=2000"], r"^buffer.batch_size = 2000 is out of range"),
        (["agent=ppo", "agent.loss.clip_epsilon=0"], r"^agent.loss.clip_epsilon = 0"),
        (["agent=ppo", "agent.loss.loss_critic_type=l3"], r"^agent.loss.loss_critic_type = 'l3' is not allowed"),
        (["agent=ppo", "agent.loss.entropy_bonus=1e-2"], r"^agent.loss.entropy_bonus = 0.01 must be true or false"),
        (["agent=ppo", "checkpoint.keep_buffer=true"], r"^checkpoint.keep_buffer = true is not allowed with agent=ppo"),
    ],
)
def test_ppo_settings_that_cannot_work_are_one_line_errors(overrides, message):
    with pytest.raises(ValueError, match=message):
        validate(compose_config("config", overrides))


def test_a_loss_target_that_does_not_match_the_agent_is_a_one_line_error():
    cfg = compose_config("config", ["agent=ddpg", "agent.loss._target_=torchrl.objectives.TD3Loss"])
    with pytest.raises(ValueError, match=r"^agent.loss._target_ = 'torchrl.objectives.TD3Loss' is not allowed"):
        validate(cfg)


@pytest.mark.parametrize("name", list(SHIPPED))
def test_each_shipped_policy_config_is_a_valid_config(name):
    validate(OmegaConf.load(ROOT / "waterair" / "assets" / f"{name}.yaml"))


def test_every_noise_and_buffer_the_config_allows_is_one_entry_of_the_builders_registries():
    from waterair.training import builders
    from waterair.training import config as training_config
    from waterair.training.algorithms import off_policy

    assert set(off_policy.EXPLORATION_NOISES) == set(training_config.NOISES)
    assert set(builders.STORAGES) == set(training_config.BUFFERS)


def test_the_publish_scenarios_change_s5s_seas_only():
    """``+scenarios=publish`` (docs/results' numbers): evaluate.py's config with S5 on 256 seas, nothing else."""
    default = OmegaConf.to_container(compose_config("evaluate"), resolve=True)
    publish = OmegaConf.to_container(compose_config("evaluate", ["+scenarios=publish"]), resolve=True)
    assert publish["scenarios"]["S5"].pop("realisations") == 256 > default["scenarios"]["S5"].pop("realisations")
    assert publish == default
