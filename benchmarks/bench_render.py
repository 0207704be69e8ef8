"""Single-thread speed of the realistic renderer + D455 sensor model at 640×480.

Renders a plausible waist-camera scene (camera 1 m high on the front of the pelvis pitched
50° down, both trouser legs and both shoes in view, tile floor with an AprilTag sheet and some
clutter) while the subject walks forward, prints frames/s and per-stage milliseconds, and
saves an example (RGB | depth | labels) to ``docs/img/render_example.png``.

With ``--session``: the whole default session (``configs/sim/default.yaml``) through
``simulate_session`` with 1 and 2 worker processes (frames/s end to end, best of ``--repeat``
runs: other processes on the machine only slow runs down), and where the time goes — CPU
milliseconds per frame of every stage of a frame (render parts, motion blur, sensor colour and
depth, PNG encoding of colour, depth and label maps), measured on one thread over every 4th
frame of the same session.

    python benchmarks/bench_render.py [--frames 30] [--family tiles] [--pitch 50]
    python benchmarks/bench_render.py --session [--repeat 3] [--workers 1 2]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from gaitnet.geometry import make_T, so3_exp  # noqa: E402
from gaitnet.io.types import AprilTagBoard  # noqa: E402
from gaitnet.sim.clutter import make_clutter  # noqa: E402
from gaitnet.sim.floor import make_floor  # noqa: E402
from gaitnet.sim.render import Lighting, render_frame  # noqa: E402
from gaitnet.sim.scene import Appearance, BodyState, LegSegment, ShoeState  # noqa: E402
from gaitnet.sim.sensor_model import SensorNoiseConfig, apply_sensor, auto_exposure  # noqa: E402
from gaitnet.training.scripts import ScriptParser  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

R_PfromC_LEVEL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
K = np.array([[385.0, 0.0, 319.5], [0.0, 385.0, 239.5], [0.0, 0.0, 1.0]])
THIGH, SHANK = 0.43, 0.43
SHOE = (0.29, 0.105, 0.085)  # length, width, height
ANKLE_IN_SHOE = np.array([-0.074, 0.0, 0.092])
APPEARANCE = Appearance((0.035, 0.06, 0.16), (0.42, 0.04, 0.035), (0.8, 0.8, 0.78))


def _rot(axis: int, angle: float) -> np.ndarray:
    v = np.zeros(3)
    v[axis] = angle
    return so3_exp(v)


def camera_pose(x: float, pitch_deg: float) -> np.ndarray:
    """Camera on the belly (pelvis at x, 0.95 m; camera 0.14 m ahead, 1.0 m high)."""
    R = _rot(1, np.deg2rad(pitch_deg)) @ R_PfromC_LEVEL
    return make_T(R, np.array([x + 0.14, 0.0, 1.0]))


def _knee(hip: np.ndarray, ankle: np.ndarray) -> np.ndarray:
    """Two-link IK, knee bending forward (+x)."""
    d = ankle - hip
    dist = min(float(np.linalg.norm(d)), THIGH + SHANK - 1e-3)
    u = d / np.linalg.norm(d)
    a = (THIGH**2 - SHANK**2 + dist**2) / (2 * dist)
    h = np.sqrt(max(THIGH**2 - a**2, 0.0))
    perp = np.array([1.0, 0.0, 0.0]) - u * u[0]
    return hip + u * a + perp / np.linalg.norm(perp) * h


def _shoe(
    side: str, x: float, y: float, yaw: float, toe_down: float
) -> tuple[ShoeState, np.ndarray]:
    """A shoe resting on its toe (``toe_down`` > 0) or heel (< 0), and its ankle point."""
    L, W, H = SHOE
    R = _rot(2, yaw) @ _rot(1, toe_down)
    c = np.array([x, y, 0.5 * L * abs(np.sin(toe_down))])
    return ShoeState(side, R, c, L, W, H), R @ ANKLE_IN_SHOE + c


def body_at(x: float, phase: float) -> BodyState:
    """Both feet ahead of the pelvis (at x): left near heel strike, right in mid swing."""
    sway = 0.04 * np.sin(phase)
    shoe_l, ankle_l = _shoe("left", x + 0.46 + sway, 0.10, 0.06, np.deg2rad(-6))
    shoe_r, ankle_r = _shoe("right", x + 0.36 - sway, -0.17, -0.15, np.deg2rad(14))
    legs = []
    for side, y, ankle in (("left", 0.09, ankle_l), ("right", -0.09, ankle_r)):
        hip = np.array([x - 0.02, y, 0.9])
        knee = _knee(hip, ankle)
        legs.append(LegSegment(side, "thigh", hip, knee, 0.085, 0.062))
        legs.append(LegSegment(side, "shank", knee, ankle, 0.057, 0.045))
    return BodyState(tuple(legs), (shoe_l, shoe_r))


def build_world(family: str, seed: int):
    rng = np.random.default_rng(seed)
    extent = ((-2.0, 18.0), (-2.0, 2.0))
    board = AprilTagBoard("start", "tag36h11", 5, 7, 0.045, 0.013, 0,
                          make_T(_rot(2, 0.25), np.array([1.3, 0.35, 0.0])))  # fmt: skip
    floor = make_floor(family, rng, extent, boards=(board,))
    clutter = make_clutter(rng, extent, n=8)
    return floor, clutter


def colour_depth(depth: np.ndarray, max_m: float = 4.0) -> np.ndarray:
    d = np.where(np.isfinite(depth), depth, 0.0)
    img = cv2.applyColorMap(np.clip(d / max_m * 255, 0, 255).astype(np.uint8), cv2.COLORMAP_TURBO)
    img[d <= 0] = 0
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def colour_labels(label: np.ndarray, instance: np.ndarray) -> np.ndarray:
    out = np.zeros((*label.shape, 3), np.uint8)
    palette = {(1, 1): (255, 60, 60), (1, 2): (255, 170, 40), (2, 1): (40, 120, 255),
               (2, 2): (40, 220, 200)}  # fmt: skip
    for (lab, ins), rgb in palette.items():
        out[(label == lab) & (instance == ins)] = rgb
    return out


def session_speed(workers: tuple[int, ...] = (1, 2), repeat: int = 3, seed: int = 0) -> dict:
    """Best frames/s of the default session end to end per number of workers."""
    import tempfile

    from gaitnet.config import load_config
    from gaitnet.sim.config import SimConfig
    from gaitnet.sim.session import simulate_session

    cfg = load_config(SimConfig, ROOT / "configs" / "sim" / "default.yaml")
    best: dict[int, float] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(repeat):
            for w in workers:
                t0 = time.perf_counter()
                r = simulate_session(cfg, seed, Path(tmp) / f"w{w}", overwrite=True, workers=w)
                best[w] = max(best.get(w, 0.0), r.n_frames / (time.perf_counter() - t0))
    return best


def session_stages(seed: int = 0, every: int = 4) -> tuple[dict[str, float], int]:
    """CPU ms per frame of each stage of the default session's frames (one thread)."""
    from gaitnet.config import load_config
    from gaitnet.io.images import depth_to_units, encode_png
    from gaitnet.sim.config import SimConfig
    from gaitnet.sim.render_motion import Motion
    from gaitnet.sim.scene_setup import build_scene, rng_streams
    from gaitnet.sim.sensor_depth import depth_image
    from gaitnet.sim.sensor_model import _colour
    from gaitnet.sim.session import marker_pixel_checks

    cfg = load_config(SimConfig, ROOT / "configs" / "sim" / "default.yaml")
    scene = build_scene(cfg, rng_streams(seed))
    cam = cfg.camera
    K = cam.intrinsics().K
    times = np.arange(0.05, scene.walk.duration_s - 0.05, 1 / cam.fps)[::every]
    T_all = scene.T_WfromC(times)
    exposure = 1.0
    acc: dict[str, float] = {}

    def lap(name: str, t0: float) -> float:
        t1 = time.thread_time()
        acc[name] = acc.get(name, 0.0) + t1 - t0
        return t1

    for k, t in enumerate(times):
        t_exp = cam.exposure_time_s(exposure)
        t0 = time.thread_time()
        body = scene.walk.body_state(t)
        t0 = lap("body state", t0)
        t_end = t + t_exp / 2
        motion = Motion(T_all[k], body, scene.T_WfromC(np.array([t_end]))[0],
                        scene.walk.body_state(t_end))  # fmt: skip
        lap("blur: end-of-exposure state", t0)
        stages: dict[str, float] = {}
        res = render_frame(K, cam.width, cam.height, T_all[k], scene.floor, body,
                           scene.appearance, scene.clutter, scene.light, timings=stages,
                           relief=scene.relief, motion=motion)  # fmt: skip
        for name, sec in stages.items():
            acc[f"render {name}"] = acc.get(f"render {name}", 0.0) + sec
        t0 = time.thread_time()
        exposure = auto_exposure(res.rgb_linear) * scene.exposure_gain
        t0 = lap("auto-exposure", t0)
        rgb = _colour(res.rgb_linear, K, np.random.default_rng(k), cfg.sensor, exposure)
        t0 = lap("sensor colour", t0)
        depth = depth_image(res, K, np.random.default_rng(k), cfg.sensor, scene.depth_unit)
        t0 = lap("sensor depth", t0)
        marker_pixel_checks(scene.walk, t, T_all[k], K, res.depth_m, res.label, res.instance)
        t0 = lap("marker checks", t0)
        encode_png(rgb, cfg.output.compress_frames)
        t0 = lap("PNG colour", t0)
        encode_png(depth_to_units(depth, 0.001), cfg.output.compress_frames)
        t0 = lap("PNG depth", t0)
        encode_png(res.label)
        encode_png(res.instance)
        lap("PNG labels + instances", t0)
    n = len(times)
    return {name: 1000 * sec / n for name, sec in acc.items()}, n


def session_main(args: argparse.Namespace) -> None:
    stages, n = session_stages(args.seed)
    print(f"default session, where the time goes (CPU ms/frame on one thread, {n} frames):")
    for name, ms in stages.items():
        print(f"  {name:30s} {ms:6.1f}")
    print(f"  {'total':30s} {sum(stages.values()):6.1f}")
    speed = session_speed(tuple(args.workers), args.repeat, args.seed)
    for w, fps in speed.items():
        print(f"default session end to end, {w} worker(s): {fps:5.1f} frames/s "
              f"(best of {args.repeat}; {os.cpu_count()} CPUs)")  # fmt: skip


def main() -> None:
    ap = ScriptParser(description=__doc__.splitlines()[0])
    ap.add_argument("--session", action="store_true", help="the whole default session")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--family", default="tiles")
    ap.add_argument("--pitch", type=float, default=50.0)
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--out", default="docs/img/render_example.png")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    if args.session:
        session_main(args)
        return

    t0 = time.perf_counter()
    floor, clutter = build_world(args.family, args.seed)
    print(f"floor '{args.family}' 20x4 m: {time.perf_counter() - t0:.2f} s, "
          f"{floor.nbytes / 1e6:.0f} MB")  # fmt: skip
    light, cfg = Lighting(), SensorNoiseConfig()
    rng = np.random.default_rng(args.seed)
    timings: dict[str, float] = {}
    exposure = None
    sensor_s = 0.0
    render_frame(
        K,
        640,
        480,
        camera_pose(0.0, args.pitch),
        floor,
        body_at(0.0, 0.0),
        APPEARANCE,
        clutter,
        light,
    )  # fmt: skip  (warm caches)
    wall0, cpu0 = time.perf_counter(), time.thread_time()
    for i in range(args.frames):
        x = 1.3 * i / 30.0
        res = render_frame(K, 640, 480, camera_pose(x, args.pitch), floor, body_at(x, i * 0.2),
                           APPEARANCE, clutter, light, timings=timings)  # fmt: skip
        t1 = time.thread_time()
        exposure = exposure or auto_exposure(res.rgb_linear)
        rgb, depth = apply_sensor(res, K, rng, cfg, exposure)
        sensor_s += time.thread_time() - t1
    wall, cpu = time.perf_counter() - wall0, time.thread_time() - cpu0
    n = args.frames
    print(f"{n} frames 640x480 on one thread (render + sensor model):")
    print(f"  CPU time : {n / cpu:5.1f} frames/s ({1000 * cpu / n:.1f} ms/frame)")
    print(f"  wall time: {n / wall:5.1f} frames/s ({1000 * wall / n:.1f} ms/frame; "
          "higher when other processes share the core)")  # fmt: skip
    print("per stage (CPU ms/frame):")
    for name, sec in {**timings, "sensor": sensor_s}.items():
        print(f"  {name:12s} {1000 * sec / n:6.1f}")

    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    row = np.hstack([rgb, colour_depth(depth), colour_labels(res.label, res.instance)])
    cv2.imwrite(str(out), cv2.cvtColor(row, cv2.COLOR_RGB2BGR))
    print(f"example: {out}")


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
