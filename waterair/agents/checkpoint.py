"""The policy file format: what a trained actor is saved as, and how it is loaded back.

A policy file is a ``torch.save`` dictionary with ``format`` (:data:`POLICY_FORMAT`), ``actor``
(the actor network's ``state_dict``), ``observation_size`` and ``frames`` (training frames, or
None). A training checkpoint is a policy file with more entries (the learner's state), so
everything that evaluates a policy reads both the same way: :func:`read_policy`. Files are
written atomically and read with ``torch.load(weights_only=True)``.
"""

from __future__ import annotations

import zipfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import torch
from tensordict.nn import TensorDictModule, TensorDictModuleBase

from waterair.agents.networks import RowBlocks, actor_for
from waterair.agents.recurrent import is_recurrent
from waterair.core.files import atomic_write
from waterair.envs.config import EnvConfig

POLICY_FORMAT = "waterair-policy/1"
"""The format tag this version writes and reads."""
ZIP_MAGIC = b"PK\x03\x04"
"""The first bytes of every file ``torch.save`` writes (a zip archive)."""
ACTION_SIZE = 4
"""Actions are (tx_vx, tx_vy, rx_vx, rx_vy) (docs/environment.md)."""


class CheckpointError(ValueError):
    """A file that cannot be used as a policy; the message is one line naming the file and the reason."""


@dataclass
class PolicyFile:
    """What :func:`read_policy` found in a policy file or training checkpoint."""

    path: Path
    actor_state: dict[str, torch.Tensor]
    observation_size: int
    frames: int | None

    def actor(
        self, network: Mapping, observation_size: int | None = None, observation: EnvConfig | None = None
    ) -> TensorDictModuleBase:
        """The actor network of the ``actor`` group's option ``network`` with these weights, in eval mode on the CPU.

        ``observation_size`` (the environment's) must equal the one the policy was trained with; ``observation``, the
        training environment's config, says its layout (which ``actor=per_end`` splits).
        Raises :class:`CheckpointError` naming both sizes or both network shapes on a mismatch. An MLP acts on its
        rows in blocks (:class:`RowBlocks`); a recurrent actor is stepped through
        :class:`waterair.agents.recurrent.StepMemory`, which does the same.
        """
        if observation_size is not None and observation_size != self.observation_size:
            raise CheckpointError(
                f"checkpoint {self.path}: trained with observations of size {self.observation_size}, but the "
                f"environment gives {observation_size}; use the observation settings it was trained with"
            )
        module = actor_for(network, self.observation_size, ACTION_SIZE, observation)
        expected = {k: tuple(v.shape) for k, v in module.state_dict().items()}
        found = {k: tuple(v.shape) for k, v in self.actor_state.items()}
        if expected != found:
            raise CheckpointError(
                f"checkpoint {self.path}: its actor has layers {_shapes(found)}, but "
                f"actor={network.get('name', 'mlp')} with hidden = {list(network['hidden'])} builds {_shapes(expected)}"
            )
        module.load_state_dict(self.actor_state)
        if is_recurrent(module):
            return module.eval()
        # in blocks of rows: a policy's actions on a link do not depend on the links beside it (RowBlocks)
        return TensorDictModule(RowBlocks(module.module), in_keys=module.in_keys, out_keys=module.out_keys).eval()


def policy_state(actor: TensorDictModule, observation_size: int, frames: int | None) -> dict:
    """The policy entries of a file: format tag, actor weights (on the CPU), sizes and frames."""
    return {
        "format": POLICY_FORMAT,
        "actor": {k: v.detach().cpu().clone() for k, v in actor.state_dict().items()},
        "observation_size": int(observation_size),
        "frames": frames,
    }


def save_policy(path: str | Path, state: Mapping) -> Path:
    """Write ``state`` (:func:`policy_state`, plus any extra entries) to ``path`` atomically."""
    if state.get("format") != POLICY_FORMAT:
        raise ValueError(f"save_policy: state['format'] must be {POLICY_FORMAT!r}")
    return atomic_write(path, lambda handle: torch.save(dict(state), handle))


def read_policy(path: str | Path) -> PolicyFile:
    """Read a policy file or training checkpoint with ``weights_only=True``, checking its format.

    Raises :class:`CheckpointError` with one line saying what the file is: missing, not a torch
    file, truncated, another project's, or another format version.
    """
    path = Path(path)
    state = load_state(path)
    tag = state.get("format")
    if tag != POLICY_FORMAT:
        if isinstance(tag, str) and tag.startswith("waterair-policy/"):
            raise CheckpointError(f"checkpoint {path} has format {tag!r}; this waterair reads {POLICY_FORMAT!r}")
        raise CheckpointError(
            f"checkpoint {path} is a torch file but not a waterair policy (no {POLICY_FORMAT!r} tag; "
            f"found keys {sorted(map(str, state))[:6]})"
        )
    actor, size = state.get("actor"), state.get("observation_size")
    if not isinstance(actor, dict) or not actor or not isinstance(size, int):
        raise CheckpointError(f"checkpoint {path} has the {POLICY_FORMAT!r} tag but no actor weights or size")
    frames = state.get("frames")
    return PolicyFile(path, actor, size, int(frames) if frames is not None else None)


def load_state(path: Path) -> dict:
    """``torch.load(path, weights_only=True)`` of a dictionary, with one-line errors for bad files."""
    if not path.is_file():
        raise CheckpointError(f"checkpoint {path} does not exist")
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception:  # torch raises many types for damaged or foreign bytes; classify by the header
        with path.open("rb") as handle:
            zipped = handle.read(4) == ZIP_MAGIC
        if zipped and zipfile.is_zipfile(path):  # whole, but holding objects that weights_only refuses
            raise CheckpointError(
                f"checkpoint {path} is a torch file holding objects, not only tensors (a saved model?); "
                f"waterair reads state dictionaries with weights_only=True"
            ) from None
        if zipped:
            raise CheckpointError(f"checkpoint {path} is truncated or damaged ({path.stat().st_size} bytes)") from None
        raise CheckpointError(
            f"checkpoint {path} is not a torch file (torch.save writes a zip archive; this is none)"
        ) from None
    if not isinstance(state, dict):
        raise CheckpointError(f"checkpoint {path} holds a {type(state).__name__}, not a waterair policy")
    return state


def _shapes(shapes: dict[str, tuple]) -> str:
    """The weight matrices' shapes, in order, e.g. ``[256x8, 256x256, 4x256]``."""
    return "[" + ", ".join("x".join(map(str, s)) for k, s in shapes.items() if k.endswith("weight")) + "]"
