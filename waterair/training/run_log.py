"""Scalars of a training run: TensorBoard event files plus a CSV with the same rows.

Tags are namespaced (``train/``, ``loss/``, ``time/``, ``eval/``); the step is the number of
environment frames, so a resumed run continues the same curves. On resume, TensorBoard events
and CSV rows written after the checkpoint are discarded (``purge_step``), so nothing is counted
twice. The run's hyperparameters go into the same events (TensorBoard's hparams table), so that the table's
row of a run is the run whose curves TensorBoard shows, under its name.
"""

from __future__ import annotations

import csv
from pathlib import Path

from torch.utils.tensorboard import SummaryWriter
from torch.utils.tensorboard.summary import hparams

from waterair.core.files import atomic_write_csv


class RunLog:
    """TensorBoard + CSV logger: the CSV in ``run_dir``, the events in ``events_dir`` (``run_dir/tensorboard``)."""

    def __init__(self, run_dir: Path, resume_frames: int | None = None, events_dir: Path | None = None):
        self.run_dir = Path(run_dir)
        self.csv_path = self.run_dir / "metrics.csv"
        self.events_dir = Path(events_dir) if events_dir is not None else self.run_dir / "tensorboard"
        # purge_step drops events at or after it; the checkpoint's own step is kept.
        purge = None if resume_frames is None else resume_frames + 1
        self.writer = SummaryWriter(str(self.events_dir), purge_step=purge)
        self._rows: list[dict] = []
        if resume_frames is not None and self.csv_path.exists():
            with self.csv_path.open(newline="") as handle:
                self._rows = [row for row in csv.DictReader(handle) if int(float(row["frames"])) <= resume_frames]

    def text(self, tag: str, text: str) -> None:
        self.writer.add_text(tag, text)

    def scalars(self, frames: int, values: dict[str, float], *, csv_row: bool = True) -> None:
        """Log ``values`` (tag → number) at step ``frames`` to TensorBoard and, with ``csv_row``, the CSV."""
        for tag, value in values.items():
            self.writer.add_scalar(tag, value, frames)
        if csv_row:
            self._rows.append({"frames": frames, **values})
            self._write_csv()

    def hparams(self, frames: int, params: dict, metric_tags: list[str]) -> None:
        """The hparams table's row of this run: ``params`` (name → number, string or bool) beside the scalars
        ``metric_tags`` that this run logs (into these events, not a run of their own as ``add_hparams`` writes)."""
        for summary in hparams(params, dict.fromkeys(metric_tags, 0.0)):  # the plugin reads the metrics' scalars
            self.writer.file_writer.add_summary(summary, frames)

    def close(self) -> None:
        self.writer.flush()
        self.writer.close()

    def _write_csv(self) -> None:
        columns = ["frames"] + sorted({key for row in self._rows for key in row} - {"frames"})
        atomic_write_csv(self.csv_path, columns, self._rows)
