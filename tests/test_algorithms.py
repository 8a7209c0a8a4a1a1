"""waterair.training.algorithms: one registry names the algorithms; it, conf/agent and the classes agree.

Only the registry (``waterair/training/algorithms/__init__.py``), conf/, the docs and the benchmarks
(``waterair/bench``, which name what they time) may name an algorithm: anywhere else in the package
an agent-name literal or a comparison of ``agent.name`` is a branch on the name that belongs in an
algorithm's module.
"""

import ast
import importlib
import inspect
import pkgutil
from pathlib import Path

from conftest import ROOT
from omegaconf import OmegaConf

import waterair.training.algorithms as algorithms
from waterair.training.algorithms import ALGORITHMS, Algorithm
from waterair.training.algorithms.ddpg import DDPG
from waterair.training.algorithms.ppo import PPO
from waterair.training.algorithms.sac import SAC
from waterair.training.algorithms.td3 import TD3

AGENT_CONF = ROOT / "conf" / "agent"
REGISTRY = ROOT / "waterair" / "training" / "algorithms" / "__init__.py"
MAY_NAME = (REGISTRY, ROOT / "waterair" / "bench")
"""Where an algorithm may be named: the registry, and the benchmarks."""
CHECKED = [p for p in [*sorted((ROOT / "waterair").rglob("*.py")), *sorted((ROOT / "hydra_plugins").rglob("*.py"))]
           if not any(p == place or place in p.parents for place in MAY_NAME)]  # fmt: skip
CHECKED += [ROOT / "train.py", ROOT / "evaluate.py"]


def disagreements(registry: dict, conf_dir: Path, classes: list[type]) -> list[str]:
    """How the registry, the agent options in ``conf_dir`` and the algorithm ``classes`` differ."""
    problems = []
    options = {path.stem: OmegaConf.load(path) for path in sorted(conf_dir.glob("*.yaml"))}
    if set(registry) != set(options):
        problems.append(f"registry {sorted(registry)} but conf/agent options {sorted(options)}")
    if set(registry.values()) != set(classes) or len(set(registry.values())) != len(registry):
        problems.append(f"registry classes {sorted(c.__name__ for c in registry.values())} but algorithm classes "
                        f"{sorted(c.__name__ for c in classes)}, each registered once")  # fmt: skip
    for name in sorted(set(registry) & set(options)):
        algorithm, option = registry[name], options[name]
        if option.agent.name != name:
            problems.append(f"conf/agent/{name}.yaml has agent.name = {option.agent.name!r}")
        if option.agent.loss._target_ != algorithm.loss_target:
            problems.append(f"conf/agent/{name}.yaml's loss {option.agent.loss._target_} but "
                            f"{algorithm.__name__}.loss_target {algorithm.loss_target}")  # fmt: skip
        if algorithm.__module__ != f"{algorithms.__name__}.{name}":
            problems.append(f"{name} is {algorithm.__module__}.{algorithm.__name__}, not in a module of its own name")
        if algorithm.on_policy and option.collector.init_random_frames != 0:  # random actions have no log-prob
            problems.append(f"conf/agent/{name}.yaml starts with random frames; {algorithm.__name__} is on-policy")
    return problems


def algorithm_classes() -> list[type]:
    """Every concrete :class:`Algorithm` defined in the sub-package's modules."""
    found = set()
    for module in pkgutil.iter_modules(algorithms.__path__):
        loaded = importlib.import_module(f"{algorithms.__name__}.{module.name}")
        for _, value in inspect.getmembers(loaded, inspect.isclass):
            if issubclass(value, Algorithm) and not inspect.isabstract(value) and value.__module__ == loaded.__name__:
                found.add(value)
    return sorted(found, key=lambda c: c.__name__)


def name_uses(source: str, names) -> list[str]:
    """Agent-name literals (any case) and comparisons of ``agent.name`` in ``source``, with their lines."""
    found = []
    lowered = {name.lower() for name in names}
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value.lower() in lowered:
            found.append(f"line {node.lineno}: the literal {node.value!r}")
        operands = [node.left, *node.comparators] if isinstance(node, ast.Compare) else []
        operands += [node.subject] if isinstance(node, ast.Match) else []
        if any(_is_agent_name(operand) for operand in operands):
            found.append(f"line {node.lineno}: a comparison of agent.name")
    return found


def _is_agent_name(node: ast.AST) -> bool:
    """``agent.name``, ``cfg.agent.name``, ``cfg["agent"].name``, ``cfg.agent["name"]`` and the like."""
    if isinstance(node, ast.Attribute) and node.attr == "name":
        owner = node.value
    elif isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant) and node.slice.value == "name":
        owner = node.value
    else:
        return False
    if isinstance(owner, ast.Subscript) and isinstance(owner.slice, ast.Constant):
        return owner.slice.value == "agent"
    return (isinstance(owner, ast.Name) and owner.id == "agent") or (
        isinstance(owner, ast.Attribute) and owner.attr == "agent"
    )


def test_the_registry_the_agent_options_and_the_algorithm_classes_agree():
    assert disagreements(ALGORITHMS, AGENT_CONF, algorithm_classes()) == []


def test_the_agreement_check_catches_each_kind_of_disagreement(tmp_path):
    for path in AGENT_CONF.glob("*.yaml"):
        (tmp_path / path.name).write_text(path.read_text())
    classes = algorithm_classes()
    # a class registered under another's name, so one is registered twice and one not at all
    swapped = disagreements({**ALGORITHMS, "td3": DDPG}, tmp_path, classes)
    assert any("each registered once" in p for p in swapped)
    assert any("td3.yaml's loss torchrl.objectives.TD3Loss but DDPG.loss_target" in p for p in swapped)
    assert any("td3 is waterair.training.algorithms.ddpg.DDPG, not in a module" in p for p in swapped)
    # an option without an algorithm, and an option naming another agent
    (tmp_path / "a2c.yaml").write_text((AGENT_CONF / "ddpg.yaml").read_text())
    (tmp_path / "ppo.yaml").write_text((AGENT_CONF / "ppo.yaml").read_text().replace("name: ppo", "name: pp0"))
    problems = disagreements(ALGORITHMS, tmp_path, classes)
    assert any("conf/agent options ['a2c', 'ddpg', 'ppo', 'sac', 'td3']" in p for p in problems)
    assert "conf/agent/ppo.yaml has agent.name = 'pp0'" in problems
    # an algorithm class left out of the registry, and an on-policy agent starting on random actions
    assert any("but algorithm classes" in p for p in disagreements({"ppo": PPO, "ddpg": DDPG}, AGENT_CONF, classes))
    ppo = (AGENT_CONF / "ppo.yaml").read_text()
    (tmp_path / "ppo.yaml").write_text(ppo.replace("init_random_frames: 0", "init_random_frames: 400"))
    assert any("is on-policy" in p for p in disagreements(ALGORITHMS, tmp_path, classes))
    assert {TD3, PPO, DDPG, SAC} == set(classes)


def test_nothing_outside_the_registry_names_an_algorithm_or_compares_agent_name():
    found = {str(p.relative_to(ROOT)): uses for p in CHECKED if (uses := name_uses(p.read_text(), ALGORITHMS))}
    assert found == {}
    assert REGISTRY not in CHECKED and ROOT / "waterair" / "training" / "loop.py" in CHECKED
    assert name_uses(REGISTRY.read_text(), ALGORITHMS)  # the check reads names where they are


def test_the_name_check_catches_a_literal_or_a_comparison_but_not_a_lookup_or_a_message():
    caught = """
ON_POLICY = ("ppo",)
if cfg.agent.name == "td3":
    pass
on_policy = agent.name in ON_POLICY
key = {"DDPG": 1}.get(cfg["agent"].name)
match cfg.agent.name:
    case _:
        pass
"""
    assert sorted(use.split(":")[0] for use in name_uses(caught, ALGORITHMS)) == [
        "line 2", "line 3", "line 3", "line 5", "line 6", "line 7",
    ]  # fmt: skip
    allowed = 'algorithm = ALGORITHMS[cfg.agent.name]\nraise ValueError("agent=ppo learns its action noise")\n'
    assert name_uses(allowed, ALGORITHMS) == []
