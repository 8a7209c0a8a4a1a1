"""The sweepers of ``train.py -m``: every job runs to its end, so a failed job costs only itself.

- ``grid`` (train.py's default, ``conf/hydra/sweeper/grid.yaml``): Hydra's basic sweeper, every
  combination of the swept values, except that a failed job does not stop the sweep;
- ``optuna`` (hydra-optuna-sweeper): a search that maximises what ``train.py`` returns, the greedy
  policy's ratio to the upper bound in the closing evaluation; a failed job is a failed trial.

Either way the sweep ends in :class:`waterair.training.sweep.SweepSummary`, which writes the
summary of the jobs that finished, names those that did not, and sets the exit status.
"""

# No "from __future__ import annotations": Hydra runs this module before it is in sys.modules, where
# dataclasses look string annotations up.
import logging
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
from hydra.core.config_store import ConfigStore
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


try:
    from hydra_plugins.hydra_optuna_sweeper.config import OptunaSweeperConf
    from hydra_plugins.hydra_optuna_sweeper.optuna_sweeper import OptunaSweeper
except ImportError:  # hydra-optuna-sweeper not installed: hydra/sweeper=optuna is refused by the preflight
    OptunaSweeper = None


if OptunaSweeper is not None:

    class SearchSweeper(OptunaSweeper):
        """Optuna's sweeper, quiet (its INFO lines say nothing the summary does not), and ending normally
        when no trial finished, so that the summary says why."""

        def __init__(self, *args: Any, **kwargs: Any) -> None:
            import optuna

            optuna.logging.set_verbosity(optuna.logging.WARNING)
            super().__init__(*args, **kwargs)

        def sweep(self, arguments: list[str]) -> None:
            try:
                super().sweep(arguments)
            except ValueError as error:  # study.best_trial with no completed trial
                if "No trials are completed yet" not in str(error):
                    raise

    @dataclass
    class SearchSweeperConf(OptunaSweeperConf):
        """hydra/sweeper=optuna for train.py: maximise the returned ratio; a failed job is a failed trial."""

        _target_: str = "hydra_plugins.waterair_sweeps.sweepers.SearchSweeper"
        direction: Any = "maximize"
        max_failure_rate: float = 1.0


def register() -> None:
    """Make hydra/sweeper=optuna the search sweeper above (called by :mod:`.options`)."""
    if OptunaSweeper is not None:
        ConfigStore.instance().store(group="hydra/sweeper", name="optuna", node=SearchSweeperConf, provider="waterair")
