"""One self-contained HTML gait report a clinician can open offline (docs/report.md).

The file needs nothing else: the style is inline CSS, the figures are PNGs inline as base64
``data:`` URIs, there are no scripts and no links to anything outside it. Sections: a header
with the session facts; the time-distance table per side (mean ± SD over the steady strides,
the Robinson symmetry index, a typical healthy adult's range for orientation); the per-stride
table (collapsed, ``<details>``); the figures; how the values were measured and their limits.
Every string from outside (facts, figure titles, notes) is escaped (:func:`html.escape`).
"""

from __future__ import annotations

import base64
import html
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

from gaitnet.errors import InputError
from gaitnet.io.atomic import atomic_write_text
from gaitnet.pipeline.gait_parameters import EVENT_COLUMNS, PARAMETERS, StrideParameters
from gaitnet.pipeline.plots import PNG_SIGNATURE

__all__ = ["STYLE", "TYPICAL_ADULT", "figures_html", "render_report", "write_report"]

#: Typical healthy adult values at a self-selected speed (J. Perry, J. M. Burnfield, *Gait
#: Analysis: Normal and Pathological Function*, 2nd ed., SLACK 2010; M. W. Whittle, *Gait
#: Analysis: An Introduction*, 4th ed., 2007; docs/references.md); stride and step times follow
#: from the cadence.
TYPICAL_ADULT = {
    "stride_length_m": "1.2–1.5",
    "stride_time_s": "1.0–1.2",
    "step_length_m": "0.6–0.75",
    "step_width_m": "0.05–0.15",
    "step_time_s": "0.5–0.6",
    "cadence_spm": "100–120",
    "walking_speed_mps": "1.2–1.4",
    "stance_pct": "≈ 60",
    "swing_pct": "≈ 40",
    "initial_double_support_pct": "≈ 10",
    "terminal_double_support_pct": "≈ 10",
    "double_support_pct": "≈ 20",
}

STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; margin: 1.5em auto;
       max-width: 1050px; color: #222; line-height: 1.4; padding: 0 1em; }
h1 { margin-bottom: 0.2em; } h2 { border-bottom: 1px solid #ccc; padding-bottom: 0.2em; }
table { border-collapse: collapse; margin: 0.5em 0 1em; font-size: 0.92em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }
th { background: #f2f2f2; } td.name, th.name { text-align: left; }
table.facts td, table.facts th { text-align: left; }
.left { color: #b71c1c; } .right { color: #1b7a1b; } .note { color: #555; font-size: 0.9em; }
tr.unsteady td { color: #888; }
figure { margin: 1em 0; } figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.9em; color: #444; }
details summary { cursor: pointer; font-weight: 600; margin: 0.5em 0; }
"""

MEASURED = (
    "Distances (stride and step length, step width) are the distances between the stance-foot "
    "landmarks of the visual-inertial filter: the floor positions where each foot rested. "
    "Stride time, cadence (steps per minute) and walking speed come from the times the filter "
    "first saw each foot resting. Initial contact and toe off come from the foot trajectories: "
    "initial contact at the least vertical velocity of the foot point before it comes to rest "
    "(O'Connor et al. 2007), toe off at the foot's most posterior position relative to the "
    "pelvis (Zeni et al. 2008). Stance, swing and double support are shares of the gait cycle "
    "between two initial contacts of the same foot. Means and SDs are over the steady strides "
    "(not the first step from standing, the last step or strides across a pause). The symmetry "
    "index is Robinson's, SI = 2 (R − L) / (R + L) × 100 %: 0 is symmetric, positive means "
    "the right side's value is larger."
)
LIMITS = (
    "Limits: events from a single foot point are tens of milliseconds off force-plate events "
    "(initial contact typically 20 ms early in steady walking, up to 140 ms early for the first "
    "and last step; toe off 10–20 ms late, measured on simulated walks); during swing the foot "
    "is often not seen by the camera and its trajectory is filled in from where it rested "
    "before and after, with a typical walking swing in between, and the motion predictor "
    "(dashed in the trajectory plots). The values are not a diagnosis; compare them with the "
    "patient's history and a clinical examination."
)


def _text(value: object) -> str:
    """A fact's value as escaped text (floats with 4 significant digits)."""
    if isinstance(value, float):
        return html.escape(f"{value:.4g}" if math.isfinite(value) else "–")
    if isinstance(value, (list, tuple)):
        return html.escape(", ".join(str(v) for v in value))
    return html.escape(str(value))


def _number(value: float | None, unit: str) -> str:
    if value is None or not math.isfinite(value):
        return "–"
    digits = 1 if unit in ("steps/min", "% of cycle") else 3 if unit in ("m", "s") else 2
    return f"{value:.{digits}f}"


def _facts(facts: Mapping[str, object]) -> str:
    rows = "".join(
        f"<tr><th>{html.escape(str(k))}</th><td>{_text(v)}</td></tr>" for k, v in facts.items()
    )
    return f'<table class="facts">{rows}</table>'


def _side_cell(stats: Mapping[str, object], key: str, unit: str) -> str:
    s = stats.get(key)
    if not isinstance(s, Mapping):
        return "<td>–</td>"
    return (
        f"<td>{_number(s['mean'], unit)} ± {_number(s['sd'], unit)} "
        f'<span class="note">({int(s["n"])})</span></td>'
    )


def _summary_table(summary: Mapping[str, object]) -> str:
    left, right = summary.get("left", {}), summary.get("right", {})
    symmetry = summary.get("symmetry_index_pct", {})
    head = (
        '<tr><th class="name">parameter</th><th>unit</th><th class="left">left</th>'
        '<th class="right">right</th><th>symmetry index SI [%]</th>'
        "<th>typical adult</th></tr>"
    )
    body = []
    for key, label, unit in PARAMETERS:
        si = symmetry.get(key) if isinstance(symmetry, Mapping) else None
        body.append(
            f'<tr><td class="name">{html.escape(label)}</td><td>{html.escape(unit)}</td>'
            f"{_side_cell(left, key, unit)}{_side_cell(right, key, unit)}"
            f"<td>{'–' if si is None else f'{si:+.1f}'}</td>"
            f"<td>{html.escape(TYPICAL_ADULT.get(key, ''))}</td></tr>"
        )
    n_left, n_right = left.get("n_strides", 0), right.get("n_strides", 0)
    inferred = int(left.get("n_inferred", 0)) + int(right.get("n_inferred", 0))
    caption = (
        f"mean ± SD (number of strides) over {int(n_left)} left and {int(n_right)} right "
        "steady strides"
        + (f", {inferred} with a stance laid from the step rhythm (not seen)" if inferred else "")
        + "; SI = 2 (R − L) / (R + L) × 100 (Robinson et al. 1987)"
    )
    return (
        f'<table class="summary"><caption class="note">{html.escape(caption)}</caption>'
        f"<thead>{head}</thead><tbody>{''.join(body)}</tbody></table>"
    )


def _stride_table(rows: Sequence[StrideParameters]) -> str:
    events = [(k, k.removesuffix("_s").replace("_", " "), "s") for k in EVENT_COLUMNS]
    columns = [*events, *PARAMETERS]
    head = "<tr><th>side</th><th>stride</th><th>steady</th><th>seen</th>" + "".join(
        f"<th>{html.escape(label)} [{html.escape(unit)}]</th>" for _, label, unit in columns
    )
    body = []
    for r in rows:
        cells = "".join(f"<td>{_number(r.values.get(k), unit)}</td>" for k, _, unit in columns)
        side = html.escape(r.side)
        body.append(
            f'<tr class="{"steady" if r.steady else "unsteady"}">'
            f'<td class="{side}">{side}</td><td>{r.index}</td>'
            f"<td>{'yes' if r.steady else 'no'}</td>"
            f"<td>{'no: laid from the step rhythm' if r.inferred else 'yes'}</td>{cells}</tr>"
        )
    return (
        f"<details><summary>Per-stride table ({len(rows)} strides)</summary>"
        f'<table class="strides"><thead>{head}</tr></thead>'
        f"<tbody>{''.join(body)}</tbody></table></details>"
    )


def figures_html(figures: Sequence[tuple[str, bytes]]) -> str:
    """``(title, PNG bytes)`` pairs as HTML figures with the PNG inlined (base64)."""
    out = []
    for title, png in figures:
        if not isinstance(png, (bytes, bytearray)) or not bytes(png).startswith(PNG_SIGNATURE):
            raise InputError(f"report figure {title!r}: not PNG bytes")
        data = base64.b64encode(bytes(png)).decode("ascii")
        t = html.escape(str(title))
        out.append(
            f'<figure><img src="data:image/png;base64,{data}" alt="{t}">'
            f"<figcaption>{t}</figcaption></figure>"
        )
    return "".join(out)


def render_report(
    facts: Mapping[str, object],
    summary: Mapping[str, object],
    rows: Sequence[StrideParameters],
    figures: Sequence[tuple[str, bytes]] = (),
    notes: Sequence[str] = (),
    title: str = "Gait report",
) -> str:
    """The report as HTML text (module docstring). ``facts``: session facts in display order
    (subject, date, duration, frames, device, software version, models, ...); ``summary``:
    :func:`gaitnet.pipeline.gait_parameters.summarise`; ``rows``: the per-stride parameters;
    ``figures``: (title, PNG bytes); ``notes``: extra lines for the measurement section."""
    extra = "".join(f"<p>{html.escape(str(n))}</p>" for n in notes)
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{html.escape(title)}</title><style>{STYLE}</style></head><body>"
        f"<header><h1>{html.escape(title)}</h1>{_facts(facts)}</header>"
        f"<section><h2>Time-distance parameters per side</h2>{_summary_table(summary)}"
        f"{_stride_table(rows)}</section>"
        f"<section><h2>Figures</h2>{figures_html(figures)}</section>"
        f"<section><h2>How these were measured</h2><p>{html.escape(MEASURED)}</p>"
        f'<p class="note">{html.escape(LIMITS)}</p>{extra}</section>'
        "</body></html>\n"
    )


def write_report(
    path: str | Path,
    facts: Mapping[str, object],
    summary: Mapping[str, object],
    rows: Sequence[StrideParameters],
    figures: Sequence[tuple[str, bytes]] = (),
    notes: Sequence[str] = (),
    title: str = "Gait report",
) -> Path:
    """Write :func:`render_report`'s HTML to ``path`` atomically; returns the path."""
    text = render_report(facts, summary, rows, figures, notes, title)
    atomic_write_text(path, text)
    return Path(path)
