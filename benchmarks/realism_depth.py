"""Depth realism of the simulated D455 (issue 8, item 2): a measurement.

On a plain floor seen by the default 640×480 camera (fx = fy = 386 px) from 1 m high (and
0.6 m, for the near bins), with the default sensor settings:

* depth error (reported − rendered true depth) per 0.25 m bin of true depth from 0.5 to 2.5 m:
  bias (mean) and RMS, over a few frames;
* the error's correlation length: the lag (px, along image rows) at which the autocorrelation
  of the error (per-bin bias removed) falls below 1/e, pixels at 1.0–1.5 m;
* flying pixels: the share of pixels at depth jumps (a 0.5 m box on the floor) that are
  reported with a depth more than 3 cm from both the true depth and the invalid value;
* holes on dark vs bright surfaces (uniform radiance 0.01, 0.3 and a 3.0 glare, at 1.5 m);
* disparity quantisation: the typical step between distinct reported depths of a noise-free
  slanted wall at 2.4–2.6 m (0 = continuous);
* a plane fitted to one frame's floor points (least squares) against the true floor z = 0:
  angle [°] and height offset [mm] at the points' centroid, median over a few seeds (each
  seed draws its own floor relief and camera unit after issue 8);
* time per frame of the sensor model (colour + depth) and of the render, ms.

Importable (:func:`measure`) and runnable on its own::

    python benchmarks/realism_depth.py [--seeds 4]

It works on the code before issue 8 too (``PYTHONPATH=/tmp/sim-base``): where the old code has
no floor relief or camera unit, those parts are simply absent.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import inspect  # noqa: E402
import time  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from gaitnet.geometry import make_T, so3_exp  # noqa: E402
from gaitnet.sim.clutter import ClutterBox  # noqa: E402
from gaitnet.sim.floor import make_floor  # noqa: E402
from gaitnet.sim.render import render_frame  # noqa: E402
from gaitnet.sim.render_types import RenderResult  # noqa: E402
from gaitnet.sim.scene import Appearance, BodyState  # noqa: E402
from gaitnet.sim.sensor_model import SensorNoiseConfig, apply_sensor  # noqa: E402
from gaitnet.training.scripts import ScriptParser  # noqa: E402

W, H, F = 640, 480, 386.0
K = np.array([[F, 0.0, (W - 1) / 2], [0.0, F, (H - 1) / 2], [0.0, 0.0, 1.0]])
R_PfromC_LEVEL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
APPEARANCE = Appearance((0.05, 0.08, 0.2), (0.5, 0.05, 0.04), (0.8, 0.8, 0.78))
NO_BODY = BodyState((), ())
BINS = np.arange(0.5, 2.51, 0.25)
HAS_RELIEF = "relief" in inspect.signature(render_frame).parameters

cv2.setNumThreads(1)


def camera(height_m: float, pitch_deg: float) -> np.ndarray:
    """Camera at (0, 0, height) looking along +x, pitched down by ``pitch_deg``."""
    R = so3_exp([0.0, np.deg2rad(pitch_deg), 0.0]) @ R_PfromC_LEVEL
    return make_T(R, np.array([0.0, 0.0, height_m]))


def _floor(seed: int):
    return make_floor("concrete", np.random.default_rng(seed), ((-2.0, 6.0), (-3.0, 3.0)),
                      texel_m=0.005, room_height_m=None)  # fmt: skip


def _world(seed: int):
    """Floor relief and camera unit of a seed (None, None before issue 8)."""
    if not HAS_RELIEF:
        return None, None
    from gaitnet.sim.floor_relief import FloorReliefConfig, sample_floor_relief
    from gaitnet.sim.sensor_depth import sample_depth_unit

    rng = np.random.default_rng(1000 + seed)
    relief = sample_floor_relief(rng, FloorReliefConfig(), "tiles", ((-2.0, 6.0), (-3.0, 3.0)))
    return relief, sample_depth_unit(rng)


def _render(floor, T: np.ndarray, relief=None, clutter=()) -> RenderResult:
    kw = {"relief": relief} if HAS_RELIEF else {}
    return render_frame(K, W, H, T, floor, NO_BODY, APPEARANCE, clutter, **kw)


def _sense(res: RenderResult, seed: int, cfg: SensorNoiseConfig | None = None, unit=None):
    kw = {"depth_unit": unit} if HAS_RELIEF else {}
    return apply_sensor(res, K, np.random.default_rng(seed), cfg or SensorNoiseConfig(), 1.0, **kw)


def error_by_distance(floor, n_frames: int = 3) -> tuple[list[tuple[float, float, float]], float]:
    """(bin centre, bias mm, RMS mm) per bin and the correlation length [px]."""
    errs, zs = [], []
    for height, pitch in ((1.0, 40.0), (0.6, 65.0)):  # together: the floor from 0.5 to 2.5 m
        res = _render(floor, camera(height, pitch))
        for k in range(n_frames):
            _, depth = _sense(res, k)
            errs.append(np.where(depth > 0, depth - res.depth_m, np.nan))
            zs.append(res.depth_m)
    err, z = np.stack(errs), np.stack(zs)
    rows = []
    for lo in BINS[:-1]:
        e = err[(z >= lo) & (z < lo + 0.25)]
        e = e[np.isfinite(e)]
        if e.size > 100:
            rows.append((lo + 0.125, 1e3 * float(e.mean()), 1e3 * float(np.sqrt(np.mean(e**2)))))
    return rows, correlation_length(err[:n_frames], z[0])


def correlation_length(err: np.ndarray, z: np.ndarray, lags: int = 16) -> float:
    """Lag [px] where the row-wise autocorrelation of the error (1.0–1.5 m) drops below 1/e."""
    band = (z > 1.0) & (z < 1.5)
    rho = []
    for lag in range(lags + 1):
        num, den = 0.0, 0.0
        for e in err:
            e = e - np.nanmean(e[band])
            a, b = e[:, : W - lag], e[:, lag:]
            m = band[:, : W - lag] & band[:, lag:] & np.isfinite(a) & np.isfinite(b)
            num += float(np.sum(a[m] * b[m]))
            den += float(np.sum(a[m] ** 2))
        rho.append(num / den)
    rho = np.asarray(rho)
    below = np.flatnonzero(rho < np.exp(-1))
    if below.size == 0:
        return float(lags)
    i = int(below[0])
    return float(i - 1 + (rho[i - 1] - np.exp(-1)) / (rho[i - 1] - rho[i]))


def flying_share(floor) -> float:
    """Share of jump pixels reported with a depth away from both sides (and valid)."""
    T = camera(1.0, 89.999)
    box = ClutterBox((0.0, 0.0), 0.0, (0.3, 0.3, 0.5), (0.5, 0.5, 0.5))
    res = _render(floor, T, clutter=(box,))
    z = res.depth_m
    k = np.ones((5, 5), np.uint8)
    zmax, zmin = cv2.dilate(z, k), cv2.erode(z, k)
    jump = (zmax - zmin) > 0.1
    shares = []
    for seed in range(3):
        _, depth = _sense(res, seed)
        d = depth[jump]
        mid = (d > zmin[jump] + 0.03) & (d < zmax[jump] - 0.03)
        shares.append(float(mid.mean()))
    return float(np.mean(shares))


def hole_shares() -> dict[str, float]:
    """Share of invalid pixels on uniform surfaces of a given radiance at 1.5 m."""
    out = {}
    for name, radiance in (("dark", 0.01), ("bright", 0.3), ("glare", 3.0)):
        rgb = np.full((H, W, 3), radiance, np.float32)
        z = np.full((H, W), 1.5, np.float32)
        lab = np.zeros((H, W), np.uint8)
        res = RenderResult(rgb, z, lab, lab)
        _, depth = _sense(res, 0)
        out[name] = float((depth == 0).mean())
    return out


def quantisation_step_mm() -> float:
    """Median step between distinct depths of a noise-free slanted wall at 2.4–2.6 m [mm]."""
    z = np.broadcast_to(np.linspace(2.4, 2.6, W, dtype=np.float32)[None, :], (H, W)).copy()
    lab = np.zeros((H, W), np.uint8)
    res = RenderResult(np.full((H, W, 3), 0.3, np.float32), z, lab, lab)
    cfg = SensorNoiseConfig(disparity_noise_px=0.0, dropout_fraction=0.0, blob_fraction=0.0)
    _, depth = _sense(res, 0, cfg)
    v = np.unique(depth[H // 2][depth[H // 2] > 0])
    return 1e3 * float(np.median(np.diff(v))) if v.size > 1 else float("nan")


def plane_fit(floor, seeds: int) -> tuple[float, float]:
    """Median over seeds of the angle [°] and offset [mm] of a plane fitted to one frame."""
    T = camera(1.0, 40.0)
    angles, offsets = [], []
    for seed in range(seeds):
        relief, unit = _world(seed)
        res = _render(floor, T, relief)
        _, depth = _sense(res, seed, unit=unit)
        v, u = np.nonzero((depth > 0) & (depth < 3.0))
        zc = depth[v, u].astype(np.float64)
        p_C = np.stack([(u - K[0, 2]) / F * zc, (v - K[1, 2]) / F * zc, zc], axis=1)
        p_W = p_C @ T[:3, :3].T + T[:3, 3]
        c = p_W.mean(axis=0)
        n = np.linalg.svd(p_W - c, full_matrices=False)[2][-1]
        n = n if n[2] > 0 else -n
        angles.append(float(np.degrees(np.arccos(min(1.0, n[2])))))
        offsets.append(1e3 * float(c[2]))
    return float(np.median(angles)), float(np.median(np.abs(offsets)))


def timing(floor, repeats: int = 5) -> tuple[float, float]:
    """(render ms, sensor ms) per 640×480 frame with the default settings."""
    relief, unit = _world(0)
    T = camera(1.0, 40.0)
    t0 = time.perf_counter()
    for _ in range(repeats):
        res = _render(floor, T, relief)
    t1 = time.perf_counter()
    for k in range(repeats):
        _sense(res, k, unit=unit)
    t2 = time.perf_counter()
    return 1e3 * (t1 - t0) / repeats, 1e3 * (t2 - t1) / repeats


def measure(seeds: int = 4) -> dict:
    """All figures of the module docstring."""
    floor = _floor(0)
    rows, corr = error_by_distance(floor)
    angle, offset = plane_fit(floor, seeds)
    render_ms, sensor_ms = timing(floor)
    return {
        "bins": rows,
        "correlation_px": corr,
        "flying_share": flying_share(floor),
        "holes": hole_shares(),
        "quantisation_mm_at_2_5m": quantisation_step_mm(),
        "plane_angle_deg": angle,
        "plane_offset_mm": offset,
        "render_ms": render_ms,
        "sensor_ms": sensor_ms,
    }


def report(m: dict) -> None:
    """Print the figures as a small table."""
    print("[depth] error vs true depth on a flat floor (default sensor, 640×480, f 386 px):")
    print("         z [m]   bias [mm]   RMS [mm]")
    for zc, bias, rms in m["bins"]:
        print(f"         {zc:5.2f}   {bias:9.2f}   {rms:8.2f}")
    holes = m["holes"]
    print(
        f"[depth] correlation length {m['correlation_px']:.1f} px; flying pixels "
        f"{100 * m['flying_share']:.1f} % of jump pixels; holes dark {100 * holes['dark']:.1f} %"
        f", bright {100 * holes['bright']:.1f} %, glare {100 * holes['glare']:.1f} %; "
        f"quantisation step at 2.5 m {m['quantisation_mm_at_2_5m']:.2f} mm"
    )
    print(
        f"[depth] one-frame floor plane fit: angle {m['plane_angle_deg']:.3f}°, offset "
        f"{m['plane_offset_mm']:.2f} mm (median over seeds); time per 640×480 frame: render "
        f"{m['render_ms']:.1f} ms, sensor (colour + depth) {m['sensor_ms']:.1f} ms"
    )


def main() -> None:
    parser = ScriptParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=4)
    args = parser.parse_args()
    report(measure(args.seeds))


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
