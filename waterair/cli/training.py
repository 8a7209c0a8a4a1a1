"""What ``train.py`` does around :func:`waterair.training.train`: checks, resume, the closing summary."""

from __future__ import annotations

import json
import logging
import math
import time
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from waterair.cli.console import quiet_dependencies
from waterair.core.files import atomic_write_text
from waterair.envs.controllers import CONTROLLERS
from waterair.training import train, validate
from waterair.training.resume import plan_resume
from waterair.training.sweep import ERROR_FILE, EVENTS, JOB_LOG, swept_at

log = logging.getLogger("waterair.train")


def check(cfg: DictConfig, overrides: list[str]) -> None:
    """Everything a training command line must satisfy before anything is written (one-line errors)."""
    if cfg.resume:
        plan_resume(cfg, overrides)
    else:
        validate(cfg)


def run(
    cfg: DictConfig,
    overrides: list[str],
    output_dir: str | Path,
    in_sweep: bool = False,
    events_dir: str | Path | None = None,
) -> float:
    """Train (or resume) and log the closing summary; return the greedy policy's ratio to the upper bound.

    The ratio is what a search (``hydra/sweeper=optuna``) maximises. A job of a sweep (``in_sweep``)
    that raises logs its traceback into its own log and leaves its error, one line, in
    :data:`~waterair.training.sweep.ERROR_FILE` for the sweep's summary; the sweep goes on. ``events_dir``
    (:func:`sweep_events_dir` for a sweep's job) is where the TensorBoard events go when ``logger.dir`` is null.
    """
    quiet_dependencies()
    if events_dir is not None and not cfg.resume and cfg.logger.get("dir") is None:
        cfg = OmegaConf.merge(cfg, {"logger": {"dir": str(events_dir)}})  # config.yaml keeps it: resume finds it
    try:
        return _run(cfg, overrides, Path(output_dir))
    except Exception as error:
        if not in_sweep:
            raise
        message = " ".join(f"{type(error).__name__}: {error}".split())
        log.error(f"The job failed: {message} (traceback in {Path(output_dir) / JOB_LOG})")
        logging.getLogger("waterair.traceback").exception("The job failed")
        atomic_write_text(Path(output_dir) / ERROR_FILE, message + "\n")
        raise


def sweep_events_dir(hydra_config: DictConfig) -> Path:
    """Where a sweep's job writes its TensorBoard events: ``SWEEP/tensorboard/NAME``, NAME its values of the swept
    keys (``agent.gamma=0.9,env.wind=12,reward.a=5``, sorted; ``job-N`` where nothing is swept), so that
    ``tensorboard --logdir SWEEP/tensorboard`` names each run by what it varied."""
    root = Path(hydra_config.sweep.dir).absolute()
    swept = set(swept_at(root))
    own = sorted(o for o in hydra_config.overrides.task if o.lstrip("+~").partition("=")[0] in swept)
    return root / EVENTS / (",".join(own) or f"job-{hydra_config.job.num}")


def _run(cfg: DictConfig, overrides: list[str], run_dir: Path) -> float:
    clock = time.perf_counter()
    if cfg.resume:
        plan = plan_resume(cfg, overrides)
        if plan.finished:
            log.info(
                f"Run {plan.run_dir} is complete: {plan.frames_done:,} of {plan.config.total_frames:,} frames. "
                f"Nothing to do; total_frames=N with N > {plan.config.total_frames} extends it."
            )
            return _saved_metrics(plan.run_dir).get("agent/ratio_to_ub", math.nan)
        cfg, run_dir = plan.config, plan.run_dir
    metrics = train(cfg, run_dir, progress=log.info, overrides=overrides)
    log.info(summary(cfg, run_dir, metrics, time.perf_counter() - clock))
    return metrics["agent/ratio_to_ub"]


def summary(cfg: DictConfig, run_dir: Path, metrics: dict[str, float], seconds: float) -> str:
    """The closing lines: where the run is, what it did, how the greedy policy scored, what to run next."""
    minutes, rest = divmod(round(seconds), 60)
    ratio = {label: metrics[f"{label}/ratio_to_ub"] for label in ("agent", "flat_snell", "straight_facing")}
    classical = next((name for name in CONTROLLERS if f"{name}/ratio_to_ub" in metrics), None)
    beside = f"{classical} {metrics[f'{classical}/ratio_to_ub']:.3f}, " if classical else ""
    return "\n".join(
        [
            "",
            f"Run directory: {run_dir}",
            f"Frames: {metrics['frames']:,} ({metrics['updates']:,} updates, {metrics['episodes']:,} episodes) "
            f"in {minutes} min {rest} s",
            f"Greedy policy at U10 = {cfg.env.sea.wind:g} m/s, offset {cfg.env.geometry.offset_ratio:.0%} "
            f"({cfg.eval.realisations} seas × {cfg.eval.steps} steps): {ratio['agent']:.3f} of the upper bound "
            f"({beside}flat-sea Snell {ratio['flat_snell']:.3f}, straight facing {ratio['straight_facing']:.3f})",
            f"Its link ({_link_name(cfg)}): outage {metrics['agent/outage']:.2%} of the steps, mean BER "
            f"{metrics['agent/ber']:.2g}, mean rate at the FEC limit {metrics['agent/rate'] / 1e6:.3g} Mbit/s "
            f"(the upper bound's outage {metrics['upper_bound/outage']:.2%})",
            f"TensorBoard: .venv/bin/tensorboard --logdir {cfg.logger.get('dir') or run_dir / 'tensorboard'}",
            f"Full evaluation: .venv/bin/python evaluate.py run={run_dir}",
        ]
    )


def _link_name(cfg: DictConfig) -> str:
    """E.g. ``10 Mbit/s OOK, 50 mW``: the operating point the outage is counted at."""
    link = cfg.get("link") or {}
    return f"{link.get('bit_rate', 1e7) / 1e6:g} Mbit/s OOK, {link.get('power_w', 0.05) * 1e3:g} mW"


def _saved_metrics(run_dir: Path) -> dict:
    path = run_dir / "final_metrics.json"
    return json.loads(path.read_text()) if path.exists() else {}
