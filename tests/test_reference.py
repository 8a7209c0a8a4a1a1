"""Each env default is written once, in the dataclasses (docs/environment.md, "Config keys"): ``make docs``
(:mod:`waterair.cli.reference`) generates what states it again (conf/env/default.yaml, the seas' and channels'
options, docs/reference/env.md), the hand-written options hold only what they change, and no hand-written doc
tabulates an env key."""

import dataclasses
import re

import pytest
from omegaconf import OmegaConf
from test_docs import hand_written_docs

from waterair.cli import reference
from waterair.envs.config import EnvConfig
from waterair.envs.groups import PHYSICS
from waterair.envs.keys import KEYS
from waterair.physics.actuator import Actuator
from waterair.physics.channel import CHANNELS, Beacon, LinkGeometry, Transceiver
from waterair.physics.motion import Motion
from waterair.physics.sea import SPECTRA
from waterair.training.config import CONF_DIR
from waterair.training.keys import TRAINING_KEYS


def env_keys() -> set[str]:
    """Every key of EnvConfig and of the objects its groups hold: ``num_envs``, ``sea.wind``, ``channel.rays``."""
    keys = {field.name for field in dataclasses.fields(EnvConfig) if field.name not in PHYSICS}
    keys |= {"sea.spectrum", "channel.name"}
    held = [("sea", kind) for kind in SPECTRA.values()] + [("channel", kind) for kind in CHANNELS.values()]
    held += [("geometry", LinkGeometry), ("optics", Transceiver), ("beacon", Beacon), ("actuator", Actuator)]
    held += [("motion", Motion)]
    return keys | {f"{group}.{field.name}" for group, kind in held for field in dataclasses.fields(kind)} - {"sea.flat"}


@pytest.mark.parametrize("part", ["conf", "env", "training"])
def test_the_generated_files_equal_a_fresh_generation(part):
    """Each part on its own (each composes its configs, a third of a second each)."""
    generate = {"conf": reference.conf_files, "env": lambda: {reference.REFERENCE: reference.reference()},
                "training": lambda: {reference.TRAINING_REFERENCE: reference.training_reference()}}[part]  # fmt: skip
    assert [path.relative_to(reference.ROOT) for path in reference.stale(write=False, parts=[generate])] == []


def test_a_changed_default_leaves_the_yaml_stale_and_changes_the_reference(monkeypatch):
    @dataclasses.dataclass(frozen=True)
    class Changed(EnvConfig):
        dt: float = 0.1

    monkeypatch.setattr(reference, "EnvConfig", Changed)
    assert reference.env_group()["dt"] == 0.1 and reference.dataclass_default("dt") == 0.1
    assert reference.stale(write=False, parts=[reference.conf_files]) == [CONF_DIR / "env" / "default.yaml"]


def test_every_env_key_is_described_once_and_the_generated_group_composes_to_the_defaults():
    assert set(KEYS) == env_keys()
    group = reference.env_group()
    assert {key: group.pop(key) for key in reference.DECIDED} == reference.DECIDED
    # conf/env/default.yaml as Hydra reads it: the operating point's interpolations resolve to the groups' defaults
    written = OmegaConf.create({"env": OmegaConf.load(CONF_DIR / "env" / "default.yaml"), "device": "cpu", "seed": 0})
    resolved = OmegaConf.to_container(written.env, resolve=True)
    defaults = EnvConfig().to_mapping()
    assert resolved["geometry"] == defaults["geometry"] and resolved["optics"] == defaults["optics"]
    assert resolved["sea"] == {key: defaults["sea"][key] for key in resolved["sea"]}
    assert {key: resolved[key] for key in ("dt", "residual_deg", "observation_extras")} == {"dt": 0.05,
            "residual_deg": EnvConfig().residual_deg, "observation_extras": []}  # fmt: skip


def test_each_hand_written_option_sets_only_what_it_changes():
    """An option of env/sea, env/observation or env/sensor names a key only to set it off its default; train.py's
    env block likewise, and the paper preset off train.py's."""
    restated = [
        f"env/{group}={option}: {key}"
        for group in reference.HAND_WRITTEN
        for option, values in reference._options(group).items()
        for key, value in values.items()
        if reference._same(value, reference.dataclass_default(key))
    ]
    train = OmegaConf.to_container(OmegaConf.load(CONF_DIR / "config.yaml"))["env"]
    composed = reference._composed("config", [])
    restated += [
        f"config.yaml: {key}" for key in train if reference._same(composed[key], reference.dataclass_default(key))
    ]
    paper = OmegaConf.to_container(OmegaConf.load(CONF_DIR / "experiment" / "paper.yaml"))["env"]
    restated += [f"experiment/paper.yaml: {key}" for key in paper if reference._same(paper[key], composed[key])]
    assert restated == []


@pytest.mark.parametrize("written", ["moderate", "ideal"])
def test_the_restatement_check_finds_an_option_that_states_a_default(monkeypatch, tmp_path, written):
    conf = tmp_path / "conf"
    conf.mkdir()
    for path in CONF_DIR.rglob("*.yaml"):
        (conf / path.relative_to(CONF_DIR)).parent.mkdir(parents=True, exist_ok=True)
        (conf / path.relative_to(CONF_DIR)).write_text(path.read_text())
    group, line = {"moderate": ("sea", "fetch: 20000.0"), "ideal": ("sensor", "latency_steps: 0")}[written]
    with open(conf / "env" / group / f"{written}.yaml", "a") as file:
        file.write(line + "\n")
    monkeypatch.setattr(reference, "CONF_DIR", conf)
    values = reference._options(group)[written]
    key = next(iter(values))
    assert reference._same(values[key], reference.dataclass_default(key))


ROW = re.compile(r"^\| `([\w.]+)`")


def tabulated(text: str, keys: set[str]) -> list[str]:
    """The ``keys`` leading a row of a table with a default column in ``text``."""
    found, header = [], None
    for line in text.splitlines():
        if not line.startswith("|"):
            header = None
        elif header is None:
            header = [cell.strip() for cell in line.strip("|").split("|")]
        elif "default" in header and (match := ROW.match(line)) and match.group(1) in keys:
            found.append(match.group(1))
    return found


def test_no_hand_written_doc_tabulates_a_key_with_its_default():
    """The key tables are docs/reference's, generated; a hand-written one would be a second copy. An env key is
    ``env.<key>`` but on docs/environment.md; a key of train.py's is named as it is (``agent.gamma``), but on
    docs/evaluation.md, whose table is of evaluate.py's own keys (its ``device``, ``seed``)."""
    env, training = env_keys(), set(TRAINING_KEYS)
    named = {path.name: (training if path.name != "evaluation.md" else set())
             | (env if path.name == "environment.md" else {f"env.{key}" for key in env})
             for path in hand_written_docs()}  # fmt: skip
    docs = {path.name: tabulated(path.read_text(), named[path.name]) for path in hand_written_docs()}
    assert docs == {name: [] for name in docs}
    # the check finds every row of a key table
    assert set(tabulated(reference.REFERENCE.read_text(), env)) == env
    assert set(tabulated(reference.TRAINING_REFERENCE.read_text(), training)) == training
