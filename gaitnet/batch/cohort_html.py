"""``cohort.html``: the cohort table and one strip plot per parameter across sessions, in one
self-contained file (inline style, figures as base64 PNG, no script, no link; the style and the
figure markup of the gait report, :mod:`gaitnet.pipeline.html_report`).

Each strip plot has a row per side; each point is one session's mean over its steady strides,
hollow where the session's result is unreliable (``reliable`` false). Points of one row are
spread a little up and down, the same way on every run, so that equal values stay visible.
"""

from __future__ import annotations

import html
from collections.abc import Sequence

from gaitnet.batch.cohort import COHORT_COLUMNS, PARAMETERS, SIDES, CohortRow
from gaitnet.batch.task import SessionOutcome
from gaitnet.pipeline.html_report import STYLE, figures_html
from gaitnet.pipeline.plots import figure_png, new_figure
from gaitnet.vio.report import SIDE_COLOURS

__all__ = ["render_cohort", "strip_plot_png"]

GOLDEN = 0.6180339887498949  # spreads the points of a row evenly, whatever their number


def strip_plot_png(rows: Sequence[CohortRow], column: str) -> bytes:
    """The strip plot of one :data:`~gaitnet.batch.cohort.PARAMETERS` column (module
    docstring)."""
    _, unit = PARAMETERS[column]
    fig = new_figure(7.0, 1.9)
    ax = fig.add_subplot(1, 1, 1)
    for i, side in enumerate(SIDES):
        own = [r for r in rows if r.side == side and r.values[column] is not None]
        x = [r.values[column] for r in own]
        y = [i + 0.5 * ((k * GOLDEN) % 1.0 - 0.5) for k in range(len(own))]
        colour = SIDE_COLOURS[side]
        faces = [colour if r.reliable else "none" for r in own]
        ax.scatter(x, y, s=28, facecolors=faces, edgecolors=colour, linewidths=1.2)
    ax.set_yticks(range(len(SIDES)), SIDES)
    ax.set_ylim(-0.6, len(SIDES) - 0.4)
    ax.set_xlabel(f"{column} [{unit}]")
    ax.grid(axis="x", alpha=0.3)
    return figure_png(fig)


def _cell(text: str, column: str) -> str:
    align = ' class="name"' if column in ("session", "path", "side") else ""
    return f"<td{align}>{html.escape(text)}</td>"


def _table(rows: Sequence[CohortRow]) -> str:
    head = "".join(
        f"<th{' class=name' if c in ('session', 'path', 'side') else ''}>{html.escape(c)}</th>"
        for c in COHORT_COLUMNS
    )
    body = "".join(
        "<tr>"
        + "".join(_cell(t, c) for t, c in zip(r.cells(), COHORT_COLUMNS, strict=True))
        + "</tr>"
        for r in rows
    )
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _failures(failed: Sequence[SessionOutcome]) -> str:
    if not failed:
        return ""
    items = "".join(
        f"<li><b>{html.escape(o.name)}</b> ({html.escape(o.session)}): "
        f"{html.escape(o.error or '')}</li>"
        for o in failed
    )
    return f"<section><h2>Failed in the last run ({len(failed)})</h2><ul>{items}</ul></section>"


def render_cohort(
    rows: Sequence[CohortRow], failed: Sequence[SessionOutcome], title: str = "Gait cohort"
) -> str:
    """``cohort.html``'s text: the table of ``rows`` (``cohort.csv``'s), the sessions that
    failed, and a strip plot per parameter with a value."""
    sessions = len({r.session for r in rows})
    figures = [
        (f"{column} [{PARAMETERS[column][1]}]: one point per session and side "
         "(hollow: unreliable result)", strip_plot_png(rows, column))
        for column in PARAMETERS
        if any(r.values[column] is not None for r in rows)
    ]  # fmt: skip
    note = (
        "Each value is the session's mean over the side's steady strides, as in its own "
        "summary.json and report.html; an empty cell: no steady stride of that side has it."
    )
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{html.escape(title)}</title><style>{STYLE}</style></head><body>"
        f"<header><h1>{html.escape(title)}</h1><p>{sessions} session(s), "
        f"{len(failed)} failed in the last run</p></header>"
        f'<section><h2>Sessions</h2><p class="note">{html.escape(note)}</p>{_table(rows)}'
        f"</section>{_failures(failed)}"
        f"<section><h2>Parameters across sessions</h2>{figures_html(figures)}</section>"
        "</body></html>\n"
    )
