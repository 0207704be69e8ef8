"""Measure the simulator against its acceptance criteria and print the figures.

    python benchmarks/validate_sim.py [--walks 40] [--seed 0] [--out runs/validate_sim]

1. Zero slip over many random walks (heights, speeds 0.6–1.7 m/s, 5/10/15 m, turns): the largest
   movement of a sole centre inside a foot-flat interval, and of the heel (toe) contact point
   during the heel (toe) rocker.
2. IMU consistency: the noise-free IMU of random walks integrated (RK4, independent code in
   gaitnet/sim/strapdown.py) from the true initial state over 10 s vs the true trajectory.
3. A full default session simulated single-threaded: frames per second of the whole loop
   (render + sensor + PNG writing), the share of visible foot markers on foot labels, the
   distance of back-projected labelled pixels to the rendered shoe / leg surfaces (noise-free
   depth), the depth noise at labelled pixels, and the session reader's acceptance.
4. Same seed → identical bytes (two runs of a small session); different seeds differ.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import hashlib  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402
import realism_blur  # noqa: E402
import realism_depth  # noqa: E402
import realism_gait  # noqa: E402
import realism_imu  # noqa: E402
import realism_tags  # noqa: E402

from gaitnet.config import load_config  # noqa: E402
from gaitnet.geometry import backproject  # noqa: E402
from gaitnet.io import SessionFolder  # noqa: E402
from gaitnet.sim.config import SimConfig  # noqa: E402
from gaitnet.sim.gait import GaitConfig, generate_walk  # noqa: E402
from gaitnet.sim.imu import ImuConfig, simulate_imu  # noqa: E402
from gaitnet.sim.render_prims import leg_sdf, shoe_sdf  # noqa: E402
from gaitnet.sim.scene_setup import build_scene, rng_streams  # noqa: E402
from gaitnet.sim.session import simulate_session  # noqa: E402
from gaitnet.sim.strapdown import integrate_imu  # noqa: E402
from gaitnet.sim.subject import sample_subject  # noqa: E402
from gaitnet.sim.worker_pool import default_workers  # noqa: E402
from gaitnet.training.scripts import ScriptParser  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

cv2.setNumThreads(1)


def slip_and_imu(n_walks: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    worst_flat, worst_heel, worst_toe, worst_imu = 0.0, 0.0, 0.0, 0.0
    cfg = load_config(SimConfig, None)
    T_PfromI = cfg.mount.T_PfromC() @ cfg.mount.T_CfromI()
    for k in range(n_walks):
        gait = GaitConfig(
            speed_mps=float(rng.uniform(0.6, 1.7)),
            walk_length_m=float(rng.choice([5.0, 10.0, 15.0])),
            turn_deg=float(rng.choice([0.0, 0.0, 45.0, -90.0])),
        )
        subject = sample_subject(np.random.default_rng(seed * 1000 + k))
        walk = generate_walk(subject, gait, np.random.default_rng(seed * 1000 + k))
        L = subject.shoe_length_m
        heel_S = np.array([-L / 2, 0.0, 0.0])
        toe_S = np.array([L / 2, 0.0, 0.0])
        for s, side in enumerate(("left", "right")):
            ev = walk.events[side]
            for i in range(len(ev.flat_start_s)):
                t = np.linspace(ev.flat_start_s[i], ev.flat_end_s[i], 50)
                p = walk.sole_centres(t)[:, s]
                worst_flat = max(worst_flat, float(np.linalg.norm(p - p[0], axis=1).max()))
                if np.isfinite(ev.hs_s[i]) and np.isfinite(ev.ff_s[i]):
                    t = np.linspace(ev.hs_s[i], ev.ff_s[i], 30)
                    p = walk.shoe_points(t, heel_S)[:, s, 0]
                    worst_heel = max(worst_heel, float(np.linalg.norm(p - p[0], axis=1).max()))
                if np.isfinite(ev.ho_s[i]) and np.isfinite(ev.to_s[i]):
                    t = np.linspace(ev.ho_s[i], ev.to_s[i], 30)
                    p = walk.shoe_points(t, toe_S)[:, s, 0]
                    worst_toe = max(worst_toe, float(np.linalg.norm(p - p[0], axis=1).max()))
        if k < 5:
            t1 = min(10.0, walk.duration_s)
            imu, truth = simulate_imu(
                walk.pelvis_kinematics,
                T_PfromI,
                0.0,
                t1,
                ImuConfig(noise_free=True),
                np.random.default_rng(k),
            )
            p_est, _ = integrate_imu(
                imu.t_ns * 1e-9,
                imu.accel,
                imu.gyro,
                truth.R_WfromI[0],
                truth.p_IinW[0],
                truth.v_IinW[0],
                9.81,
            )
            worst_imu = max(worst_imu, float(np.linalg.norm(p_est - truth.p_IinW, axis=1).max()))
    print(
        f"[slip] {n_walks} random walks: max sole-centre motion in foot flat "
        f"{1000 * worst_flat:.4f} mm (criterion < 2 mm); heel pivot {1000 * worst_heel:.4f} mm; "
        f"toe pivot {1000 * worst_toe:.4f} mm"
    )
    print(
        f"[imu] noise-free IMU integrated over 10 s (5 walks): max position error "
        f"{1000 * worst_imu:.4f} mm (criterion < 10 mm)"
    )


def surface_checks(cfg: SimConfig, seed: int, session: Path, every: int) -> None:
    """Labelled pixels back-projected with noise-free depth lie on the rendered surfaces.

    The session's own world (same seed, same set-up), rendered noise-free.
    """
    scene = build_scene(cfg, rng_streams(seed))
    K = cfg.camera.intrinsics().K
    folder = SessionFolder(session)
    dist_foot, dist_leg, noise = [], [], []
    for k in range(0, len(folder), every):
        t = folder.frame_times_ns[k] * 1e-9
        T_WC = scene.T_WfromC(np.array([t]))[0]
        body = scene.walk.body_state(t)
        res = scene.render(cfg.camera, t, T_WC)
        noisy = folder.frame(k).depth_m
        for value, sink in ((1, dist_foot), (2, dist_leg)):
            v, u = np.nonzero(res.label == value)
            if len(u) == 0:
                continue
            z = res.depth_m[v, u]
            p_C = backproject(K, u.astype(float), v.astype(float), z)
            p_W = p_C @ T_WC[:3, :3].T + T_WC[:3, 3]
            side = res.instance[v, u]
            d = np.full(len(u), np.inf)
            for s in (1, 2):
                m = side == s
                if value == 1:
                    d[m] = np.abs(shoe_sdf(body.shoes[s - 1], p_W[m]))
                else:
                    legs = [g for g in body.legs if g.side == ("left", "right")[s - 1]]
                    d[m] = np.min([np.abs(leg_sdf(g, p_W[m])) for g in legs], axis=0)
            sink.extend(d.tolist())
            ok = noisy[v, u] > 0
            noise.extend((noisy[v, u][ok] - z[ok]).tolist())
    for name, d in (("foot", dist_foot), ("leg", dist_leg)):
        if d:
            d = np.asarray(d)
            print(
                f"[labels] {name} pixels ({len(d)}): distance of back-projected noise-free "
                f"depth to the rendered surface median {1000 * np.median(d):.3f} mm, "
                f"99th pct {1000 * np.percentile(d, 99):.3f} mm"
            )
    if noise:
        n = np.asarray(noise)
        print(
            f"[labels] measured depth − true depth at labelled pixels: mean "
            f"{1000 * n.mean():.2f} mm, std {1000 * n.std():.2f} mm"
        )


def digest(root: Path) -> str:
    h = hashlib.sha256()
    for p in sorted(root.rglob("*")):
        if p.is_file():
            h.update(str(p.relative_to(root)).encode())
            h.update(p.read_bytes())
    return h.hexdigest()


def main() -> None:
    parser = ScriptParser(description=__doc__.splitlines()[0])
    parser.add_argument("--walks", type=int, default=40)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="runs/validate_sim")
    parser.add_argument("--every", type=int, default=10, help="frames between surface checks")
    args = parser.parse_args()
    out = Path(args.out)
    slip_and_imu(args.walks, args.seed)
    realism_gait.report(realism_gait.measure(seed=args.seed))  # gait values vs speed
    realism_depth.report(realism_depth.measure())  # depth error vs distance, plane fit
    realism_imu.main(seeds=2)  # shocks, wobble, IMU errors, frame timing, strapdown
    realism_tags.report()  # tags decoded at 640×480 / 1280×800, area-sampling check
    realism_blur.report()  # blur length vs image speed × exposure time

    cfg = load_config(SimConfig, ROOT / "configs" / "sim" / "default.yaml")
    start = time.perf_counter()
    workers = default_workers()
    result = simulate_session(cfg, args.seed, out / "default", overwrite=True, workers=workers)
    elapsed = time.perf_counter() - start
    print(
        f"[speed] default session: {result.n_frames} frames 640×480 in {elapsed:.1f} s = "
        f"{result.n_frames / elapsed:.2f} frames/s end to end with {workers} render worker(s) "
        f"and a PNG writer thread on {os.cpu_count()} CPUs (gait, render, sensor, PNG, truth)"
    )
    checks = result.marker_checks
    visible = 100 * checks["visible_marker_fraction"]
    on_label = 100 * checks["visible_marker_on_foot_label"]
    print(
        f"[markers] visible in {visible:.1f} % of frame-sides; on a foot label of the right "
        f"side in {on_label:.2f} % of those (criterion ≥ 99 %)"
    )
    session = SessionFolder(out / "default")
    print(f"[reader] session reader accepts it: {len(session)} frames, {len(session.imu)} IMU")
    surface_checks(cfg, args.seed, out / "default", args.every)

    tiny = load_config(SimConfig, ROOT / "configs" / "sim" / "tiny.yaml")
    a = simulate_session(tiny, 11, out / "tiny_a", overwrite=True).path
    b = simulate_session(tiny, 11, out / "tiny_b", overwrite=True).path
    c = simulate_session(tiny, 12, out / "tiny_c", overwrite=True).path
    print(
        f"[determinism] same seed identical bytes: {digest(a) == digest(b)}; "
        f"different seed differs: {digest(a) != digest(c)}"
    )


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
