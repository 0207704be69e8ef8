"""Measure the IMU and timing realism of the simulator (issue 8, item 4) and print a table.

    python benchmarks/realism_imu.py [--seeds 3]
    PYTHONPATH=/tmp/sim-base python benchmarks/realism_imu.py   # the simulator before

Pure measurement on the simulator's own worlds (no rendering: the scene, the walk, the IMU):
1. heel-strike shocks: the noise-free IMU's specific force high-passed at 10 Hz (4th-order
   Butterworth, zero phase): its power in [HS − 20 ms, HS + 150 ms] around each heel strike vs
   the rest of the walking phase, and the peak of the shock at the rig in g, at 0.8, 1.2 and
   1.6 m/s;
2. the camera's wobble on its strap, from the camera-in-pelvis truth at the IMU rate:
   displacement (RMS / max, mm) and tilt (max, °), and its natural frequency, damping ratio and
   gain recovered by a least-squares fit of ``ẍ + 2ζωẋ + ω²x = −γu`` (``u`` the pelvis
   acceleration in the pelvis frame plus the shock's acceleration);
3. IMU errors: scale and misalignment recovered by a least-squares fit of the measured
   (noise- and bias-free, quantised) IMU against the exact one, the quantisation step, and the
   camera–IMU time offset recovered by cross-correlating the measured gyro norm with the exact
   one;
4. frame timing: dropped-frame rate and timestamp jitter over a 2-hour stream of frame times;
5. strapdown: the noise-free IMU of the moving rig integrated (``gaitnet/sim/strapdown.py``)
   over 10 s at 200 Hz and at 1 kHz vs the true trajectory;
6. cost: milliseconds per session for the rig motion and the IMU, per frame at 30 Hz.

Works with the code before the issue (no rig motion, no IMU errors, no timing effects: those
rows read 0 or n/a).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from scipy.signal import butter, sosfiltfilt

from gaitnet.config import load_config
from gaitnet.sim.config import SimConfig
from gaitnet.sim.imu import ImuConfig, simulate_imu
from gaitnet.sim.scene_setup import build_scene, rng_streams
from gaitnet.sim.strapdown import integrate_imu
from gaitnet.training.scripts import ScriptParser

ROOT = Path(__file__).resolve().parents[1]
G0 = 9.80665
SPEEDS = (0.8, 1.2, 1.6)


def _config(*overrides: str) -> SimConfig:
    return load_config(
        SimConfig,
        ROOT / "configs" / "sim" / "default.yaml",
        ["gait.walk_length_m=8", "scene.floor_family=wood", "scene.clutter_count=0", *overrides],
    )


def _rig(scene, cfg: SimConfig):
    """The body the IMU sits on and its IMU-in-body transform (before: the pelvis)."""
    if hasattr(scene, "camera_kinematics"):
        return scene.camera_kinematics, cfg.mount.T_CfromI()
    T_PfromI = scene.mount.T_PfromC() @ cfg.mount.T_CfromI()
    return scene.walk.pelvis_kinematics, T_PfromI


def _heel_strikes(walk) -> np.ndarray:
    hs = np.concatenate([walk.events[s].hs_s for s in ("left", "right")])
    return np.sort(hs[np.isfinite(hs)])


def shock_figures(speed: float, seed: int) -> dict[str, float]:
    """High-frequency power around heel strikes vs elsewhere, and the shock's peak [g]."""
    cfg = _config(f"gait.speed_mps={speed}")
    scene = build_scene(cfg, rng_streams(seed))
    body, T = _rig(scene, cfg)
    walk = scene.walk
    _, truth = simulate_imu(
        body, T, 0.0, walk.duration_s, ImuConfig(noise_free=True), np.random.default_rng(0)
    )
    t, f = truth.t_s, truth.specific_force
    hp = sosfiltfilt(butter(4, 10.0, "highpass", fs=200.0, output="sos"), f, axis=0)
    power = (hp**2).sum(1)
    hs = _heel_strikes(walk)
    near = np.zeros(len(t), bool)
    peaks = []
    for h in hs:
        w = (t >= h - 0.02) & (t <= h + 0.15)
        near |= w
        peaks.append(float(np.linalg.norm(hp[w], axis=1).max()) / G0)
    walking = (t > hs.min() - 0.3) & (t < hs.max() + 0.5)
    far = walking & ~near
    total = ((f - f[walking].mean(0)) ** 2).sum(1)
    return {
        "hf_share_at_hs": float(power[near].sum() / total[near].sum()),
        "hf_ratio_hs_vs_elsewhere": float(power[near].mean() / max(power[far].mean(), 1e-12)),
        "peak_g": float(np.median(peaks)),
    }


def wobble_figures(seed: int) -> dict[str, float]:
    """Wobble amplitude and its damped-spring parameters recovered from the mount truth."""
    cfg = _config()
    scene = build_scene(cfg, rng_streams(seed))
    motion = getattr(scene, "mount_motion", None)
    if motion is None or motion.spline is None:
        return {"rms_mm": 0.0, "max_mm": 0.0, "tilt_max_deg": 0.0}
    walk = scene.walk
    t = np.arange(0.0, walk.duration_s, 1 / 200.0)
    T = motion.T_PfromC(t)
    dev = T[:, :3, 3] - motion.T_PfromC_nominal[:3, 3]
    R_rel = T[:, :3, :3] @ motion.T_PfromC_nominal[:3, :3].T
    tilt = np.degrees(np.arccos(np.clip((np.trace(R_rel, axis1=1, axis2=2) - 1) / 2, -1, 1)))
    impact, wobble = motion.parts(t)
    # Fit ẍ + a1 ẋ + a0 x = b u on the vertical axis (numerical derivatives of the truth).
    h = t[1] - t[0]
    x = wobble[:, 2]
    dx, ddx = np.gradient(x, h), np.gradient(np.gradient(x, h), h)
    R_WP, _, _, a_P, _ = walk.pelvis_kinematics(t)
    u = np.einsum("nji,nj->ni", R_WP, a_P)[:, 2] + np.gradient(np.gradient(impact[:, 2], h), h)
    A = np.stack([dx, x, u], 1)
    (a1, a0, b), *_ = np.linalg.lstsq(A, -ddx, rcond=None)
    w = np.sqrt(a0)
    return {
        "rms_mm": float(1000 * np.sqrt((dev**2).sum(1).mean())),
        "max_mm": float(1000 * np.linalg.norm(dev, axis=1).max()),
        "tilt_max_deg": float(tilt.max()),
        "freq_hz": float(w / (2 * np.pi)),
        "damping": float(a1 / (2 * w)),
        "gain": float(b),
    }


def imu_error_figures(seed: int) -> dict[str, float]:
    """Scale / misalignment by least squares, quantisation and the time offset."""
    cfg = _config()
    rngs = rng_streams(seed)
    scene = build_scene(cfg, rngs)
    body, T = _rig(scene, cfg)
    quiet = dict(
        gyro_noise_density=0.0,
        accel_noise_density=0.0,
        gyro_bias_random_walk=0.0,
        accel_bias_random_walk=0.0,
        gyro_initial_bias_std=0.0,
        accel_initial_bias_std=0.0,
    )
    imu_cfg = ImuConfig(**quiet)
    out: dict[str, float] = {}
    calibration = None
    try:
        from gaitnet.sim.imu import draw_imu_calibration

        offset = cfg.timing.draw_imu_time_offset(rngs["imu_calibration"])
        calibration = draw_imu_calibration(imu_cfg, rngs["imu_calibration"], offset)
        samples, truth = simulate_imu(
            body, T, 0.0, scene.walk.duration_s, imu_cfg, np.random.default_rng(1), calibration
        )
    except ImportError:  # before: no IMU errors
        samples, truth = simulate_imu(
            body, T, 0.0, scene.walk.duration_s, imu_cfg, np.random.default_rng(1)
        )
    for name, meas, ideal in (
        ("accel", samples.accel, truth.specific_force),
        ("gyro", samples.gyro, truth.omega_I),
    ):
        M = np.linalg.lstsq(ideal, meas, rcond=None)[0].T
        out[f"{name}_scale_max_pct"] = float(100 * np.abs(np.diag(M) - 1).max())
        off = M - np.diag(np.diag(M))
        out[f"{name}_cross_max_pct"] = float(100 * np.abs(off).max())
        if calibration is not None:
            true_M = getattr(calibration, f"{name}_matrix")
            out[f"{name}_fit_error"] = float(np.abs(M - true_M).max())
        steps = np.diff(np.unique(np.round(meas[:, 0], 12)))
        out[f"{name}_lsb"] = float(steps.min()) if len(steps) else 0.0
    # Time offset: cross-correlate the measured gyro norm (its timestamps) with the exact one.
    stamps = samples.t_ns * 1e-9
    grid = np.arange(1.0, scene.walk.duration_s - 1.0, 1e-4)
    meas = np.interp(grid, stamps, np.linalg.norm(samples.gyro, axis=1))
    lags = np.arange(-0.02, 0.02 + 1e-9, 1e-4)
    true_w = body(grid)[4]
    R_CI = T[:3, :3]
    ref_t = np.linalg.norm(true_w @ R_CI, axis=1)
    corr = []
    for lag in lags:
        ref = np.interp(grid, grid + lag, ref_t)
        corr.append(np.dot(meas - meas.mean(), ref - ref.mean()))
    out["time_offset_ms_recovered"] = float(1000 * lags[int(np.argmax(corr))])
    out["time_offset_ms_true"] = (
        float(1000 * calibration.time_offset_s) if calibration is not None else 0.0
    )
    return out


def timing_figures(seed: int) -> dict[str, float]:
    """Dropped-frame rate and timestamp jitter over two hours of frames at 30 Hz."""
    try:
        from gaitnet.sim.frame_timing import make_frame_times
    except ImportError:
        return {"drop_rate_pct": 0.0, "jitter_std_ms": 0.0, "max_run_of_drops": 0}
    cfg = _config()
    ft = make_frame_times(7200.0, 30.0, cfg.timing, rng_streams(seed)["frame_timing"])
    jitter = ft.stamp_ns * 1e-9 - ft.true_s
    runs = np.diff(ft.dropped)
    return {
        "drop_rate_pct": float(100 * len(ft.dropped) / (len(ft.dropped) + len(ft.index))),
        "jitter_std_ms": float(1000 * jitter.std()),
        "max_run_of_drops": int(1 if len(ft.dropped) and (runs > 1).all() else len(ft.dropped)),
    }


def strapdown_figures(seed: int) -> dict[str, float]:
    """Noise-free IMU of the moving rig integrated over 10 s vs the truth [mm]."""
    cfg = _config()
    scene = build_scene(cfg, rng_streams(seed))
    body, T = _rig(scene, cfg)
    out = {}
    for rate in (200.0, 1000.0):
        s, tr = simulate_imu(
            body, T, 0.0, 10.0, ImuConfig(noise_free=True, rate_hz=rate), np.random.default_rng(0)
        )
        p, _ = integrate_imu(
            s.t_ns * 1e-9, s.accel, s.gyro, tr.R_WfromI[0], tr.p_IinW[0], tr.v_IinW[0], 9.81
        )
        out[f"err_mm_{int(rate)}hz"] = float(1000 * np.linalg.norm(p - tr.p_IinW, axis=1).max())
    return out


def cost_figures(seed: int) -> dict[str, float]:
    """Time to build the scene's rig motion and the session's IMU, per 30 Hz frame [ms]."""
    cfg = _config()
    scene = build_scene(cfg, rng_streams(seed))
    n_frames = scene.walk.duration_s * 30.0
    start = time.perf_counter()
    motion_ms = 0.0
    if hasattr(scene, "mount_motion"):
        from gaitnet.sim.mount_dynamics import build_mount_motion

        build_mount_motion(
            scene.walk, scene.mount, scene.mount.T_PfromC(), np.random.default_rng(0)
        )
        motion_ms = 1000 * (time.perf_counter() - start)
    body, T = _rig(scene, cfg)
    start = time.perf_counter()
    simulate_imu(body, T, 0.0, scene.walk.duration_s, cfg.imu, np.random.default_rng(0))
    imu_ms = 1000 * (time.perf_counter() - start)
    return {
        "rig_motion_ms_per_frame": motion_ms / n_frames,
        "imu_ms_per_frame": imu_ms / n_frames,
    }


def report(seeds: int = 2) -> dict[str, dict[str, float]]:
    """All figures (means over ``seeds`` worlds), printed as a table by :func:`main`."""
    rows: dict[str, dict[str, float]] = {}

    def mean(fn, *args) -> dict[str, float]:
        runs = [fn(*args, s) for s in range(seeds)]
        return {k: float(np.mean([r[k] for r in runs])) for k in runs[0]}

    for v in SPEEDS:
        rows[f"shock @ {v} m/s"] = mean(shock_figures, v)
    rows["wobble"] = mean(wobble_figures)
    rows["imu errors"] = imu_error_figures(0)
    rows["frame timing"] = timing_figures(0)
    rows["strapdown 10 s"] = mean(strapdown_figures)
    rows["cost"] = cost_figures(0)
    return rows


def print_report(rows: dict[str, dict[str, float]]) -> None:
    for name, figures in rows.items():
        text = ", ".join(f"{k} {v:.4g}" for k, v in figures.items())
        print(f"[imu-realism] {name}: {text}")


def main(seeds: int | None = None) -> None:
    if seeds is None:
        parser = ScriptParser(description=__doc__.splitlines()[0])
        parser.add_argument("--seeds", type=int, default=2)
        seeds = parser.parse_args().seeds
    print_report(report(seeds))


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
