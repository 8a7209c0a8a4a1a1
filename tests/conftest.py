"""Shared fixtures and helpers: the default geometry as tensors, Hydra configs composed from conf/."""

import gc

gc.disable()  # until the tests are collected (pytest_runtestloop, below): imports and collection 2 s shorter

import os
import platform
from pathlib import Path

import pytest
import torch
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

import waterair.training.config  # noqa: F401  (registers the config's resolvers, as train.py's imports do)
from waterair.core.process import set_up_process
from waterair.envs.config import EnvConfig
from waterair.physics.channel import LinkGeometry
from waterair.physics.surface import WaveSurface

if os.environ.get("PYTEST_XDIST_WORKER"):  # workers share the cores: one torch thread each
    torch.set_num_threads(1)

# inductor's first compile in a process on an empty compile cache builds and loads a C++ program for each vector
# instruction set the CPU's flags list, to see that the compiler can target it (about 12 s on the slower machine,
# paid in each worker that compiles); the tests take the CPU's flags as the answer, in this process and in those
# they start. What the probe guards against, a C++ compiler too old for the CPU, is one a user's first compile
# shows.
torch._inductor.config.cpp.vec_isa_ok = True
os.environ["TORCHINDUCTOR_VEC_ISA_OK"] = "1"
# The tests' graphs are emitted as scalar C++ loops: inductor's lowering, fusion and graphs are a user's, only the
# loops are not written a second time with vector instructions, which took half of each compile (25 s against 11 s
# for the full channel's reception, docs/benchmarks.md, "Tests"). What the tests show, that a graph is traced once
# and computes what eager computes, does not depend on it; a user's compile and the benchmark's emit both.
torch._inductor.config.cpp.simdlen = 1
# Each worker compiles in its own process, one core each: a pool of compile processes (torch's default, one per
# core) would start and import torch in every worker only to share the same two cores.
torch._inductor.config.compile_threads = 1
os.environ["TORCHINDUCTOR_COMPILE_THREADS"] = "1"

ROOT = Path(__file__).resolve().parents[1]
"""The repository root (where train.py, evaluate.py and conf/ live)."""


@pytest.hookimpl(tryfirst=True)
def pytest_runtestloop(session):
    """Before the first test (in a worker, its tests collected; in ``-n``'s controlling process, before it hands
    them out): the process set up as an entry point sets up its own once its imports are done
    (:func:`waterair.core.process.set_up_process`: the collector, the allocator, dynamo's recompile limits, the
    inductor fix). The tests run as a user's command runs; tests/test_process.py checks that the library alone
    changes none of it."""
    set_up_process()


def pytest_collection_modifyitems(items):
    """The slow tests first, in their files' order: on ``make test``'s workers the longest start while the
    queue is full, so that no worker is left running one alone at the end."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)


TINY = [
    "env.num_envs=8",
    "env.sea.n_dir=8",
    "env.max_steps=50",
    "collector.frames_per_batch=400",
    "collector.init_random_frames=400",
    "checkpoint.every_frames=800",
    "eval.realisations=4",
    "eval.steps=20",
    "logger.progress_bar=false",
    "buffer.capacity=20000",
    "actor.hidden=[32,32]",
    "critic.hidden=[32,32]",
    "compile_update=false",  # compiling costs more than these tiny runs take
    "env.compile_kernel=false",
]
"""Overrides that shrink a training run to seconds: a few links, a coarse sea, small networks, eager."""
ONE_PATH = ["env/spectrum=jonswap", "env/channel=single_path", "env/motion=static", "env/actuator=ideal"]
"""The paper's sea, one refraction path, and ends that stand still and point at once (a TINY run's eager step in
13 ms, not 21): for the tests of what runs training (launchers, sweeps, searches), not of what it learns on the
defaults."""


def paper_physics(**sea) -> dict:
    """The paper's sea (with ``sea``'s keys) and channel, the defaults until they moved to the measured-slope sea and
    the full channel, as env keys: for tests of what was calibrated on them."""
    return {"sea": {"spectrum": "jonswap", **sea}, "channel": {"name": "single_path"}}


F64 = torch.float64


def ends(offset: float, batch: int, depth: float = 10.0, height: float = 10.0, dtype=F64):
    """T and R ``[batch, 3]`` of one geometry (``offset`` ratio, ``depth`` and ``height`` in m)."""
    tx, rx = LinkGeometry(tx_depth=depth, rx_height=height, offset_ratio=offset).positions(dtype)
    return tx.expand(batch, 3).contiguous(), rx.expand(batch, 3).contiguous()


def calm(surface: WaveSurface) -> WaveSurface:
    """The same seas with every amplitude and unresolved slope set to zero."""
    still = surface.clone()
    still.amplitude = torch.zeros_like(surface.amplitude)
    still.unresolved = torch.zeros_like(surface.unresolved)
    return still


def rejection(script: str, overrides) -> str:
    """The one line ``script`` (train.py or evaluate.py) exits with for ``overrides``: its preflight, run
    in-process exactly as its ``__main__`` runs it first (tests/test_cli.py runs two as processes)."""
    from waterair.cli import evaluation, training
    from waterair.cli.preflight import preflight

    config_name, check = {"train.py": ("config", training.check), "evaluate.py": ("evaluate", evaluation.check)}[script]
    with pytest.raises(SystemExit) as stop:
        preflight(config_name, list(overrides), check)
    line = str(stop.value.code)
    assert line.startswith("error: ") and "\n" not in line, line
    return line


def compose_config(name: str, overrides=(), **kwargs):
    """``conf/NAME.yaml`` composed with ``overrides``, as train.py / evaluate.py would see it."""
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        return compose(config_name=name, overrides=list(overrides), **kwargs)


@pytest.fixture(scope="session")
def inductor():
    """torch.compile started in this process. Its first compile pays a one-off start (on an empty compile cache,
    about 9 s on the slower machine with the vector instructions taken from the CPU's flags, as above); a
    test that compiles takes this fixture, so that the start is paid once per worker, in the setup, and the
    test's own time is its graphs'."""
    torch.compile(torch.sin)(torch.zeros(2))


@pytest.fixture
def default_positions():
    """T and R of the default link (10 m deep, 10 m high, 10 % offset) in float64."""
    return LinkGeometry().positions(torch.float64)


def preset_config(observation: str, sensor: str, batch: int, **overrides) -> EnvConfig:
    """The env group with ``env/observation`` and ``env/sensor`` presets, as train.py composes it."""
    cfg = compose_config("config", [f"env/observation={observation}", f"env/sensor={sensor}"])
    values = {**OmegaConf.to_container(cfg.env, resolve=True), "num_envs": batch, "seed": 11, "max_steps": 10**6}
    values["compile_kernel"] = False  # the YAML's auto is decided by the entry points
    return EnvConfig.from_mapping({**values, **overrides})


def machine() -> dict[str, str]:
    """This process's identity, as a recording keeps it: the CPU's vendor and model (from /proc/cpuinfo; the
    model name alone is generic on a virtual machine, so with its family, model and stepping numbers), torch's
    version and commit, the instruction set torch dispatches to and torch's threads (1 under ``make test``'s
    workers, set at the top of this file)."""
    cpu = {}
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.exists():
        for line in cpuinfo.read_text().splitlines():
            key, _, value = line.partition(":")
            if not line.strip():
                break  # the first processor's block describes them all
            cpu[key.strip()] = value.strip()
    numbers = ", ".join(f"{key} {cpu.get(key, '?')}" for key in ("cpu family", "model", "stepping"))
    return {
        "cpu_vendor": cpu.get("vendor_id", platform.machine()),
        "cpu_model": f"{cpu.get('model name', platform.processor())} ({numbers})",
        "torch": f"{torch.__version__} ({torch.version.git_version})",
        "capability": torch.backends.cpu.get_cpu_capability(),
        "threads": str(torch.get_num_threads()),
    }


def reloaded_scores(cfg, metrics: dict, path: Path):
    """The policy at ``path`` (a checkpoint or policy file), reloaded as evaluate.py loads it, scores on the closing
    evaluation's seas of the run with config ``cfg`` what that run scored (``metrics``); returns its actor."""
    from waterair.evaluation.policies import load_policy
    from waterair.evaluation.runner import compare_policies
    from waterair.evaluation.scenarios import Scenario

    config = EnvConfig.from_mapping({**OmegaConf.to_container(cfg.env, resolve=True), "compile_kernel": False})
    actor = load_policy(path).actor(cfg.actor, config.observation_size)
    point = ((cfg.env.sea.wind, cfg.env.geometry.offset_ratio, cfg.env.geometry.offset_azimuth_deg),)
    scenario = Scenario("check", "reload", None, point, cfg.eval.realisations, cfg.eval.steps, cfg.eval.seed)
    scored = compare_policies(config, {"reloaded": actor}, scenario)["reloaded"]
    for key in ("ratio_to_ub", "mean_gain"):
        assert scored[key] == pytest.approx(metrics[f"agent/{key}"], rel=1e-6, abs=1e-12)
    return actor
