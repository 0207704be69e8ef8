"""AprilTag decoding on simulated standing frames (issue 8, item 1): a measurement.

For the default world of a few seeds (one per floor family), the first standing frame of the
session (both feet behind the start sheet) is rendered through the D455 colour model and
decoded with ``cv2.aruco`` (``DICT_APRILTAG_36h11``, default ``DetectorParameters``):

* tags decoded per frame (of 35) and the largest distance of a decoded corner from the true
  projection of :func:`gaitnet.io.types.tag_corners_in_board`, at the default 640×480 and at the
  D455's native 1280×800 (same field of view: the 640×480 image is the 1280×800 one scaled by
  0.6 and cropped to the central 640 columns, as the device does), at several camera pitches and
  heights (camera heights come from the subject's height);
* the area-sampling check: the noise-free render at 1280×800, averaged over each 640×480
  pixel's footprint (``cv2.INTER_AREA`` in linear radiance, cropped), against the direct
  640×480 render — mean absolute difference in 8-bit sRGB grey levels over the sheet.

Importable (:func:`decode_table`, :func:`area_check`) and runnable on its own::

    python benchmarks/realism_tags.py [--seeds 5] [--pitches 55 70 80]

It works on the code before issue 8 too (``PYTHONPATH=<old tree>``) for before/after figures.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

from dataclasses import dataclass, replace  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from gaitnet.geometry import project  # noqa: E402
from gaitnet.io.types import AprilTagBoard, tag_corners_in_board  # noqa: E402
from gaitnet.sim.config import SimConfig  # noqa: E402
from gaitnet.sim.render_color import encode_srgb8  # noqa: E402
from gaitnet.sim.rig import CameraConfig  # noqa: E402
from gaitnet.sim.scene_setup import SimScene, build_scene, rng_streams  # noqa: E402
from gaitnet.sim.sensor_model import apply_sensor, auto_exposure  # noqa: E402
from gaitnet.training.scripts import ScriptParser  # noqa: E402

FAMILIES = ("tiles", "wood", "carpet", "concrete", "textureless")
SCALE_NATIVE = 0.6  # 1280×800 → 768×480, then the central 640 columns = the 640×480 mode
CROP_X = 64


def native_camera(cam: CameraConfig) -> CameraConfig:
    """The 1280×800 camera whose 0.6× area-downsampled, centre-cropped image is ``cam``'s."""
    s = SCALE_NATIVE
    return CameraConfig(
        width=1280,
        height=800,
        fx=cam.fx / s,
        fy=cam.fy / s,
        cx=(cam.cx + CROP_X + 0.5) / s - 0.5,
        cy=(cam.cy + 0.5) / s - 0.5,
        fps=cam.fps,
    )


def to_default_mode(img: np.ndarray) -> np.ndarray:
    """A 1280×800 image as the 640×480 mode sees it (area average, central crop)."""
    small = cv2.resize(img, (768, 480), interpolation=cv2.INTER_AREA)
    return small[:, CROP_X : CROP_X + 640]


@dataclass(frozen=True)
class Standing:
    """One world and the camera pose of its first standing frame."""

    scene: SimScene
    cfg: SimConfig
    T_WfromC: np.ndarray
    t_s: float


def standing_world(seed: int, family: str, pitch_deg: float, height_m: float | None) -> Standing:
    """The default world of ``seed`` with the given floor family, pitch and subject height."""
    cfg = SimConfig()
    cfg = replace(
        cfg,
        scene=replace(cfg.scene, floor_family=family),
        mount=replace(cfg.mount, pitch_deg=float(pitch_deg)),
        subject=replace(cfg.subject, height_m=height_m),
    )
    scene = build_scene(cfg, rng_streams(seed))
    t = 0.1
    return Standing(scene, cfg, scene.T_WfromC(np.array([t]))[0], t)


def render_colour(st: Standing, cam: CameraConfig, seed: int) -> tuple[np.ndarray, object]:
    """8-bit colour of the standing frame seen by ``cam`` (sensor model, fixed exposure rule)."""
    res = st.scene.render(cam, st.t_s, st.T_WfromC)
    exposure = auto_exposure(res.rgb_linear) * st.scene.exposure_gain
    rng = np.random.default_rng(seed)
    rgb, _ = apply_sensor(res, cam.intrinsics().K, rng, st.cfg.sensor, exposure)
    return rgb, res


def true_corners(
    board: AprilTagBoard, K: np.ndarray, T_WfromC: np.ndarray
) -> dict[int, np.ndarray]:
    """Projected (4, 2) corners of every tag of ``board``, aruco order."""
    T_CfromW = np.linalg.inv(T_WfromC)
    out = {}
    for tag_id in board.tag_ids:
        p_B = tag_corners_in_board(board, tag_id)
        p_W = p_B @ board.T_WfromBoard[:3, :3].T + board.T_WfromBoard[:3, 3]
        p_C = p_W @ T_CfromW[:3, :3].T + T_CfromW[:3, 3]
        uv, _ = project(K, p_C)
        out[tag_id] = uv
    return out


def detect(rgb: np.ndarray) -> dict[int, np.ndarray]:
    """``cv2.aruco`` tag36h11 detections with default parameters: id → (4, 2) corners."""
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    detector = cv2.aruco.ArucoDetector(dictionary, cv2.aruco.DetectorParameters())
    corners, ids, _ = detector.detectMarkers(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY))
    if ids is None:
        return {}
    return {int(i): c.reshape(4, 2) for i, c in zip(ids.ravel(), corners, strict=True)}


def decode_stats(
    rgb: np.ndarray, board: AprilTagBoard, K: np.ndarray, T_WfromC: np.ndarray
) -> tuple[int, int, int, float]:
    """(tags fully in view, decoded board tags, wrong ids, largest corner error [px])."""
    h, w = rgb.shape[:2]
    truth = true_corners(board, K, T_WfromC)
    in_view = [i for i, c in truth.items() if np.all((c >= 0) & (c <= [w - 1, h - 1]))]
    found = detect(rgb)
    good = [i for i in found if i in truth]
    wrong = len(found) - len(good)
    err = max((float(np.abs(found[i] - truth[i]).max()) for i in good), default=float("nan"))
    return len(in_view), len(good), wrong, err


def decode_row(seed: int, family: str, pitch: float, height_m: float | None) -> dict:
    """Decoding at 640×480 and 1280×800 for one world."""
    st = standing_world(seed, family, pitch, height_m)
    board = st.scene.boards[0]
    row = {"seed": seed, "family": family, "pitch": pitch,
           "cam_z": float(st.T_WfromC[2, 3])}  # fmt: skip
    for name, cam in (("640", st.cfg.camera), ("1280", native_camera(st.cfg.camera))):
        rgb, _ = render_colour(st, cam, seed)
        n_view, n_dec, wrong, err = decode_stats(rgb, board, cam.intrinsics().K, st.T_WfromC)
        row[name] = (n_view, n_dec, wrong, err)
    return row


def decode_table(
    seeds: int = 5, pitches: tuple[float, ...] = (55.0, 70.0, 80.0),
    heights: tuple[float | None, ...] = (1.55, 1.9),
) -> list[dict]:  # fmt: skip
    """Rows of :func:`decode_row` over seeds (floor families in turn), pitches and heights."""
    rows = []
    for k in range(seeds):
        for pitch in pitches:
            for h in heights:
                rows.append(decode_row(k, FAMILIES[k % len(FAMILIES)], pitch, h))
    return rows


def area_check(seed: int = 0, family: str = "tiles", pitch: float = 70.0) -> dict:
    """Noise-free render at 1280×800 area-averaged to 640×480 vs the direct 640×480 render,
    over the start sheet: mean and 95th-percentile absolute difference in sRGB grey levels,
    and the same for the old-style point-sampled comparison (nearest pixel of 1280×800)."""
    st = standing_world(seed, family, pitch, None)
    cam = st.cfg.camera
    direct = st.scene.render(cam, st.t_s, st.T_WfromC)
    big = st.scene.render(native_camera(cam), st.t_s, st.T_WfromC)
    down = to_default_mode(big.rgb_linear)
    grey = np.array([0.2126, 0.7152, 0.0722], np.float32)
    scale = 0.5 / max(float(np.percentile(direct.rgb_linear @ grey, 99)), 1e-6)
    g_direct = encode_srgb8(direct.rgb_linear @ grey * scale).astype(np.float32)
    g_down = encode_srgb8(down @ grey * scale).astype(np.float32)
    board = st.scene.boards[0]
    truth = true_corners(board, cam.intrinsics().K, st.T_WfromC)
    mask = np.zeros(g_direct.shape, np.uint8)
    for c in truth.values():
        cv2.fillConvexPoly(mask, np.round(c).astype(np.int32), 1)
    sel = mask.astype(bool) & (direct.label == 0)
    diff = np.abs(g_direct - g_down)[sel]
    contrast = np.percentile(g_direct[sel], 95) - np.percentile(g_direct[sel], 5)
    return {
        "pixels": int(sel.sum()),
        "mad": float(diff.mean()),
        "p95": float(np.percentile(diff, 95)),
        "contrast_direct": float(contrast),
        "contrast_down": float(np.percentile(g_down[sel], 95) - np.percentile(g_down[sel], 5)),
    }


def summarise(rows: list[dict]) -> None:
    """Print the decoding table and its totals."""
    print("seed family       pitch cam_z | 640x480: view dec wrong err_px | 1280x800: view dec "
          "wrong err_px")  # fmt: skip
    for r in rows:
        a, b = r["640"], r["1280"]
        print(f"{r['seed']:4d} {r['family']:12s} {r['pitch']:5.0f} {r['cam_z']:5.2f} | "
              f"{a[0]:4d} {a[1]:3d} {a[2]:5d} {a[3]:6.2f} | {b[0]:4d} {b[1]:3d} {b[2]:5d} "
              f"{b[3]:6.2f}")  # fmt: skip
    for name in ("640", "1280"):
        dec = np.array([r[name][1] for r in rows], float)
        view = np.array([r[name][0] for r in rows], float)
        wrong = sum(r[name][2] for r in rows)
        errs = np.array([r[name][3] for r in rows], float)
        print(f"{name}: decoded {dec.mean():.1f} of {view.mean():.1f} tags in view per frame "
              f"(min {dec.min():.0f}), wrong ids {wrong}, worst corner error "
              f"{np.nanmax(errs) if np.isfinite(errs).any() else float('nan'):.2f} px")  # fmt: skip


def report(seeds: int = 5) -> None:
    """The figures for the validation report (benchmarks/validate_sim.py)."""
    print("\n== AprilTags on standing frames (cv2.aruco tag36h11, default parameters) ==")
    rows = decode_table(seeds, pitches=(55.0, 70.0, 80.0), heights=(None,))
    summarise(rows)
    a = area_check()
    print(f"area check (1280x800 INTER_AREA -> 640x480 vs direct, sheet tags, {a['pixels']} px): "
          f"mean |diff| {a['mad']:.2f} grey levels, p95 {a['p95']:.1f}; tag contrast "
          f"(p95 - p5) direct {a['contrast_direct']:.0f}, "
          f"downsampled {a['contrast_down']:.0f}")  # fmt: skip


def main() -> None:
    ap = ScriptParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--pitches", type=float, nargs="+", default=[55.0, 70.0, 80.0])
    ap.add_argument("--heights", type=float, nargs="+", default=[1.55, 1.9])
    args = ap.parse_args()
    cv2.setNumThreads(1)
    summarise(decode_table(args.seeds, tuple(args.pitches), tuple(args.heights)))
    a = area_check()
    print(f"area check: {a}")


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
