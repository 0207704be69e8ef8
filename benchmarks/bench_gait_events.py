"""Timing errors of the gait-event rule (gaitnet.pipeline.gait_events) on simulated sessions.

For every session folder under ROOT (``gaitnet simulate`` output, docs/groundtruth.md) the
events are detected from the ground-truth foot points (``feet.csv`` shoe-top marker or sole
centre, or the ankle joint of ``joints.npz``), optionally with white noise added, and matched
to ``events.csv`` (``heel_strike_s``, ``toe_off_s``): each true event is paired with the
nearest detected event of its side and kind within 0.25 s; the rest count as missed (true) or
extra (detected). Printed per input: matched counts, misses, extras and the signed median,
median |e|, 95th percentile |e| and maximum |e| of detected − true, in ms. Sessions whose name
starts with one of ``--select`` are the ones the rule was chosen on; the others are reported
separately as held out.

    python benchmarks/bench_gait_events.py /tmp/sessions --noise-mm 0 5
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from gaitnet.pipeline.gait_events import SIDES, FootContact, detect_events, stances_from_contacts
from gaitnet.pipeline.gait_parameters import stride_parameters
from gaitnet.training.scripts import ScriptParser
from gaitnet.vio.gait import strides_from_stances

SEVEN = [0, 1, 2, 3, 4, 5, 6]  # joints.npz positions: [0, 1, 2, 4, 5, 7, 8, 10, 11] → first 7
TOLERANCE_S = 0.25


def load(session: Path) -> dict:
    gt = session / "groundtruth"
    rows = list(csv.DictReader((gt / "feet.csv").open()))
    t = np.array([int(r["t_ns"]) for r in rows]) * 1e-9
    points = {}
    for kind in ("marker", "sole"):
        points[kind] = {
            s: np.array([[float(r[f"{kind}_{s}_{a}"]) for a in "xyz"] for r in rows]) for s in SIDES
        }
    j = np.load(gt / "joints.npz")
    positions = j["positions"][:, SEVEN]
    points["ankle"] = {"left": positions[:, 5], "right": positions[:, 6]}
    events = list(csv.DictReader((gt / "events.csv").open()))
    return {"t": t, "points": points, "joints": positions, "events": events}


def true_contacts(events: list[dict]) -> list[FootContact]:
    """The simulator's stances (``events.csv`` rows) as foot contacts."""

    def num(text: str) -> float | None:
        return float(text) if text else None

    return [
        FootContact(
            r["side"],
            num(r["heel_strike_s"]),
            num(r["toe_off_s"]),
            float(r["flat_start_s"]),
            float(r["flat_end_s"]),
            np.array([float(r["sole_x_m"]), float(r["sole_y_m"]), 0.0]),
        )
        for r in events
    ]


PHASES = ("stance_pct", "double_support_pct")


def phase_errors(contacts: list[FootContact], events: list[dict]) -> dict[str, list[float]]:
    """Detected − true stance % and double support % of the steady strides between the true
    stances (the same strides, phases from detected vs true events)."""
    truth = true_contacts(events)
    strides = strides_from_stances(stances_from_contacts(truth))
    found = stride_parameters(strides, contacts)
    true = stride_parameters(strides, truth)
    out: dict[str, list[float]] = {k: [] for k in PHASES}
    for a, b in zip(found, true, strict=True):
        for k in PHASES:
            if a.steady and a.values[k] is not None and b.values[k] is not None:
                out[k].append(a.values[k] - b.values[k])
    return out


def match(true: list[float], found: list[float]) -> tuple[list[float | None], int, int]:
    """Signed error of each true event to the nearest found one (each used once; None when
    none lies within the tolerance), the misses and the extras."""
    errors: list[float | None] = []
    used: set[int] = set()
    for x in true:
        cands = [(abs(f - x), i) for i, f in enumerate(found) if i not in used]
        if cands and min(cands)[0] <= TOLERANCE_S:
            _, i = min(cands)
            used.add(i)
            errors.append(found[i] - x)
        else:
            errors.append(None)
    missed = sum(e is None for e in errors)
    return errors, missed, len(found) - len(used)


def evaluate(data: dict, kind: str, with_pelvis: bool, noise_m: float, rng) -> dict:
    feet = {s: p + rng.normal(0.0, noise_m, p.shape) for s, p in data["points"][kind].items()}
    joints = data["joints"] if with_pelvis else None
    contacts = detect_events(data["t"], feet, joints)
    out = {"ic": [], "to": [], "ic_steady": [], "missed": 0, "extra": 0}
    out |= phase_errors(contacts, data["events"])
    for side in SIDES:
        ev = [e for e in data["events"] if e["side"] == side]
        for key, col, attr in (
            ("ic", "heel_strike_s", "initial_contact_s"),
            ("to", "toe_off_s", "toe_off_s"),
        ):
            rows = [k for k, e in enumerate(ev) if e[col]]
            found = [getattr(c, attr) for c in contacts if c.side == side]
            errors, missed, extra = match(
                [float(ev[k][col]) for k in rows], [f for f in found if f is not None]
            )
            out[key] += [e for e in errors if e is not None]
            out["missed"] += missed
            out["extra"] += extra
            if key == "ic":  # steady: neither the first step from standing nor the last one
                out["ic_steady"] += [
                    e
                    for k, e in zip(rows, errors, strict=True)
                    if e is not None and ev[k - 1]["heel_strike_s"] and ev[k]["toe_off_s"]
                ]
    return out


def line(label: str, errors: list[float]) -> str:
    e = 1000.0 * np.asarray(errors)
    if e.size == 0:
        return f"{label}: none"
    a = np.abs(e)
    return (
        f"{label} n {e.size:4d} median {np.median(e):+6.1f} median|e| {np.median(a):5.1f} "
        f"p95|e| {np.percentile(a, 95):6.1f} max|e| {a.max():6.1f} ms"
    )


def main() -> None:
    ap = ScriptParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("root", type=Path, help="folder of simulated session folders")
    ap.add_argument("--noise-mm", type=float, nargs="+", default=[0.0])
    ap.add_argument("--select", nargs="*", default=["S1_", "S2_"])
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    sessions = sorted(
        p for p in args.root.iterdir() if (p / "groundtruth" / "events.csv").is_file()
    )
    data = {s.name: load(s) for s in sessions}
    print(f"{len(sessions)} sessions under {args.root}")
    for noise in args.noise_mm:
        for kind, pelvis in (("marker", True), ("marker", False), ("sole", True), ("ankle", True)):
            rng = np.random.default_rng(args.seed)
            groups: dict[str, dict] = {}
            for name, d in data.items():
                group = "selection" if name.startswith(tuple(args.select)) else "held out"
                r = evaluate(d, kind, pelvis, noise * 1e-3, rng)
                g = groups.setdefault(group, {k: 0 if k in ("missed", "extra") else [] for k in r})
                for k in g:
                    g[k] += r[k]
            for group, g in sorted(groups.items()):
                how = "pelvis" if pelvis else "v_z   "
                tag = f"{kind:6s} TO by {how} noise {noise:.0f} mm {group:9s}"
                print(f"{tag} missed {g['missed']} extra {g['extra']}")
                print("   " + line("IC", g["ic"]))
                print("   " + line("IC", g["ic_steady"]) + " (steady steps)")
                print("   " + line("TO", g["to"]))
                for k in PHASES:
                    e = np.asarray(g[k])
                    print(
                        f"   {k} error (steady strides, points of the cycle): n {e.size} "
                        f"median {np.median(e):+.1f} p95|e| {np.percentile(abs(e), 95):.1f}"
                    )


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
