"""Whether an evaluation's groups compile their step: ``env.compile_kernel: auto`` in evaluate.py and in
training's closing evaluation.

Each group of an evaluation (the policies that share an environment interface, :mod:`waterair.evaluation.runner`) steps
through graphs of its own. Measured on the 2-core VM (docs/benchmarks.md, "Evaluation"): compiling a group's graphs into
an empty cache takes 100–220 s, loading them back about 12 s, and then a frame costs about 0.17 ms against 0.52 ms eager
at an evaluation's widths. Every process that runs the group's batches pays its compile, so a group compiles when each
process's share of its frames repays that, from its channel's ``evaluation_frames``: with its graphs in torch's compile
cache (a name noted when it compiled them, :func:`waterair.core.compiling.graphs_kept`) from the warm count, else from
the cold one. Any graph in the cache (training's, another group's) does not make a group's warm.
"""

from __future__ import annotations

from waterair.core.compiling import compiling_pays, graphs_kept, graphs_name, keep_graphs
from waterair.envs.config import EnvConfig

VARYING = (
    "num_envs",
    "seed",
    "compile_kernel",
    "replicas",
    "wind_values",
    "offset_values",
    "offset_azimuth_values",
    "wind_direction_values",
    "wind_range",
    "offset_range",
    "divergence_values",
    "divergence_range",
)
"""What an evaluation's groups set for each rollout and its graphs take as inputs: left out of a group's name."""


def group_name(config: EnvConfig) -> str:
    """The name of the graphs an evaluation group on ``config`` compiles: its interface, sensing and physics,
    without what varies within its graphs (:data:`VARYING`, and the links' divergence, which S5 sweeps)."""
    values = {key: value for key, value in config.to_mapping().items() if key not in VARYING}
    values["optics"] = {key: value for key, value in values["optics"].items() if key != "divergence"}
    return graphs_name("evaluation", values)


def compiled_group(config: EnvConfig, frames: int, processes: int = 1) -> tuple[EnvConfig, str]:
    """``config`` compiled or eager for a group that steps ``frames`` link-steps in all, shared between
    ``processes`` processes, and a clause saying why. Each process that runs a batch of the group compiles its graphs
    (side by side, neither finds the other's in the cache), so the compile must repay itself on each process's
    share of the frames."""
    cache = "warm" if graphs_kept(group_name(config)) else "cold"
    pays, reason = compiling_pays(-(-frames // processes), cache, config.channel, "evaluation")
    return config.replace(compile_kernel=pays), reason.replace("compile cache", "compile cache for this group")


def note_compiled(config: EnvConfig) -> None:
    """Note, once a group on ``config`` has run compiled, that its graphs are in torch's compile cache."""
    if config.compile_kernel:
        keep_graphs(group_name(config))
