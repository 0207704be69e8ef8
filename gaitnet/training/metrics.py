"""Per-epoch metrics: ``metrics.csv`` (append-safe on resume) and TensorBoard scalars.

One row per epoch with a fixed set of columns (named like the TensorBoard tags, e.g.
``train/loss``, ``val/mpjpe_m``). On resume from epoch ``e`` rows of epochs ``>= e`` (written
by an interrupted run after its last checkpoint) are dropped first, so the file never holds an
epoch twice; the rewrite is atomic. TensorBoard events go to ``<run_dir>/tb`` with
``purge_step`` set on resume for the same reason. Only rank 0 should create a logger.

TensorBoard is an optional extra (``pip install -e '.[train]'``): it is imported only when
asked for, and when it is not installed one log message says so and ``metrics.csv`` is still
written. A metric row is only written when every value is finite
(:func:`require_finite` raises :class:`NonFiniteMetricError` first), so neither ``metrics.csv``
nor a checkpoint ever records a NaN.
"""

from __future__ import annotations

import csv
import io
import logging
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

from gaitnet.errors import InputError
from gaitnet.io.atomic import atomic_write_text

__all__ = ["MetricsLogger", "NonFiniteMetricError", "read_metrics", "require_finite"]

logger = logging.getLogger(__name__)


class NonFiniteMetricError(InputError):
    """Training diverged (a loss or metric is NaN/inf); nothing of that epoch is recorded."""


def require_finite(values: Mapping[str, float], where: str) -> None:
    """Raise :class:`NonFiniteMetricError` naming the first non-finite value of ``values``."""
    for key, value in values.items():
        if not math.isfinite(float(value)):
            raise NonFiniteMetricError(
                f"{where}: {key} is {float(value)}; training diverged (try a lower optim.lr or "
                "optim.grad_clip_norm, and check the data); no checkpoint was written for it"
            )


def read_metrics(path: str | Path) -> list[dict[str, str]]:
    """Rows of a ``metrics.csv`` as dicts of strings (empty list when the file is missing)."""
    path = Path(path)
    if not path.is_file():
        return []
    with path.open(newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


class MetricsLogger:
    """Write one CSV row and TensorBoard scalars per epoch.

    ``fields`` are the metric columns (besides ``epoch``); a value missing from a row is left
    empty. ``start_epoch > 0`` means resume: earlier rows are kept, later ones dropped.
    ``tensorboard=False`` skips the event files.
    """

    def __init__(
        self,
        run_dir: str | Path,
        fields: Sequence[str],
        *,
        start_epoch: int = 0,
        tensorboard: bool = True,
    ) -> None:
        self.run_dir = Path(run_dir)
        self.run_dir.mkdir(parents=True, exist_ok=True)
        self.path = self.run_dir / "metrics.csv"
        self.fields = ["epoch", *fields]
        kept = [r for r in read_metrics(self.path) if _epoch(r) < start_epoch]
        if start_epoch == 0 or not self.path.is_file() or kept != read_metrics(self.path):
            self._rewrite(kept)
        self._writer = None
        if tensorboard:
            try:
                from torch.utils.tensorboard import SummaryWriter
            except ImportError:
                logger.warning(
                    "tensorboard is not installed: metrics go to %s only "
                    "(pip install -e '.[train]' for TensorBoard scalars, or set "
                    "train.tensorboard=false)",
                    self.path,
                )
            else:
                self._writer = SummaryWriter(
                    log_dir=str(self.run_dir / "tb"),
                    purge_step=start_epoch if start_epoch > 0 else None,
                )

    def _rewrite(self, rows: list[dict[str, str]]) -> None:
        buffer = io.StringIO()
        writer = csv.DictWriter(buffer, fieldnames=self.fields, extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow(row)
        atomic_write_text(self.path, buffer.getvalue())

    def log(self, epoch: int, values: Mapping[str, float]) -> None:
        """Append the row of ``epoch`` and write each value as a TensorBoard scalar.

        Every value must be finite (:func:`require_finite`).
        """
        unknown = sorted(set(values) - set(self.fields))
        if unknown:
            raise KeyError(f"metrics {unknown} are not columns of {self.path} ({self.fields})")
        require_finite(values, f"epoch {epoch}")
        row = {"epoch": str(int(epoch))}
        for key, value in values.items():
            row[key] = f"{float(value):.8g}"
        with self.path.open("a", newline="", encoding="utf-8") as handle:
            csv.DictWriter(handle, fieldnames=self.fields).writerow(row)
            handle.flush()
        if self._writer is not None:
            for key, value in values.items():
                self._writer.add_scalar(key, float(value), int(epoch))
            self._writer.flush()

    def close(self) -> None:
        """Close the TensorBoard writer."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None


def _epoch(row: Mapping[str, str]) -> int:
    try:
        return int(row.get("epoch", ""))
    except ValueError:
        return 1 << 62
