"""The gait report of a simulated session built from its ground truth (docs/report.md).

Runs the report stage alone on a ``gaitnet simulate`` session folder: the shoe-top markers of
``groundtruth/feet.csv`` as the foot trajectories (frames where ``marker_pixels.csv`` marks the
marker visible count as measured, the others as filled), the 7 joints of ``joints.npz`` and the
sagittal joint angles of its local rotations (``gaitnet.pipeline.joint_angles``), gait
events, stances and strides from the trajectories (no filter), the parameters, the figures and
the HTML report. Prints the per-side summary next to the same parameters computed from the
simulator's true events.

    python benchmarks/report_demo.py SESSION --out /tmp/report_demo
"""

from __future__ import annotations

import csv
import time
from pathlib import Path

import numpy as np
from bench_gait_events import true_contacts

from gaitnet import __version__
from gaitnet.pipeline.gait_events import SIDES, detect_events, stances_from_contacts
from gaitnet.pipeline.gait_parameters import (
    PARAMETERS,
    stride_parameters,
    stride_table_csv,
    summarise,
)
from gaitnet.pipeline.html_report import write_report
from gaitnet.pipeline.joint_angles import sagittal_angles_deg
from gaitnet.pipeline.plots import (
    foot_trajectories_png,
    gait_phases_png,
    joint_angles_png,
    top_view_png,
    write_png,
)
from gaitnet.training.scripts import ScriptParser
from gaitnet.vio.gait import strides_from_stances


def main() -> None:
    ap = ScriptParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("session", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    gt = args.session / "groundtruth"
    rows = list(csv.DictReader((gt / "feet.csv").open()))
    t_ns = np.array([int(r["t_ns"]) for r in rows])
    t = t_ns * 1e-9
    feet = {
        s: np.array([[float(r[f"marker_{s}_{a}"]) for a in "xyz"] for r in rows]) for s in SIDES
    }
    visible = {
        (int(r["t_ns"]), r["side"]): r["visible"] == "1"
        for r in csv.DictReader((gt / "marker_pixels.csv").open())
    }
    measured = {s: np.array([visible.get((k, s), False) for k in t_ns]) for s in SIDES}
    truth_joints = np.load(gt / "joints.npz")
    joints = truth_joints["positions"][:, :7]
    angles = sagittal_angles_deg(truth_joints["joint_aa"][:, :6])

    start = time.perf_counter()
    contacts = detect_events(t, feet, joints)
    stances = stances_from_contacts(contacts)
    strides = strides_from_stances(stances)
    params = stride_parameters(strides, contacts)
    summary = summarise(params)
    figures = [
        (
            "Foot trajectories (solid: marker visible, dashed: hidden)",
            foot_trajectories_png(t, feet, measured),
        ),
        ("Walk seen from above", top_view_png(feet, stances, contacts)),
        ("Joint angles over the gait cycle (mean ± SD)", joint_angles_png(t, angles, contacts)),
        ("Stance and swing over time", gait_phases_png(contacts, float(t[0]), float(t[-1]))),
    ]
    args.out.mkdir(parents=True, exist_ok=True)
    names = ("foot_trajectories", "top_view", "joint_angles", "gait_phases")
    for name, (_, png) in zip(names, figures, strict=True):
        write_png(args.out / f"{name}.png", png)
    (args.out / "gait_strides.csv").write_text(stride_table_csv(params))
    facts = {
        "subject": f"simulated subject of {args.session.name}",
        "session": str(args.session.name),
        "duration [s]": float(t[-1] - t[0]),
        "frames": len(t),
        "device": "simulated RealSense D455 (ground-truth feet and joints)",
        "software": f"gaitnet {__version__}",
    }
    report = write_report(args.out / "report.html", facts, summary, params, figures)
    elapsed = time.perf_counter() - start
    print(f"report: {report} ({report.stat().st_size / 1e3:.0f} kB, {elapsed:.2f} s)")

    events = list(csv.DictReader((gt / "events.csv").open()))
    truth = summarise(stride_parameters(strides, true_contacts(events)))
    print(f"{'parameter':32s} {'left':>16s} {'right':>16s} {'true events L':>14s} {'R':>7s} SI %")
    for key, label, unit in PARAMETERS:
        cells = []
        for side in SIDES:
            s = summary[side].get(key)
            cells.append(f"{s['mean']:.3f}±{s['sd']:.3f}" if s else "-")
        true = [truth[side].get(key) for side in SIDES]
        true_txt = [f"{x['mean']:.3f}" if x else "-" for x in true]
        si = summary["symmetry_index_pct"].get(key)
        print(
            f"{label + ' [' + unit + ']':32s} {cells[0]:>16s} {cells[1]:>16s} "
            f"{true_txt[0]:>14s} {true_txt[1]:>7s} {'' if si is None else f'{si:+.1f}'}"
        )


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
