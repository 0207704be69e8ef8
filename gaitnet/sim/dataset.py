"""Labelled segmentation frames from many random simulated subjects, floors and lightings.

``gaitnet simulate-dataset --config configs/sim/<name>.yaml --n N --seed S --out DIR`` writes::

    DIR/images/<id>.png     8-bit RGB (what the camera delivers)
    DIR/images/<id>.json    labelme polygons of the same frame (with --labelme)
    DIR/depth/<id>.png      16-bit depth in mm aligned to RGB, 0 = invalid
    DIR/labels/<id>.png     label map: 0 background, 1 foot, 2 leg
    DIR/instances/<id>.png  side map: 0 none, 1 left, 2 right
    DIR/frames.csv          id, gravity direction in the camera frame (unit, pointing down),
                            camera height above the floor, pitch, floor family, subject height
    DIR/camera.yaml         intrinsics (all frames share them)
    DIR/labels.txt          labelme class list (__ignore__, _background_, foot, leg)
    DIR/dataset_config.yaml the resolved simulator config

Each frame comes from its own random subject, walk, floor family, lighting, clutter and camera
pitch (uniform in ``pitch_range_deg``) at a random time inside the walking phase.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import yaml

from gaitnet.config import dump_config
from gaitnet.errors import SessionError
from gaitnet.geometry import make_T
from gaitnet.io.atomic import atomic_write_text
from gaitnet.io.images import depth_to_units, encode_png
from gaitnet.io.labelme_io import labelme_document, labels_txt
from gaitnet.sim.config import SimConfig
from gaitnet.sim.floor import FLOOR_FAMILIES, make_clutter, make_floor
from gaitnet.sim.gait import generate_walk
from gaitnet.sim.render import render_frame
from gaitnet.sim.sensor_model import apply_sensor, auto_exposure
from gaitnet.sim.session import floor_extent, rng_streams, sample_appearance, sample_lighting
from gaitnet.sim.subject import sample_subject

Progress = Callable[[Iterable, int], Iterable]


@dataclass(frozen=True)
class DatasetResult:
    path: Path
    n_frames: int
    label_fractions: dict[str, float]


def _frame_seed(seed: int, index: int) -> int:
    return int(np.random.SeedSequence([seed, index]).generate_state(1)[0])


def simulate_dataset(
    cfg: SimConfig,
    n_frames: int,
    seed: int,
    out_dir: str | Path,
    pitch_range_deg: tuple[float, float] = (55.0, 75.0),
    labelme: bool = False,
    overwrite: bool = False,
    progress: Progress | None = None,
) -> DatasetResult:
    """Write ``n_frames`` labelled frames (module docstring); atomic like a session folder."""
    if n_frames < 1:
        raise ValueError("n_frames must be at least 1")
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise SessionError(f"{out_dir}: output path exists and is not a folder")
    if out_dir.exists() and any(out_dir.iterdir()) and not overwrite:
        raise SessionError(f"{out_dir}: output exists and is not empty")
    staging = out_dir.parent / f".{out_dir.name}.partial"
    shutil.rmtree(staging, ignore_errors=True)
    for sub in ("images", "depth", "labels", "instances"):
        (staging / sub).mkdir(parents=True)
    cam = cfg.camera
    K = cam.intrinsics().K
    rows = [
        "id,gravity_cx,gravity_cy,gravity_cz,camera_height_m,pitch_deg,floor_family,"
        "subject_height_m"
    ]
    counts = np.zeros(3)
    indices: Iterable[int] = range(n_frames)
    if progress is not None:
        indices = progress(indices, n_frames)
    try:
        for i in indices:
            rngs = rng_streams(_frame_seed(seed, i))
            subject = sample_subject(rngs["subject"], cfg.subject.height_range_m)
            walk = generate_walk(subject, cfg.gait, rngs["gait"])
            room = rngs["room"]
            family = FLOOR_FAMILIES[int(room.integers(len(FLOOR_FAMILIES)))]
            extent = floor_extent(walk)
            floor = make_floor(
                family, room, extent, max(cfg.scene.texel_m, 0.004), (), room_height_m=2.8
            )
            clutter = make_clutter(room, extent, cfg.scene.clutter_count, path_y_m=0.0)
            appearance = sample_appearance(subject, floor, room, cfg.scene.shoe_like_floor_prob)
            light = sample_lighting(rngs["lighting"], True)
            pitch = float(rngs["lighting"].uniform(*pitch_range_deg))
            mount = replace(cfg.mount, pitch_deg=pitch)
            walking = (cfg.gait.stand_start_s + 0.5, walk.duration_s - cfg.gait.stand_end_s - 0.5)
            t = float(rngs["gait"].uniform(*walking))
            R_WP, p_P = walk.pelvis_pose(np.array([t]))
            T_WfromC = make_T(R_WP[0], p_P[0]) @ mount.T_PfromC()
            result = render_frame(
                K,
                cam.width,
                cam.height,
                T_WfromC,
                floor,
                walk.body_state(t),
                appearance,
                clutter,
                light,
            )
            exposure = auto_exposure(result.rgb_linear) * float(
                rngs["lighting"].uniform(*cfg.scene.exposure_range)
            )
            rgb, depth = apply_sensor(result, K, rngs["sensor"], cfg.sensor, exposure)
            name = f"{i:06d}"
            (staging / "images" / f"{name}.png").write_bytes(encode_png(rgb))
            (staging / "depth" / f"{name}.png").write_bytes(
                encode_png(depth_to_units(depth, 0.001))
            )
            (staging / "labels" / f"{name}.png").write_bytes(encode_png(result.label))
            (staging / "instances" / f"{name}.png").write_bytes(encode_png(result.instance))
            if labelme:
                doc = labelme_document(result.label, result.instance, f"{name}.png")
                (staging / "images" / f"{name}.json").write_text(json.dumps(doc, indent=1))
            gravity_C = T_WfromC[:3, :3].T @ np.array([0.0, 0.0, -1.0])
            rows.append(
                f"{name},{gravity_C[0]:.9f},{gravity_C[1]:.9f},{gravity_C[2]:.9f},"
                f"{T_WfromC[2, 3]:.6f},{pitch:.4f},{family},{subject.height_m:.4f}"
            )
            counts += np.bincount(result.label.ravel(), minlength=3)[:3]
        atomic_write_text(staging / "frames.csv", "\n".join(rows) + "\n")
        atomic_write_text(staging / "labels.txt", labels_txt())
        intr = cam.intrinsics()
        atomic_write_text(
            staging / "camera.yaml",
            yaml.safe_dump(
                {
                    "width": intr.width,
                    "height": intr.height,
                    "fx": intr.fx,
                    "fy": intr.fy,
                    "cx": intr.cx,
                    "cy": intr.cy,
                    "depth_scale_m": 0.001,
                },
                sort_keys=False,
            ),
        )
        atomic_write_text(
            staging / "dataset_config.yaml",
            f"# gaitnet simulate-dataset --seed {seed} --n {n_frames}\n" + dump_config(cfg),
        )
        if out_dir.exists():
            shutil.rmtree(out_dir)
        staging.rename(out_dir)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    total = counts.sum()
    fractions = {
        name: float(c / total)
        for name, c in zip(("background", "foot", "leg"), counts, strict=True)
    }
    return DatasetResult(out_dir, n_frames, fractions)
