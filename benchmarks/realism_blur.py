"""Motion blur of simulated frames (issue 8, item 3): a measurement.

1. Known answer: a synthetic foot (a white patch labelled as the left shoe, on a black floor
   1 m below a camera looking straight down) moves during the exposure by a known amount; the
   blur length measured in the image (the extent of the linear coverage ramps on each side of
   the patch) is compared with the image displacement ``f · Δ / z``, the image speed times the
   exposure time.
2. A default session (before: no blur): the exposure times the auto-exposure chose
   (``groundtruth/exposure.csv``), and the swinging foot's image speed times that exposure
   time — the blur length of the feet on the frames — per frame.

Importable (:func:`synthetic_foot_blur`, :func:`known_answer`, :func:`session_blur`) and
runnable on its own::

    python benchmarks/realism_blur.py [--seed 0]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

from dataclasses import replace  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from gaitnet.geometry import make_T, project  # noqa: E402
from gaitnet.sim.config import SimConfig  # noqa: E402
from gaitnet.sim.render_motion import Motion, motion_blur  # noqa: E402
from gaitnet.sim.render_types import camera_rays  # noqa: E402
from gaitnet.sim.scene import INSTANCE_LEFT, LABEL_FOOT, BodyState, ShoeState  # noqa: E402
from gaitnet.sim.scene_setup import build_scene, rng_streams  # noqa: E402
from gaitnet.sim.sensor_model import auto_exposure  # noqa: E402
from gaitnet.training.scripts import ScriptParser  # noqa: E402

F = 300.0  # focal length of the synthetic camera [px]
SIZE = (200, 160)  # width, height
PATCH = (60, 40)  # patch width, height [px]


def synthetic_foot_blur(displacement_px: float) -> tuple[np.ndarray, np.ndarray]:
    """(blurred, sharp) grey images of the synthetic foot moving ``displacement_px`` along the
    image x axis during the exposure (camera at 1 m looking straight down at the floor)."""
    w, h = SIZE
    K = np.array([[F, 0.0, (w - 1) / 2], [0.0, F, (h - 1) / 2], [0.0, 0.0, 1.0]])
    # camera: x = world x, y = −world y, z = −world z (looking down), 1 m above the floor
    T = make_T(np.diag([1.0, -1.0, -1.0]), np.array([0.0, 0.0, 1.0]))
    depth = np.full((h, w), 1.0, np.float32)
    label = np.zeros((h, w), np.uint8)
    u0, v0 = (w - PATCH[0]) // 2, (h - PATCH[1]) // 2
    label[v0 : v0 + PATCH[1], u0 : u0 + PATCH[0]] = LABEL_FOOT
    instance = np.where(label > 0, INSTANCE_LEFT, 0).astype(np.uint8)
    rgb = np.repeat((label > 0).astype(np.float32)[..., None], 3, axis=2)
    env = np.zeros_like(rgb)
    shoe = ShoeState("left", np.eye(3), np.zeros(3), 0.28, 0.1, 0.08)
    half = displacement_px / F / 2  # metres moved in the exposure's second half at 1 m
    shoe_end = replace(shoe, p_SoleCentre_W=np.array([half, 0.0, 0.0]))
    body, body_end = BodyState((), (shoe,)), BodyState((), (shoe_end,))
    m = Motion(T, body, T, body_end)
    out = motion_blur(rgb, env, depth, label, instance, camera_rays(K, w, h), K, m)
    return out[..., 0], rgb[..., 0]


def blur_length(img: np.ndarray) -> float:
    """Blur length [px] along x of a blurred white patch: the coverage ramps on both sides of
    the centre row, 10–90 % each (a box blur of length L gives ramps 0.8 L long)."""
    row = img[img.shape[0] // 2]
    ramp = int(((row > 0.1) & (row < 0.9)).sum())
    return ramp / 2 / 0.8


def known_answer(displacements=(0.0, 5.0, 10.0, 20.0, 40.0)) -> list[tuple[float, float]]:
    """(expected, measured) blur length [px] of the synthetic foot."""
    return [(d, blur_length(synthetic_foot_blur(d)[0])) for d in displacements]


def session_blur(seed: int = 0) -> dict:
    """Exposure times and the feet's blur lengths over the frames of a default world
    (computed from the true motion: image speed of the shoe centres × exposure time)."""
    cfg = SimConfig()
    scene = build_scene(cfg, rng_streams(seed))
    cam = cfg.camera
    K = cam.intrinsics().K
    t = np.arange(0.05, scene.walk.duration_s - 0.05, 1 / cam.fps)
    T_WfromC = scene.T_WfromC(t)
    dt = 1e-3
    T_next = scene.T_WfromC(t + dt)
    c0, c1 = scene.walk.sole_centres(t), scene.walk.sole_centres(t + dt)
    speeds = np.zeros((len(t), 2))
    for k in range(len(t)):
        for s in range(2):
            a = project(K, (np.linalg.inv(T_WfromC[k]) @ np.append(c0[k, s], 1.0))[None, :3])
            b = project(K, (np.linalg.inv(T_next[k]) @ np.append(c1[k, s], 1.0))[None, :3])
            speeds[k, s] = np.linalg.norm(b[0] - a[0]) / dt
    res = scene.render(cam, float(t[0]), T_WfromC[0])
    exposure = auto_exposure(res.rgb_linear) * scene.exposure_gain
    exposure_s = cam.exposure_time_s(exposure)
    fast = speeds.max(axis=1)
    return {
        "exposure_s": exposure_s,
        "foot_speed_px_s_p95": float(np.percentile(fast, 95)),
        "foot_blur_px_p50": float(np.percentile(fast * exposure_s, 50)),
        "foot_blur_px_p95": float(np.percentile(fast * exposure_s, 95)),
        "foot_blur_px_max": float(fast.max() * exposure_s),
    }


def report(seeds: int = 3) -> None:
    """The figures for the validation report (benchmarks/validate_sim.py)."""
    print("\n== Motion blur (synthetic foot: expected vs measured blur length, px) ==")
    for exp, got in known_answer():
        print(f"  image displacement {exp:5.1f} px -> measured blur {got:5.1f} px")
    print("== Motion blur in default worlds (exposure from the auto-exposure) ==")
    for seed in range(seeds):
        s = session_blur(seed)
        print(f"  seed {seed}: exposure {1e3 * s['exposure_s']:.1f} ms; swinging foot blur "
              f"median {s['foot_blur_px_p50']:.1f} px, p95 {s['foot_blur_px_p95']:.1f} px, "
              f"max {s['foot_blur_px_max']:.1f} px (before: 0 px)")  # fmt: skip


def main() -> None:
    ap = ScriptParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args()
    cv2.setNumThreads(1)
    report(args.seeds)


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
