"""Whether a run compiles its environment step and its update: ``env.compile_kernel`` and ``compile_update``.

Each is true, false or ``auto`` (:mod:`waterair.core.compiling` says when compiling pays). A recurrent actor's
update stays eager on ``auto``: compiled, its recurrent module breaks the graph and the update is no faster (PPO,
``actor=gru``, 1,600-frame batches on one thread: 230-330 frames/s either way, the compiles 60 s more). So does
``actor=per_end``'s with PPO or SAC, and ``true`` is refused for it (:func:`waterair.training.config.validate`):
TorchRL's ``MultiAgentMLP`` keeps its weights in a ``TensorDictParams`` that the loss swaps for its own at each call,
and the walk over the modules that builds the policy's distribution hashes it by that identity, so the compiled
update recompiles at every step until its limit. DDPG's and TD3's build none: theirs compile (a few dozen graphs).
"""

from __future__ import annotations

from omegaconf import DictConfig, OmegaConf

from waterair.agents.per_end import PER_END
from waterair.agents.recurrent import CELLS
from waterair.core.compiling import CHOICES, cache_state, compiling_pays
from waterair.core.validation import check_choice
from waterair.physics.channel import channel
from waterair.training.algorithms import ALGORITHMS

__all__ = ["CHOICES", "cache_state", "compile_plan"]


def compile_plan(cfg: DictConfig, frames_to_go: int, cache: str | None = None) -> tuple[DictConfig, str]:
    """``cfg`` with ``env.compile_kernel`` and ``compile_update`` decided (true or false), and a line saying why.

    ``cache`` is ``warm`` or ``cold`` (default: :func:`cache_state`); it is read only if a key is ``auto``.
    """
    settings = {"env.compile_kernel": cfg.env.compile_kernel, "compile_update": cfg.compile_update}
    for key, value in settings.items():
        check_choice(key, str(value).lower(), CHOICES)
    automatic = [key for key, value in settings.items() if str(value).lower() == "auto"]
    decided = {key: str(value).lower() == "true" for key, value in settings.items()}
    reason = "as configured"
    if automatic:
        pays, reason = compiling_pays(
            frames_to_go, cache, channel(**OmegaConf.to_container(cfg.env.channel, resolve=True))
        )
        decided.update({key: pays for key in automatic})
        if "compile_update" in automatic and decided["compile_update"] and (why := _eager_update(cfg)):
            decided["compile_update"] = False
            reason += f"; {why}"
    plan = OmegaConf.merge(
        cfg, {"env": {"compile_kernel": decided["env.compile_kernel"]}, "compile_update": decided["compile_update"]}
    )
    parts = [f"{'compiled' if decided[key] else 'eager'} {name}" for key, name in
             (("env.compile_kernel", "environment step"), ("compile_update", "update"))]  # fmt: skip
    return plan, f"{', '.join(parts)} ({reason})"


def recompiles_every_call(cfg: DictConfig) -> bool:
    """Whether ``cfg``'s update, compiled, would recompile at every call: a per-end actor under a loss that builds a
    distribution around it (this module's docstring says why)."""
    return cfg.actor.name == PER_END and ALGORITHMS[cfg.agent.name].gaussian_policy


def _eager_update(cfg: DictConfig) -> str | None:
    """Why the update of ``cfg``'s actor and agent stays eager on ``auto``, or None where it compiles."""
    actor = cfg.actor.name
    if actor in CELLS:
        return f"a recurrent actor's update ({actor}) eager, which is no slower"
    if recompiles_every_call(cfg):
        return f"actor=per_end's update with agent={cfg.agent.name} eager (TorchRL's MultiAgentMLP would recompile it)"
    return None
