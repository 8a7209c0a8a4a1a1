"""Rebuild the summary of a sweep: ``python -m waterair.cli.sweep outputs/sweeps/DATE/TIME``.

Writes ``summary.csv``, ``summary.md`` and ``learning_curves.png`` at the sweep's root from its
jobs' folders, as the end of a multirun does (:mod:`waterair.training.sweep`): for a sweep whose
end never came (the submitting process was killed), or while its jobs still run. Prints where the
summary is; if a job did not finish, exits with status 1 and one line naming it, why, and its log.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from waterair.training.sweep import conclude


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m waterair.cli.sweep", description=__doc__.splitlines()[0])
    parser.add_argument("root", type=Path, help="the sweep's folder (hydra.sweep.dir), e.g. outputs/sweeps/DATE/TIME")
    root = parser.parse_args(argv).root
    if not root.is_dir():
        sys.exit(f"error: {root} is not a directory; give a sweep's folder (outputs/sweeps/DATE/TIME)")
    conclude(root)


if __name__ == "__main__":
    main()
