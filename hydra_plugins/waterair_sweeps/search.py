"""The search of ``train.py -m hydra/sweeper=optuna``: Optuna's ask-and-tell loop over Hydra's launcher.

Each batch of ``n_jobs`` trials is asked of the study, launched as jobs with their sampled values,
and told back: a job that returned a finite number is a complete trial with that value (``train.py``
returns the greedy policy's ratio to the upper bound in the closing evaluation, which the search
maximises), any other job a failed trial (``TrialState.FAIL``), and the search goes on. The sweep
then ends in :class:`waterair.training.sweep.SweepSummary`, as a grid does, with the best trial's
parameters and value in :data:`RESULTS_FILE` beside the summary.

The search space is Hydra's override syntax, on the command line or in ``hydra.sweeper.params``:
``choice(a,b)`` (and ``glob``) is a categorical parameter over the values as they are written;
``range(start,stop,step)`` a stepped one over exactly the values a grid would run (``stop``
excluded); ``interval(low,high)`` a uniform float, ``tag(log,interval(low,high))`` a log-uniform
one. Every other override is passed to every trial as it is. Samplers: ``hydra/sweeper/sampler=tpe``
(the default), ``gp`` and ``random``. Every key is in docs/training.md.
"""

# No "from __future__ import annotations": Hydra runs this module before it is in sys.modules, where
# dataclasses look string annotations up.
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from importlib.util import find_spec
from pathlib import Path
from typing import Any

from hydra.core.config_store import ConfigStore
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.override_parser.types import IntervalSweep, Override, RangeSweep
from hydra.core.plugins import Plugins
from hydra.core.utils import JobReturn, JobStatus
from hydra.plugins.sweeper import Sweeper
from hydra.types import HydraContext, TaskFunction
from hydra.utils import instantiate
from omegaconf import MISSING, DictConfig, OmegaConf

from waterair.core.validation import check_choice, check_int, check_range

log = logging.getLogger(__name__)

RESULTS_FILE = "optimization_results.yaml"
"""The best trial at the sweep root: ``{name: optuna, best_params, best_value}``."""
DIRECTIONS = ("maximize", "minimize")

Dimension = tuple[str, Any, str]
"""One override of a search: its key, its Optuna distribution (None when it is not swept), its text."""


class SearchSweeper(Sweeper):
    """Optuna's ask-and-tell loop, a batch of ``n_jobs`` trials at a time (module docstring).

    The keys are checked here, once, with messages that name them; train.py's preflight builds this
    sweeper and its search space before anything is written.
    """

    def __init__(
        self,
        sampler: DictConfig,
        direction: str,
        storage: str | None,
        study_name: str | None,
        n_trials: int,
        n_jobs: int,
        max_failure_rate: float,
        params: DictConfig | None,
    ) -> None:
        self.sampler = sampler
        self.direction = check_choice("hydra.sweeper.direction", direction, DIRECTIONS)
        self.storage, self.study_name = storage, study_name
        self.n_trials = check_int("hydra.sweeper.n_trials", n_trials, 1)
        self.n_jobs = check_int("hydra.sweeper.n_jobs", n_jobs, 1)
        self.max_failure_rate = check_range("hydra.sweeper.max_failure_rate", max_failure_rate, 0.0, 1.0)
        self.params = [f"{key!s}={value}" for key, value in (params or {}).items()]
        self.config: DictConfig | None = None
        self.hydra_context: HydraContext | None = None
        self.launcher = None

    def setup(self, *, hydra_context: HydraContext, task_function: TaskFunction, config: DictConfig) -> None:
        self.config, self.hydra_context = config, hydra_context
        self.launcher = Plugins.instance().instantiate_launcher(
            config=config, hydra_context=hydra_context, task_function=task_function
        )

    def sweep(self, arguments: list[str]) -> None:
        import optuna
        from optuna.trial import TrialState

        assert self.config is not None and self.launcher is not None and self.hydra_context is not None
        optuna.logging.set_verbosity(optuna.logging.WARNING)  # its INFO lines say nothing the summary does not
        space = self.space(arguments, self.hydra_context.config_loader)
        distributions = {key: distribution for key, distribution, _ in space if distribution is not None}
        study = optuna.create_study(
            storage=self.storage,
            sampler=instantiate(self.sampler),
            study_name=self.study_name,
            direction=optuna.study.StudyDirection[self.direction.upper()],
            load_if_exists=True,
        )
        root = Path(self.config.hydra.sweep.dir)
        root.mkdir(parents=True, exist_ok=True)
        OmegaConf.save(self.config, root / "multirun.yaml")
        log.info(f"Study {study.study_name} ({self.storage or 'in memory'}), {type(study.sampler).__name__}")
        launched = 0
        while launched < self.n_trials:
            trials = [study.ask(distributions) for _ in range(min(self.n_jobs, self.n_trials - launched))]
            batch = [trial_overrides(space, trial.params) for trial in trials]
            jobs = self.launcher.launch(batch, initial_job_idx=launched)
            failed = 0
            for number, (trial, overrides, job) in enumerate(zip(trials, batch, jobs, strict=True), start=launched):
                trial.set_user_attr("sweep_dir", str(root))
                trial.set_user_attr("job", number)
                trial.set_user_attr("overrides", list(overrides))
                value = objective(job)
                study.tell(trial, value, state=TrialState.FAIL if value is None else TrialState.COMPLETE)
                failed += value is None
            launched += len(trials)
            if failed > self.max_failure_rate * len(trials) and launched < self.n_trials:
                log.error(
                    f"The search stops after {launched} of {self.n_trials} trials: {failed} of the last "
                    f"{len(trials)} failed (hydra.sweeper.max_failure_rate={self.max_failure_rate:g})"
                )
                break
        write_best(study, root / RESULTS_FILE)

    def space(self, arguments: Sequence[str], config_loader: Any = None) -> list[Dimension]:
        """The search space of ``hydra.sweeper.params`` and then ``arguments`` (a ``glob`` needs ``config_loader``)."""
        parser = OverridesParser.create(config_loader=config_loader)
        return search_space(parser.parse_overrides([*self.params, *arguments]))


def search_space(overrides: Sequence[Override]) -> list[Dimension]:
    """Every override as a :data:`Dimension`, in the order given (a later override of a key replaces an earlier)."""
    dimensions = {override.get_key_element(): override for override in overrides}
    return [
        (key, distribution(override) if override.is_sweep_override() else None, _text(override))
        for key, override in dimensions.items()
    ]


def distribution(override: Override) -> Any:
    """The Optuna distribution of one swept override (module docstring); a ``ValueError`` naming it if Optuna
    refuses it (a log scale from 0, an empty range)."""
    from optuna.distributions import CategoricalDistribution, FloatDistribution, IntDistribution

    sweep = override.value()
    try:
        if isinstance(sweep, IntervalSweep):
            assert sweep.start is not None and sweep.end is not None  # the parser sets both
            if "log" in sweep.tags and sweep.start <= 0:
                raise ValueError(f"a log scale needs low > 0, not {sweep.start:g}")
            return FloatDistribution(sweep.start, sweep.end, log="log" in sweep.tags)
        if isinstance(sweep, RangeSweep):  # shuffled or not: the order of a grid, not a sampler's
            values = [value for value in override.sweep_iterator() if isinstance(value, int | float)]
            if not values:
                raise ValueError("the range holds no value")
            low, high, step = min(values), max(values), abs(sweep.step)
            if all(isinstance(value, int) for value in values) and isinstance(step, int):
                return IntDistribution(int(low), int(high), step=step)
            return FloatDistribution(float(low), float(high), step=float(step))
        return CategoricalDistribution(list(override.sweep_string_iterator()))
    except ValueError as error:
        raise ValueError(f"{override.input_line}: {error}") from None


def trial_overrides(space: list[Dimension], params: dict[str, Any]) -> list[str]:
    """A trial's overrides: each swept key at the trial's value, every other override as it was written."""
    return [f"{key}={params[key]}" if distribution is not None else text for key, distribution, text in space]


def objective(job: JobReturn) -> float | None:
    """What a finished job returned, as a finite number; None for a job that failed or returned none."""
    if job.status != JobStatus.COMPLETED:
        return None
    try:
        value = float(job.return_value)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


def write_best(study: Any, path: Path) -> None:
    """Log the study's best trial and write it to ``path``; nothing when no trial finished (the summary says why)."""
    from optuna.trial import TrialState

    if not study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,)):
        return
    best = study.best_trial
    log.info(f"Best parameters: {best.params}")
    log.info(f"Best value: {best.value}")
    OmegaConf.save(OmegaConf.create({"name": "optuna", "best_params": best.params, "best_value": best.value}), path)


def _text(override: Override) -> str:
    return override.input_line or f"{override.get_key_element()}={override.get_value_element_as_str()}"


@dataclass
class TPESamplerConf:
    """hydra/sweeper/sampler=tpe (the default): Optuna's tree-structured Parzen estimator."""

    _target_: str = "optuna.samplers.TPESampler"
    seed: int | None = None
    n_startup_trials: int = 10


@dataclass
class GPSamplerConf:
    """hydra/sweeper/sampler=gp: Optuna's Gaussian-process sampler (it needs torch and scipy)."""

    _target_: str = "optuna.samplers.GPSampler"
    seed: int | None = None
    n_startup_trials: int = 10


@dataclass
class RandomSamplerConf:
    """hydra/sweeper/sampler=random: values drawn independently of earlier trials."""

    _target_: str = "optuna.samplers.RandomSampler"
    seed: int | None = None


@dataclass
class SearchSweeperConf:
    """hydra/sweeper=optuna for train.py: maximise the returned ratio; a failed job is a failed trial."""

    _target_: str = "hydra_plugins.waterair_sweeps.search.SearchSweeper"
    _recursive_: bool = False  # the sampler is built when the search starts, not when the sweeper is
    defaults: list[Any] = field(default_factory=lambda: [{"sampler": "tpe"}])
    sampler: Any = MISSING
    direction: str = "maximize"
    storage: str | None = None
    study_name: str | None = None
    n_trials: int = 20
    n_jobs: int = 2
    max_failure_rate: float = 1.0
    params: dict[str, str] | None = None


SAMPLERS = {"tpe": TPESamplerConf, "gp": GPSamplerConf, "random": RandomSamplerConf}


def register() -> None:
    """Make hydra/sweeper=optuna this search, with its samplers (called by :mod:`.options`; not without optuna)."""
    if find_spec("optuna") is None:
        return
    store = ConfigStore.instance()
    store.store(group="hydra/sweeper", name="optuna", node=SearchSweeperConf, provider="waterair")
    for name, node in SAMPLERS.items():
        store.store(group="hydra/sweeper/sampler", name=name, node=node, provider="waterair")
