"""The package layout: imports point down the layers, no cycles, light imports, short modules.

Layers, bottom to top: core → physics → envs → agents → evaluation → training → cli, then the entry
points. A module may import its own layer and the ones below; nothing imports ``waterair.bench``.
Inside training, the algorithms (``waterair.training.algorithms``) sit below the loop, its builders and
its config: they import nothing else of training. Imports inside functions count too.
"""

import ast
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import ROOT

PACKAGE = ROOT / "waterair"
LAYERS = ("core", "physics", "envs", "agents", "evaluation", "training", "cli")
"""Sub-packages from the bottom up."""
FORBIDDEN = {
    "core": {"torchrl", "hydra", "omegaconf", "tensorboard", "matplotlib", "tensordict"},
    "physics": {"torchrl", "hydra", "omegaconf", "tensorboard", "matplotlib"},
    "envs": {"hydra", "omegaconf", "tensorboard", "matplotlib"},
    "agents": {"hydra", "omegaconf", "tensorboard", "matplotlib"},
    "evaluation": {"tensorboard"},
}
"""Third-party packages each layer must not import."""
BENEATH = {"waterair.training.algorithms": "waterair.training"}
"""Sub-packages below the rest of their layer: they import nothing of it outside themselves."""
MAX_LINES = 420
"""About 400 lines: a longer module is asking to be split."""
MAX_PARAMETERS = 8
"""The most parameters a function of the physics or the envs takes (``self``/``cls`` not counted): past it, what
belongs together (a sea's harmonics, a solver's options, a sensor's settings) is passed whole."""
MAX_POSITIONAL = 7
"""The most positional parameters of such a function: the rest by keyword, or the named result they come from
(an ``Iterate``, a ``PathSolution``, the ``RefractiveIndices``) passed whole rather than unpacked field by field."""


def module_name(path: Path, root: Path = ROOT) -> str:
    parts = path.relative_to(root).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported_modules(path: Path, modules: set[str], root: Path = ROOT) -> set[str]:
    """Every module ``path`` imports anywhere in its body (``from X import Y`` counts X.Y if it is a module)."""
    name = module_name(path, root)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            for alias in node.names:
                candidate = f"{base}.{alias.name}"
                found.add(candidate if candidate in modules else base)
    return found


def graph(files: list[Path]) -> dict[str, set[str]]:
    modules = {module_name(f) for f in files}
    return {module_name(f): imported_modules(f, modules) for f in files}


def layer_of(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[0] == "waterair" else None


def layering_violations(imports: dict[str, set[str]]) -> list[str]:
    """Imports that point up the layers, into bench, or at a package a layer must not use."""
    problems = []
    for source, targets in imports.items():
        layer = layer_of(source)
        for target in targets:
            top = target.split(".")[0]
            if layer in FORBIDDEN and top in FORBIDDEN[layer]:
                problems.append(f"{source} imports {target} ({layer} must not use {top})")
            if top != "waterair":
                continue
            if layer_of(target) == "bench" and layer != "bench":
                problems.append(f"{source} imports {target} (nothing imports bench)")
            if layer in LAYERS and target == "waterair":
                problems.append(f"{source} imports the root package waterair (import the sub-package)")
            if layer in LAYERS and layer_of(target) in LAYERS:
                if LAYERS.index(layer_of(target)) > LAYERS.index(layer):
                    problems.append(f"{source} ({layer}) imports {target} ({layer_of(target)}), a higher layer")
            for low, rest in BENEATH.items():
                if _within(source, low) and not _within(target, low) and _within(target, rest):
                    problems.append(f"{source} imports {target} ({low} sits below the rest of {rest})")
    return problems


def _within(module: str, package: str) -> bool:
    return module == package or module.startswith(f"{package}.")


def cycles(imports: dict[str, set[str]]) -> list[list[str]]:
    """Import cycles among the modules (strongly connected components of more than one module)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(node):
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for nxt in imports.get(node, ()):
            if nxt not in imports:
                continue
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in on_stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1 or node in imports.get(node, ()):
                found.append(sorted(component))

    for node in imports:
        if node not in index:
            visit(node)
    return found


SOURCES = sorted(PACKAGE.rglob("*.py")) + [ROOT / "train.py", ROOT / "evaluate.py"]


def channel_name_literals(files: list[Path]) -> list[str]:
    """String constants that are a channel's name (``"full"``, ``"single_path"``, ...) in ``files``."""
    from waterair.physics.channel import CHANNELS

    return [f"{path}:{node.lineno} {node.value!r}" for path in files
            for node in ast.walk(ast.parse(path.read_text()))
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in CHANNELS]  # fmt: skip


def test_no_channel_is_named_outside_physics_channel():
    """A model's traits are its class's (waterair.physics.channel.registry); nothing else compares its name.
    Benchmarks may name what they time."""
    allowed = (PACKAGE / "physics" / "channel", PACKAGE / "bench")
    outside = [path for path in SOURCES if not any(path.is_relative_to(folder) for folder in allowed)]
    assert channel_name_literals(outside) == []


def test_a_channel_name_literal_is_found(tmp_path):
    module = tmp_path / "late.py"
    module.write_text('def f(config):\n    return config.channel == "single_path"\n')
    assert channel_name_literals([module]) and not channel_name_literals([ROOT / "waterair" / "core" / "files.py"])


def test_imports_point_down_the_layers():
    assert layering_violations(graph(SOURCES)) == []


def test_no_import_cycles():
    assert cycles(graph(SOURCES)) == []


def test_the_checks_catch_an_upward_import_and_a_cycle():
    # The same checks on a made-up graph: physics reaching up into training, and a two-module cycle.
    bad = {
        "waterair.physics.sea": {"waterair.training.loop", "torchrl"},
        "waterair.training.loop": {"waterair.training.builders"},
        "waterair.training.builders": {"waterair.training.loop"},
        "waterair.envs.env": {"waterair.bench.env"},
        "waterair.training.algorithms.ppo": {"waterair.training.builders", "waterair.training.algorithms.base"},
    }
    problems = layering_violations(bad)
    assert [p for p in problems if "sits below" in p] == [
        "waterair.training.algorithms.ppo imports waterair.training.builders (waterair.training.algorithms sits "
        "below the rest of waterair.training)"
    ]
    assert any("higher layer" in p for p in problems)
    assert any("must not use torchrl" in p for p in problems)
    assert any("nothing imports bench" in p for p in problems)
    assert cycles(bad) == [["waterair.training.builders", "waterair.training.loop"]]


def test_function_level_imports_count(tmp_path):
    module = tmp_path / "waterair" / "physics" / "late.py"
    module.parent.mkdir(parents=True)
    module.write_text("def f():\n    from waterair.envs.env import WaterAirEnv\n    return WaterAirEnv\n")
    imports = {"waterair.physics.late": imported_modules(module, set(), root=tmp_path)}
    assert imports["waterair.physics.late"] == {"waterair.envs.env"}
    assert any("higher layer" in p for p in layering_violations(imports))


def test_no_module_is_much_over_400_lines():
    long = {str(p.relative_to(ROOT)): n for p in SOURCES if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert long == {}


def long_signatures(files: list[Path], root: Path = ROOT) -> dict[str, int]:
    """Functions of ``files`` with more than :data:`MAX_PARAMETERS` parameters (positional, keyword-only,
    ``*args``, ``**kwargs``; a method's ``self`` or ``cls`` not counted) or more than :data:`MAX_POSITIONAL`
    positional ones, as ``path:line name`` → their parameters."""
    found = {}
    for path in files:
        tree = ast.parse(path.read_text())
        methods = {id(f) for c in ast.walk(tree) if isinstance(c, ast.ClassDef) for f in c.body}
        for node in ast.walk(tree):
            if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            arguments = node.args
            names = [a.arg for a in (*arguments.posonlyargs, *arguments.args)]
            static = any(isinstance(d, ast.Name) and d.id == "staticmethod" for d in node.decorator_list)
            bound = id(node) in methods and not static and names[:1] in (["self"], ["cls"])
            positional = len(names) - bound
            count = positional + len(arguments.kwonlyargs) + bool(arguments.vararg) + bool(arguments.kwarg)
            if count > MAX_PARAMETERS or positional > MAX_POSITIONAL:
                found[f"{path.relative_to(root)}:{node.lineno} {node.name}"] = count
    return found


def test_no_physics_or_env_function_takes_more_than_eight_parameters_or_seven_positional_ones():
    files = [p for p in SOURCES if p.is_relative_to(PACKAGE / "physics") or p.is_relative_to(PACKAGE / "envs")]
    assert long_signatures(files) == {}
    # sensor noise is read by the name of what it feeds (envs.sensors.SensorNoise), not by column
    assert [str(p.relative_to(ROOT)) for p in files if "noise[" in p.read_text()] == []


def test_a_long_signature_is_found(tmp_path):
    module = tmp_path / "wide.py"
    module.write_text(
        "class A:\n    def m(self, a, b, c, d, e, f, g):\n        pass\n\n"
        "def f(a, b, c, d, e, f, g, *h, i, **j):\n    pass\n\n"
        "def g(a, b, c, d, e, f, g, h):\n    pass\n\n"
        "def h(a, b, c, d, e, f, g, *, i=1):\n    pass\n"
    )
    assert long_signatures([module], root=tmp_path) == {"wide.py:5 f": 10, "wide.py:8 g": 8}


HEAVY = ("torchrl", "hydra", "omegaconf", "tensorboard", "matplotlib")
"""The RL, config and plotting stacks, which the physics API must not load."""


@pytest.fixture(scope="module")
def tour() -> subprocess.CompletedProcess:
    """README's tour (``from waterair import ...``: the package and its physics) run as written in a process of
    its own, which then prints, as its last line, which of :data:`HEAVY` it loaded."""
    readme = (ROOT / "README.md").read_text()
    code = readme.split("## A short tour", 1)[1].split("```python\n", 1)[1].split("```", 1)[0]
    code += f"\nimport sys\nprint(sorted({{m.split('.')[0] for m in sys.modules}} & set({HEAVY!r})))\n"
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)


def test_the_physics_api_imports_no_rl_or_plotting_stack(tour):
    assert tour.returncode == 0, tour.stderr[-2000:]
    assert tour.stdout.strip().splitlines()[-1] == "[]"


def test_the_readme_tour_runs_as_written(tour):
    assert tour.returncode == 0, tour.stderr[-2000:]
    printed = dict(line.split(" ", 1) for line in tour.stdout.strip().splitlines()[:-1])
    intensity = {name: float(value.removeprefix("tensor(").rstrip(")")) for name, value in printed.items()}
    assert 0.8 < intensity["single_path"] < 1.2  # aligned along the exact path: about the calm-sea gain
    # the full channel on the measured-slope sea at 12 m/s: the unresolved slopes spread the beam after the
    # surface, and the paper's one path gives 1.6-2.6x the received power (docs/model.md §4)
    assert 1.6 < intensity["single_path"] / intensity["full"] < 2.6
