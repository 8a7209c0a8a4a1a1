"""Device choice: ``auto`` picks CUDA when present, else the CPU."""

from __future__ import annotations

import torch

from waterair.core.validation import check_choice

DEVICES = ("cpu", "cuda", "auto")


def resolve_device(name: str, key: str = "device") -> torch.device:
    """``auto`` → CUDA when available, else CPU; ``cpu``/``cuda`` as given (``cuda`` must exist).

    Raises ``ValueError`` naming ``key`` (the config key) for an unknown name or a missing GPU.
    """
    check_choice(key, name, DEVICES)
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise ValueError(f"{key} = 'cuda' is not available on this machine (no CUDA device); use auto or cpu")
    return torch.device(name)
