"""Gait realism: spatio-temporal values, pelvis, knee and ankle angles and standing sway vs speed.

    python benchmarks/realism_gait.py [--subjects 4] [--seed 0]
    PYTHONPATH=/tmp/sim-base python benchmarks/realism_gait.py   # an older simulator

Pure measurement on the gait generator alone (no rendering): for each speed in :data:`SPEEDS`,
``--subjects`` random subjects walk 10 m straight with the default :class:`GaitConfig`
otherwise; the steady strides (the first two and last two steps left out) are measured and
averaged. Columns: stance and double-support share of the cycle, cadence, stride length, pelvis
vertical excursion per step, lateral excursion per stride, rotation and obliquity (half peak-to-
peak), knee flexion at heel strike / loading peak / toe off / swing peak, ankle dorsiflexion at toe
off and its minimum in the 10 % of the cycle after it, ankle in late swing (85–95 % of the cycle),
and the pelvis sway while standing at the start (RMS anterior-posterior / medio-lateral, mean
frequency). Textbook bands: docs/references.md (*Normal adult walking*, *Simulator realism:
gait*). Works with any gaitnet that has ``generate_walk(subject, GaitConfig, rng)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gaitnet.sim.gait import GaitConfig, Walk, generate_walk
from gaitnet.sim.subject import sample_subject
from gaitnet.training.scripts import ScriptParser

SPEEDS = (0.8, 1.0, 1.2, 1.4, 1.6)
DT = 2e-3
SIDES = ("left", "right")
COLUMNS = (
    ("stance", "stance %", "{:.1f}"),
    ("double", "dbl supp %", "{:.1f}"),
    ("cadence", "cadence/min", "{:.0f}"),
    ("stride", "stride m", "{:.2f}"),
    ("vert", "pelvis z cm", "{:.1f}"),
    ("lat", "pelvis y cm", "{:.1f}"),
    ("rot", "rot ±°", "{:.1f}"),
    ("obl", "obl ±°", "{:.1f}"),
    ("knee_hs", "knee HS°", "{:.0f}"),
    ("knee_load", "knee LR°", "{:.0f}"),
    ("knee_to", "knee TO°", "{:.0f}"),
    ("knee_sw", "knee sw°", "{:.0f}"),
    ("ankle_to", "ankle TO°", "{:.0f}"),
    ("ankle_pf", "ankle min°", "{:.0f}"),
    ("ankle_ls", "ankle LS°", "{:.0f}"),
    ("sway_ap", "sway AP mm", "{:.1f}"),
    ("sway_ml", "sway ML mm", "{:.1f}"),
    ("sway_f", "sway Hz", "{:.2f}"),
)
BANDS = {
    "stance": "≈ 62 → 58",
    "double": "≈ 24 → 16",
    "cadence": "100–125",
    "stride": "1.2–1.6 (1.3 m/s)",
    "vert": "4–5 (1.2 m/s)",
    "lat": "≈ 4",
    "rot": "±4–5 (normal)",
    "obl": "±3–5",
    "knee_hs": "0–5",
    "knee_load": "15–20",
    "knee_to": "35–40",
    "knee_sw": "60–65",
    "ankle_to": "−10…−20",
    "ankle_pf": "−15…−20",
    "ankle_ls": "≈ 0",
    "sway_ap": "2–5",
    "sway_ml": "1–3",
    "sway_f": "0.1–1",
}


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    cos = np.sum(a * b, -1) / np.linalg.norm(a, axis=-1) / np.linalg.norm(b, axis=-1)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def knee_flexion_deg(J: np.ndarray) -> np.ndarray:
    """Knee flexion [deg] (n, 2) from joints (n, 9, 3) (``Walk.joints`` order)."""
    return _angle(J[:, 3:5] - J[:, 1:3], J[:, 5:7] - J[:, 3:5])


def ankle_dorsiflexion_deg(J: np.ndarray, J_rest: np.ndarray) -> np.ndarray:
    """Ankle dorsiflexion [deg] (n, 2): the shank–foot angle's decrease from the rest pose.

    Angle between ankle→knee and ankle→foot joint (ball of the foot); positive = toes toward the
    shank (dorsiflexion), negative = plantarflexion.
    """
    rest = _angle(J_rest[None, 3:5] - J_rest[None, 5:7], J_rest[None, 7:9] - J_rest[None, 5:7])
    return rest - _angle(J[:, 3:5] - J[:, 5:7], J[:, 7:9] - J[:, 5:7])


@dataclass
class GaitValues:
    """Means over the steady strides of one walk (keys of :data:`COLUMNS`)."""

    values: dict[str, float]


def measure_walk(w: Walk) -> dict[str, float]:
    """The :data:`COLUMNS` values of one straight walk along +x."""
    t = np.arange(0.0, w.duration_s, DT)
    J = w.joints(t)
    R, p = w.pelvis_pose(t)
    knee = knee_flexion_deg(J)
    ankle = ankle_dorsiflexion_deg(J, w.skeleton.rest_joints)
    hs = w.steps.hs_s
    out: dict[str, list[float]] = {k: [] for k, _, _ in COLUMNS}
    step_t = np.diff(hs)[2:-2]
    out["cadence"].append(60.0 / float(np.mean(step_t)))
    for k in range(2, len(hs) - 3):
        m = (t >= hs[k]) & (t < hs[k + 1])
        out["vert"].append(float(np.ptp(p[m, 2])))
    steady = (t > hs[2]) & (t < hs[-3])
    yaw = np.degrees(np.arctan2(R[:, 1, 0], R[:, 0, 0]))
    obl = np.degrees(np.arctan2(R[:, 2, 1], R[:, 2, 2]))
    for i, side in enumerate(SIDES):
        ev = w.events[side]
        other = w.events[SIDES[1 - i]]
        out["stride"] += list(ev.stride_lengths_m[2:-2])
        for k in range(2, len(ev.hs_s) - 2):
            cycle = ev.hs_s[k + 1] - ev.hs_s[k]
            if not (np.isfinite(ev.to_s[k]) and np.isfinite(cycle)):
                continue
            out["stance"].append(100.0 * (ev.to_s[k] - ev.hs_s[k]) / cycle)
            # double support after this heel strike: until the other foot's toe off
            to_other = other.to_s[(other.to_s > ev.hs_s[k]) & (other.to_s < ev.hs_s[k + 1])]
            if len(to_other):
                out["double"].append(200.0 * (to_other[0] - ev.hs_s[k]) / cycle)
            ph = (t - ev.hs_s[k]) / cycle
            cyc = (ph >= 0.0) & (ph < 1.0)
            out["knee_hs"].append(float(knee[np.argmin(np.abs(ph)), i]))
            out["knee_load"].append(float(knee[cyc & (ph < 0.25), i].max()))
            i_to = int(np.argmin(np.abs(t - ev.to_s[k])))
            out["knee_to"].append(float(knee[i_to, i]))
            out["knee_sw"].append(float(knee[cyc, i].max()))
            out["ankle_to"].append(float(ankle[i_to, i]))
            after = (t >= ev.to_s[k]) & (t <= ev.to_s[k] + 0.1 * cycle)
            out["ankle_pf"].append(float(ankle[after, i].min()))
            late = (ph >= 0.85) & (ph <= 0.95)
            out["ankle_ls"].append(float(ankle[late, i].mean()))
            stride = (t >= ev.hs_s[k]) & (t < ev.hs_s[k + 1])
            out["lat"].append(float(np.ptp(p[stride, 1])))
    out["rot"].append(0.5 * float(np.ptp(yaw[steady])))
    out["obl"].append(0.5 * float(np.ptp(obl[steady])))
    stand = t <= w.config.stand_start_s
    ap = p[stand, 0] - p[stand, 0].mean()
    ml = p[stand, 1] - p[stand, 1].mean()
    out["sway_ap"].append(1000.0 * float(np.sqrt(np.mean(ap**2))))
    out["sway_ml"].append(1000.0 * float(np.sqrt(np.mean(ml**2))))
    out["sway_f"].append(mean_frequency_hz(ap, DT))
    res = {k: float(np.mean(v)) if v else float("nan") for k, v in out.items()}
    res["vert"] *= 100.0
    res["lat"] *= 100.0
    return res


def mean_frequency_hz(x: np.ndarray, dt: float) -> float:
    """Power-weighted mean frequency of ``x`` (0 for a signal still to within 1 µm RMS)."""
    x = np.asarray(x, dtype=np.float64) - np.mean(x)
    if np.sqrt(np.mean(x**2)) < 1e-6:
        return 0.0
    spec = np.abs(np.fft.rfft(x * np.hanning(len(x)))) ** 2
    f = np.fft.rfftfreq(len(x), dt)
    spec[0] = 0.0
    total = float(spec.sum())
    return float((f * spec).sum() / total) if total > 1e-30 else 0.0


def measure(speeds: tuple[float, ...] = SPEEDS, subjects: int = 4, seed: int = 0) -> dict:
    """``{speed: {column: mean over subjects}}`` plus the per-subject spread of a few values."""
    table: dict[float, dict[str, float]] = {}
    spread: dict[float, dict[str, float]] = {}
    for v in speeds:
        rows = []
        for s in range(subjects):
            rng = np.random.default_rng([seed, s])
            subject = sample_subject(rng)
            gait = GaitConfig(speed_mps=v, walk_length_m=10.0, stand_start_s=4.0)
            rows.append(measure_walk(generate_walk(subject, gait, rng)))
        table[v] = {k: float(np.mean([r[k] for r in rows])) for k, _, _ in COLUMNS}
        spread[v] = {
            k: float(np.std([r[k] for r in rows])) for k in ("stance", "cadence", "rot", "obl")
        }
    return {"table": table, "spread": spread}


def report(result: dict) -> None:
    """Print the table (rows: speeds; last row the textbook band)."""
    names = [c[1] for c in COLUMNS]
    width = max(len(n) for n in names) + 1
    print("[gait] " + "speed".ljust(6) + "".join(n.rjust(width) for n in names))
    for v, row in result["table"].items():
        cells = "".join(fmt.format(row[k]).rjust(width) for k, _, fmt in COLUMNS)
        print(f"[gait] {v:<6.1f}{cells}")
    print("[gait] band  " + "  ".join(f"{c[1]}: {BANDS[c[0]]}" for c in COLUMNS))
    for v, sp in result["spread"].items():
        print(
            f"[gait] {v:.1f} m/s between-subject std: stance {sp['stance']:.2f} %, cadence "
            f"{sp['cadence']:.1f}/min, rotation {sp['rot']:.2f}°, obliquity {sp['obl']:.2f}°"
        )


def main() -> None:
    parser = ScriptParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subjects", type=int, default=4)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    report(measure(SPEEDS, args.subjects, args.seed))


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
