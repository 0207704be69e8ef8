"""Figures of the gait report as PNG bytes (docs/report.md, *Plots*), after thesis Figs.
5.10–5.14.

Drawn with matplotlib's Agg canvas directly (no pyplot, no display, no global state); each
function returns the PNG file's bytes for :func:`write_png` or the HTML report. Left red, right
green (the gait-lab habit, docs/ecosystem.md; the colours of ``gaitnet vio``'s plot).

- :func:`foot_trajectories_png` — x, y, z of each foot over time (Figs. 5.10, 5.12–5.14):
  frames where the foot was measured drawn solid, frames filled in dashed and
  lighter, the ground truth (when given) as a broad grey line underneath;
- :func:`top_view_png` — the walk seen from above: both feet's paths, the filter's stance-foot
  landmarks and the detected foot contacts (Fig. 5.11's plane);
- :func:`joint_angles_png` — hip, knee and ankle angles over the normalised gait cycle (0 % =
  initial contact, 100 % = the next one of the same foot), mean ± SD band per side over the
  cycles, the mean toe off marked;
- :func:`gait_phases_png` — stance bars per side over time from detected events only (a missed
  event leaves its phase unknown, hatched), double support where both overlap.
"""

from __future__ import annotations

import io
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from numpy.typing import ArrayLike, NDArray

from gaitnet.errors import InputError
from gaitnet.io.atomic import atomic_write_bytes
from gaitnet.pipeline.gait_events import SIDES, FootContact, check_points, check_times
from gaitnet.pipeline.joint_angles import ANGLE_NAMES
from gaitnet.vio.gait import Stance
from gaitnet.vio.report import SIDE_COLOURS

__all__ = [
    "PNG_SIGNATURE",
    "figure_png",
    "foot_trajectories_png",
    "gait_cycles",
    "gait_phases_png",
    "joint_angles_png",
    "new_figure",
    "top_view_png",
    "write_png",
]

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
CYCLE_POINTS = 101
DPI = 100
FloatArray = NDArray[np.float64]


def new_figure(width: float, height: float) -> Figure:
    """A figure of ``width`` × ``height`` inches at :data:`DPI`, drawn without a display."""
    fig = Figure(figsize=(width, height), dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


def figure_png(fig: Figure) -> bytes:
    """``fig`` laid out tightly, as PNG bytes."""
    buffer = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buffer, format="png")
    return buffer.getvalue()


def write_png(path: str | Path, png: bytes) -> None:
    """Write PNG bytes to ``path`` atomically (refuses bytes that are not a PNG)."""
    if not png.startswith(PNG_SIGNATURE):
        raise InputError(f"{path}: the data to write is not a PNG image")
    atomic_write_bytes(path, png)


def _feet(feet: Mapping[str, ArrayLike], n: int, name: str) -> dict[str, FloatArray]:
    if not feet or set(feet) - set(SIDES):
        raise InputError(f"{name}: keys must be among {SIDES}, got {sorted(feet)}")
    return {side: check_points(feet[side], n, f"{name} {side!r}") for side in SIDES if side in feet}


def _masks(measured: Mapping[str, ArrayLike] | None, sides, n: int) -> dict[str, NDArray]:
    out = {}
    for side in sides:
        if measured is None or side not in measured:
            out[side] = np.ones(n, dtype=bool)
            continue
        m = np.asarray(measured[side])
        if m.shape != (n,) or m.dtype != bool:
            raise InputError(
                f"measured {side!r}: expected a bool array of shape ({n},), got {m.dtype} {m.shape}"
            )
        out[side] = m
    return out


def foot_trajectories_png(
    t_s: ArrayLike,
    feet: Mapping[str, ArrayLike],
    measured: Mapping[str, ArrayLike] | None = None,
    truth: Mapping[str, ArrayLike] | None = None,
) -> bytes:
    """x, y, z of each foot [m] over time [s] (module docstring). ``feet`` and ``truth``: side
    → (n, 3) at the times ``t_s``; ``measured``: side → (n,) bool, True where the foot was
    measured (missing: all measured)."""
    t = check_times(t_s)
    pts = _feet(feet, t.size, "feet")
    masks = _masks(measured, pts, t.size)
    true = _feet(truth, t.size, "truth") if truth is not None else {}
    fig = new_figure(10, 6.5)
    axes = fig.subplots(3, len(pts), sharex=True, squeeze=False)
    for col, (side, p) in enumerate(pts.items()):
        colour = SIDE_COLOURS[side]
        m = masks[side]
        # a filled run is drawn including the measured frames on either side, so lines join
        filled = ~m | np.convolve(~m, np.ones(3), mode="same").astype(bool)
        for row, axis in enumerate("xyz"):
            ax = axes[row, col]
            if side in true:
                ax.plot(t, true[side][:, row], color="k", lw=2.6, alpha=0.3, label="ground truth")
            ax.plot(t, np.where(m, p[:, row], np.nan), color=colour, lw=1.6, label="measured")
            ax.plot(
                t,
                np.where(filled, p[:, row], np.nan),
                color=colour,
                lw=1.2,
                ls="--",
                alpha=0.55,
                label="filled in",
            )
            ax.set_ylabel(f"{axis} [m]")
            ax.grid(True, lw=0.3)
        axes[0, col].set_title(f"{side} foot")
        axes[-1, col].set_xlabel("time [s]")
        axes[0, col].legend(loc="best", fontsize=7)
    return figure_png(fig)


def top_view_png(
    feet: Mapping[str, ArrayLike],
    stances: Sequence[Stance] = (),
    contacts: Sequence[FootContact] = (),
    camera_xy: ArrayLike | None = None,
) -> bytes:
    """Top view [m]: each foot's path, the filter's stance-foot landmarks (squares), the
    detected contacts' positions (circles) and, when given, the camera path (n, 2)."""
    first = np.asarray(next(iter(feet.values()), np.zeros((0, 3))))
    pts = _feet(feet, first.shape[0] if first.ndim == 2 else -1, "feet")
    fig = new_figure(10, 3.8)
    ax = fig.subplots()
    if camera_xy is not None:
        cam = np.asarray(camera_xy, dtype=float)
        if cam.ndim != 2 or cam.shape[1] != 2 or not np.all(np.isfinite(cam)):
            raise InputError(f"camera_xy: expected a finite (n, 2) array, got shape {cam.shape}")
        ax.plot(cam[:, 0], cam[:, 1], color="0.3", lw=1.0, label="camera")
    for side, p in pts.items():
        colour = SIDE_COLOURS[side]
        ax.plot(p[:, 0], p[:, 1], color=colour, lw=0.8, alpha=0.6, label=f"{side} foot path")
        own = [s.xy for s in stances if s.side == side]
        if own:
            xy = np.array(own)
            ax.scatter(
                xy[:, 0],
                xy[:, 1],
                marker="s",
                s=30,
                color=colour,
                zorder=3,
                label=f"{side} stance landmarks",
            )
        mine = [c.position[:2] for c in contacts if c.side == side]
        if mine:
            xy = np.array(mine)
            ax.scatter(
                xy[:, 0],
                xy[:, 1],
                marker="o",
                s=60,
                facecolors="none",
                edgecolors=colour,
                zorder=4,
                label=f"{side} contacts",
            )
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m] (stretched)")
    ax.grid(True, lw=0.3)
    ax.legend(loc="best", fontsize=7, ncol=2)
    ax.set_title("walk seen from above")
    return figure_png(fig)


def gait_cycles(contacts: Sequence[FootContact], side: str) -> list[tuple[float, float, float]]:
    """``(IC, TO, next IC)`` [s] of each complete cycle of ``side``: consecutive contacts
    with both initial contacts and a toe off between them, at most 1.5 × the median cycle
    long (longer ones bridge a pause)."""
    own = sorted((c for c in contacts if c.side == side), key=lambda c: c.still_start_s)
    cycles = [
        (a.initial_contact_s, a.toe_off_s, b.initial_contact_s)
        for a, b in zip(own[:-1], own[1:], strict=True)
        if a.initial_contact_s is not None
        and b.initial_contact_s is not None
        and a.toe_off_s is not None
        and a.initial_contact_s < a.toe_off_s < b.initial_contact_s
    ]
    if not cycles:
        return []
    median = float(np.median([c[2] - c[0] for c in cycles]))
    return [c for c in cycles if c[2] - c[0] <= 1.5 * median]


Cycle = tuple[float, float, float]  # initial contact, toe off, next initial contact [s]


def joint_angles_png(
    t_s: ArrayLike,
    angles_deg: ArrayLike,
    contacts: Sequence[FootContact],
    cycles: Mapping[str, Sequence[Cycle]] | None = None,
) -> bytes:
    """Hip, knee and ankle angles [deg] over the normalised gait cycle (module docstring):
    ``angles_deg`` (n, 6) at ``t_s``, columns
    :data:`gaitnet.pipeline.joint_angles.ANGLE_NAMES` (hip L, R, knee L, R, ankle L, R), over
    ``cycles`` per side when given (``gaitnet infer``: the cycles of the report's table,
    :func:`gaitnet.pipeline.gait_parameters.table_cycles`, so that the legend's n is the
    table's), else :func:`gait_cycles` of ``contacts``."""
    t = check_times(t_s)
    a = np.asarray(angles_deg, dtype=float)
    if a.shape != (t.size, len(ANGLE_NAMES)):
        raise InputError(f"angles_deg: expected shape ({t.size}, 6), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InputError("angles_deg: not all finite")
    fig = new_figure(10, 3.6)
    axes = fig.subplots(1, 3)
    phase = np.linspace(0.0, 100.0, CYCLE_POINTS)
    for s, side in enumerate(SIDES):
        own = list(cycles.get(side, ())) if cycles is not None else gait_cycles(contacts, side)
        colour = SIDE_COLOURS[side]
        for j, ax in enumerate(axes):
            if not own:
                continue
            curves = np.array(
                [np.interp(ic + phase / 100 * (nxt - ic), t, a[:, 2 * j + s]) for ic, _, nxt in own]
            )
            mean, sd = curves.mean(axis=0), curves.std(axis=0)
            ax.fill_between(phase, mean - sd, mean + sd, color=colour, alpha=0.2, lw=0)
            ax.plot(phase, mean, color=colour, lw=1.5, label=f"{side} (n = {len(own)})")
            to = np.mean([100 * (to - ic) / (nxt - ic) for ic, to, nxt in own])
            ax.axvline(to, color=colour, lw=0.8, ls="--")
    for ax, title in zip(axes, ("hip flexion", "knee flexion", "ankle dorsiflexion"), strict=True):
        ax.set_title(f"{title} [deg]")
        ax.set_xlabel("gait cycle [%]")
        ax.set_xlim(0, 100)
        ax.grid(True, lw=0.3)
        ax.axhline(0.0, color="0.5", lw=0.5)
    handles = axes[0].get_legend_handles_labels()[0]
    if handles:
        axes[0].legend(loc="best", fontsize=7)
    else:
        for ax in axes:
            ax.text(50, 0, "no complete gait cycle", ha="center", va="center")
    return figure_png(fig)


#: A stance whose still interval reaches this close [s] to the plotted range's start or end
#: began before it or ended after it (the subject stood): its missing event is outside.
EDGE_S = 0.05

Span = tuple[float, float]


def stance_spans(
    contacts: Sequence[FootContact], side: str, t_start_s: float, t_end_s: float
) -> tuple[list[Span], list[Span]]:
    """``side``'s stances as ``(start, end)`` [s] from detected events only, and the spans
    whose phase is unknown. A stance runs from its initial contact to its toe off. Without an
    initial contact it starts at the range's start when its still interval does (the
    subject stood), else at the start of its still interval, with the time back to the
    previous stance's end (or the range's start) unknown; likewise without a toe off."""
    own = sorted((c for c in contacts if c.side == side), key=lambda c: c.still_start_s)
    known: list[Span] = []
    unknown: list[Span] = []
    for i, c in enumerate(own):
        start, end = c.initial_contact_s, c.toe_off_s
        if start is None:
            start = t_start_s if c.still_start_s <= t_start_s + EDGE_S else c.still_start_s
            before = _end(own[i - 1]) if i > 0 else t_start_s
            if start > t_start_s and start > before:
                unknown.append((before, start))
        if end is None:
            end = t_end_s if c.still_end_s >= t_end_s - EDGE_S else c.still_end_s
            after = _start(own[i + 1]) if i + 1 < len(own) else t_end_s
            if end < t_end_s and after > end:
                unknown.append((end, after))
        if end > start:
            known.append((start, end))
    return known, unknown


def _start(c: FootContact) -> float:
    return c.still_start_s if c.initial_contact_s is None else c.initial_contact_s


def _end(c: FootContact) -> float:
    return c.still_end_s if c.toe_off_s is None else c.toe_off_s


def gait_phases_png(contacts: Sequence[FootContact], t_start_s: float, t_end_s: float) -> bytes:
    """Stance of each foot (bars) from ``t_start_s`` to ``t_end_s`` [s], from detected events
    only (:func:`stance_spans`): where an event was not detected the phase is drawn as
    unknown (hatched), never as stance; double support where both feet's stances overlap."""
    if not (np.isfinite(t_start_s) and np.isfinite(t_end_s) and t_end_s > t_start_s):
        raise InputError(f"gait phases: time range {t_start_s}..{t_end_s} s is not increasing")
    fig = new_figure(10, 2.4)
    ax = fig.subplots()
    bars = {}
    any_unknown = False
    for row, side in enumerate(SIDES):
        known, unknown = stance_spans(contacts, side, t_start_s, t_end_s)
        bars[side] = [(a, b - a) for a, b in known]
        ax.broken_barh(bars[side], (1 - row + 0.1, 0.8), color=SIDE_COLOURS[side])
        if unknown:
            any_unknown = True
            ax.broken_barh(
                [(a, b - a) for a, b in unknown],
                (1 - row + 0.1, 0.8),
                facecolor="none",
                edgecolor="0.6",
                hatch="///",
                lw=0.5,
            )
    both = [
        (max(a, c), min(a + w, c + v) - max(a, c))
        for a, w in bars["left"]
        for c, v in bars["right"]
        if min(a + w, c + v) > max(a, c)
    ]
    ax.broken_barh(both, (-0.4, 0.3), color="0.35")
    ax.set_yticks([1.5, 0.5, -0.25], ["left stance", "right stance", "double support"])
    ax.set_ylim(-0.5, 2.0)
    ax.set_xlim(t_start_s, t_end_s)
    ax.set_xlabel("time [s]")
    ax.grid(True, axis="x", lw=0.3)
    if any_unknown:
        ax.set_title("hatched: an event was not detected, the phase is unknown", fontsize=8)
    return figure_png(fig)
