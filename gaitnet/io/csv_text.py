"""CSV text of a table: a header and rows, ``\\n`` line ends (the result folders' tables)."""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence

__all__ = ["csv_text"]


def csv_text(columns: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """The CSV text of ``rows`` under the header ``columns`` (quoted where a cell needs it)."""
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(columns)
    writer.writerows(rows)
    return text.getvalue()
