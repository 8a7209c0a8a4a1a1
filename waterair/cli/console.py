"""The dependencies' messages that a user of train.py or evaluate.py can do nothing about, silenced by name.

Each entry names the message and where it comes from; every other warning still shows. The entry
points call :func:`quiet_dependencies` in the process that does the work (a sweep's job included).
"""

from __future__ import annotations

import logging
import warnings

WARNINGS = (
    # tensordict reads torch._dynamo.config.inline_inbuilt_nn_modules while torch.compile traces; torch 2.13
    # deprecated the option (it is always on), so every compiled run would print this.
    {"message": r"torch\._dynamo\.config\.inline_inbuilt_nn_modules is deprecated", "category": FutureWarning},
)
"""``warnings.filterwarnings`` arguments of the warnings to ignore."""
LOG_RECORDS = {
    # Dynamo says once per process that it traces through TorchRL's profiler annotations without recording them.
    "torch._dynamo.variables.ctx_manager": "Profiler record function",
}
"""Logger name → the start of the records of that logger to drop."""


class DropRecords(logging.Filter):
    """Drops the records whose message starts with ``prefix``."""

    def __init__(self, prefix: str):
        super().__init__()
        self.prefix = prefix

    def filter(self, record: logging.LogRecord) -> bool:
        return not record.getMessage().startswith(self.prefix)


def quiet_dependencies() -> None:
    """Silence :data:`WARNINGS` and :data:`LOG_RECORDS` in this process (calling it again changes nothing)."""
    for arguments in WARNINGS:
        warnings.filterwarnings("ignore", **arguments)
    for name, prefix in LOG_RECORDS.items():
        logger = logging.getLogger(name)
        if not any(isinstance(f, DropRecords) and f.prefix == prefix for f in logger.filters):
            logger.addFilter(DropRecords(prefix))
