"""The sweepers of ``train.py -m``: every job runs to its end, so a failed job costs only itself.

- ``grid`` (train.py's default, ``conf/hydra/sweeper/grid.yaml``): Hydra's basic sweeper, every
  combination of the swept values, except that a failed job does not stop the sweep;
- ``optuna`` (:mod:`.search`): a search that maximises what ``train.py`` returns, the greedy
  policy's ratio to the upper bound in the closing evaluation; a failed job is a failed trial.

Either way the sweep ends in :class:`waterair.training.sweep.SweepSummary`, which writes the
summary of the jobs that finished, names those that did not, and sets the exit status.
"""

import logging
import time
from pathlib import Path
from typing import Any

from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
from hydra.core.override_parser.overrides_parser import OverridesParser
from omegaconf import OmegaConf

log = logging.getLogger(__name__)


class GridSweeper(BasicSweeper):
    """Hydra's basic sweeper without its stop at the first failed job (it raises that job's exception).

    The jobs' results are returned as they are; the summary reads the outcome from the jobs' folders.
    """

    def sweep(self, arguments: list[str]) -> Any:
        assert self.config is not None and self.launcher is not None and self.hydra_context is not None
        parser = OverridesParser.create(config_loader=self.hydra_context.config_loader)
        overrides = parser.parse_overrides([*self._parse_config(), *arguments])
        self.overrides = self.split_arguments(overrides, self.max_batch_size)
        sweep_dir = Path(self.config.hydra.sweep.dir)
        sweep_dir.mkdir(parents=True, exist_ok=True)
        OmegaConf.save(self.config, sweep_dir / "multirun.yaml")
        returns, initial_job_idx = [], 0
        while not self.is_done():
            batch = self.get_job_batch()
            started = time.perf_counter()
            self.validate_batch_is_legal(batch)
            log.debug(f"Validated {len(batch)} jobs in {time.perf_counter() - started:.2f} s")
            returns.append(self.launcher.launch(batch, initial_job_idx=initial_job_idx))
            initial_job_idx += len(batch)
        return returns
