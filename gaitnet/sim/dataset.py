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
    DIR/preview.png         RGB | depth | labels of the first ``output.preview_frames`` frames
    DIR/dataset_config.yaml the resolved simulator config (the keys that act, see below)

Each frame is one simulated world (:func:`gaitnet.sim.scene_setup.build_scene`, the same set-up
as a whole session, from the frame's own seed) seen at a random time inside the walking phase,
so every ``subject``, ``gait``, ``camera`` (but ``fps``), ``mount`` (but the IMU's pose),
``scene`` (but ``exposure_drift``), ``sensor``, ``output.preview_frames`` and
``output.compress_frames`` (images and depth stored uncompressed by default) key acts as in
``gaitnet simulate``; ``mount.pitch_deg`` given as a range ``[lo, hi]`` is drawn per frame
(``pitch_range_deg`` replaces it: the command's ``--pitch-min/--pitch-max``).

Keys that mean nothing for single frames (:data:`SINGLE_FRAME_UNUSED`: the frame rate, the IMU,
the IMU's pose in the camera, the exposure drift over a session, the ``timing`` section
(timestamp jitter, dropped frames, camera–IMU offset), ``output.labels`` — a
segmentation data set always has labels) are refused with a :class:`~gaitnet.errors.
ConfigError` when they differ from their defaults, and left out of ``dataset_config.yaml``.

The folder is written through :func:`gaitnet.io.atomic.staged_folder`: it appears at ``DIR``
only when complete; an exception leaves nothing, and a killed run's staging folder is removed
by the next run.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray

from gaitnet.config import config_to_dict
from gaitnet.errors import ConfigError, InputError
from gaitnet.io.atomic import atomic_write_text, check_output_folder, staged_folder
from gaitnet.io.contact_sheet import colourise_depth, colourise_labels, contact_sheet, write_png
from gaitnet.io.images import depth_to_units, encode_png
from gaitnet.io.labelme_io import labelme_document, labels_txt
from gaitnet.segmentation.folder_files import camera_yaml_text
from gaitnet.sim.config import SimConfig
from gaitnet.sim.render_types import F32, RenderResult
from gaitnet.sim.rig import PITCH_RANGE_DEG
from gaitnet.sim.scene_setup import SimScene, build_scene, check_seed, rng_streams
from gaitnet.sim.sensor_model import apply_sensor, auto_exposure

log = logging.getLogger(__name__)

Progress = Callable[[Iterable, int], Iterable]

MAX_FRAMES = 1_000_000  # frame ids have six digits
DEPTH_SCALE_M = 0.001
WALKING_MARGIN_S = 0.5  # frames are drawn this far inside the walking phase

#: Config keys without meaning for single frames, and why (refused unless at their defaults).
SINGLE_FRAME_UNUSED: dict[str, str] = {
    "camera.fps": "single frames have no frame rate",
    "imu": "single frames have no IMU",
    "mount.imu_in_camera_m": "single frames have no IMU",
    "mount.imu_rpy_deg": "single frames have no IMU",
    "scene.exposure_drift": "the drift is over a session; each frame draws its exposure from "
    "scene.exposure_range",
    "output.labels": "a segmentation data set always has label maps",
    "timing": "frame timestamps, dropped frames and the camera-IMU offset belong to a session",
    "motion": "single frames are drawn from generated walks (play a clip with gaitnet simulate)",
}


@dataclass(frozen=True)
class DatasetResult:
    path: Path
    n_frames: int
    label_fractions: dict[str, float]


@dataclass(frozen=True, eq=False)
class DatasetFrame:
    """One simulated frame: its world, time, camera matrix and pose, the noise-free render
    (labels, true depth) and what the camera delivers (8-bit RGB, depth in metres, 0 =
    invalid)."""

    scene: SimScene
    t_s: float
    K: np.ndarray
    T_WfromC: np.ndarray
    render: RenderResult
    rgb: NDArray[np.uint8]
    depth_m: F32

    def gravity_C(self) -> np.ndarray:
        """Unit gravity direction (pointing down) in the camera frame."""
        return self.T_WfromC[:3, :3].T @ np.array([0.0, 0.0, -1.0])


def frame_seed(seed: int, index: int) -> int:
    """The seed of frame ``index`` of a data set seeded with ``seed`` (< 2**32)."""
    return int(np.random.SeedSequence([seed, index]).generate_state(1)[0])


def _lookup(tree: dict[str, Any], dotted: str) -> Any:
    node: Any = tree
    for part in dotted.split("."):
        node = node[part]
    return node


def _differing_keys(value: Any, default: Any, prefix: str) -> list[str]:
    if isinstance(value, dict):
        return [
            key
            for name in value
            for key in _differing_keys(value[name], default[name], f"{prefix}.{name}")
        ]
    return [] if value == default else [prefix]


def check_single_frame_config(cfg: SimConfig) -> None:
    """Refuse keys in :data:`SINGLE_FRAME_UNUSED` that differ from their defaults."""
    given, default = config_to_dict(cfg), config_to_dict(SimConfig())
    for dotted, why in SINGLE_FRAME_UNUSED.items():
        keys = _differing_keys(_lookup(given, dotted), _lookup(default, dotted), dotted)
        if keys:
            value = _lookup(given, keys[0])
            raise ConfigError(
                f"config key '{keys[0]}' (= {value!r}) has no effect in simulate-dataset "
                f"({why}); remove it"
            )


def resolved_dataset_config(cfg: SimConfig) -> dict[str, Any]:
    """The config as plain data without the keys single frames do not use."""
    data = config_to_dict(cfg)
    for dotted in SINGLE_FRAME_UNUSED:
        *parents, last = dotted.split(".")
        node = data
        for part in parents:
            node = node[part]
        del node[last]
    return data


def simulate_frame(
    cfg: SimConfig, seed: int, index: int = 0, t_s: float | None = None
) -> DatasetFrame:
    """Frame ``index`` of the data set seeded ``seed`` (``t_s`` fixes its time instead of
    drawing it inside the walking phase)."""
    rngs = rng_streams(frame_seed(seed, index))
    scene = build_scene(cfg, rngs)
    walk = scene.walk
    lo = cfg.gait.stand_start_s + WALKING_MARGIN_S
    hi = walk.duration_s - cfg.gait.stand_end_s - WALKING_MARGIN_S
    t = float(rngs["gait"].uniform(lo, hi)) if t_s is None else float(t_s)
    T_WfromC = scene.T_WfromC(np.array([t]))[0]
    result = scene.render(cfg.camera, t, T_WfromC)
    exposure = auto_exposure(result.rgb_linear) * scene.exposure_gain
    exposure_s = cfg.camera.exposure_time_s(exposure)
    if exposure_s > 0:  # motion blur over the exposure time that brightness asks for
        result = scene.render(cfg.camera, t, T_WfromC, exposure_s)
    K = cfg.camera.intrinsics().K
    rgb, depth = apply_sensor(
        result, K, rngs["sensor"], cfg.sensor, exposure, rngs["depth"], scene.depth_unit
    )
    return DatasetFrame(scene, t, K, T_WfromC, result, rgb, depth)


def _check_arguments(
    cfg: SimConfig, n_frames: int, pitch_range_deg: tuple[float, float] | None
) -> SimConfig:
    if isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer)):
        raise InputError(f"--n (number of frames) must be an integer, got {n_frames!r}")
    if not 1 <= n_frames <= MAX_FRAMES:
        raise InputError(f"--n (number of frames) must be within 1–{MAX_FRAMES}, got {n_frames}")
    check_single_frame_config(cfg)
    if pitch_range_deg is None:
        return cfg
    lo, hi = (float(v) for v in pitch_range_deg)
    a, b = PITCH_RANGE_DEG
    if not (a <= lo <= hi <= b):
        raise InputError(
            f"--pitch-min/--pitch-max must satisfy {a:g} ≤ min ≤ max ≤ {b:g}°, got {lo:g}, {hi:g}"
        )
    return replace(cfg, mount=replace(cfg.mount, pitch_deg=(lo, hi)))


def simulate_dataset(
    cfg: SimConfig,
    n_frames: int,
    seed: int,
    out_dir: str | Path,
    pitch_range_deg: tuple[float, float] | None = None,
    labelme: bool = False,
    overwrite: bool = False,
    progress: Progress | None = None,
) -> DatasetResult:
    """Write ``n_frames`` labelled frames (module docstring).

    ``pitch_range_deg`` (None: ``mount.pitch_deg``) replaces the config's pitch by a range
    drawn per frame. Bad values (``n_frames`` outside 1–1000000, a seed outside [0, 2**32), a
    pitch range outside 10–89°, keys without meaning for single frames, an output path that is
    a file or a non-empty folder without ``overwrite``) raise a
    :class:`~gaitnet.errors.GaitnetError` before anything is written.
    """
    seed = check_seed(seed, "--seed")
    cfg = _check_arguments(cfg, n_frames, pitch_range_deg)
    rows = [
        "id,gravity_cx,gravity_cy,gravity_cz,camera_height_m,pitch_deg,floor_family,"
        "subject_height_m"
    ]
    counts = np.zeros(3)
    preview_rows: list[list[np.ndarray]] = []
    captions: list[str] = []
    check_output_folder(out_dir, overwrite)
    with staged_folder(out_dir, overwrite) as staging:
        for sub in ("images", "depth", "labels", "instances"):
            (staging / sub).mkdir()
        indices: Iterable[int] = range(n_frames)
        if progress is not None:  # only now: a progress bar must not precede an early error
            indices = progress(indices, n_frames)
        compress = cfg.output.compress_frames
        for i in indices:
            frame = simulate_frame(cfg, seed, i)
            label, instance = frame.render.label, frame.render.instance
            name = f"{i:06d}"
            (staging / "images" / f"{name}.png").write_bytes(encode_png(frame.rgb, compress))
            (staging / "depth" / f"{name}.png").write_bytes(
                encode_png(depth_to_units(frame.depth_m, DEPTH_SCALE_M), compress)
            )
            (staging / "labels" / f"{name}.png").write_bytes(encode_png(label))
            (staging / "instances" / f"{name}.png").write_bytes(encode_png(instance))
            if labelme:
                doc = labelme_document(label, instance, f"{name}.png")
                (staging / "images" / f"{name}.json").write_text(json.dumps(doc, indent=1))
            g = frame.gravity_C()
            scene = frame.scene
            rows.append(
                f"{name},{g[0]:.9f},{g[1]:.9f},{g[2]:.9f},{frame.T_WfromC[2, 3]:.6f},"
                f"{scene.pitch_deg:.4f},{scene.floor_family},{scene.subject.height_m:.4f}"
            )
            counts += np.bincount(label.ravel(), minlength=3)[:3]
            if len(preview_rows) < cfg.output.preview_frames:
                preview_rows.append(
                    [frame.rgb, colourise_depth(frame.depth_m), colourise_labels(label)]
                )
                captions.append(f"{name}: {scene.floor_family}, {scene.pitch_deg:.0f}°")
        atomic_write_text(staging / "frames.csv", "\n".join(rows) + "\n")
        atomic_write_text(staging / "labels.txt", labels_txt())
        camera = camera_yaml_text(cfg.camera.intrinsics(), DEPTH_SCALE_M)
        atomic_write_text(staging / "camera.yaml", camera)
        header = (
            f"# gaitnet simulate-dataset --config <this file> --seed {seed} --n {n_frames}"
            f"{' --labelme' if labelme else ''} reproduces this data set\n"
        )
        atomic_write_text(
            staging / "dataset_config.yaml",
            header + yaml.safe_dump(resolved_dataset_config(cfg), sort_keys=False),
        )
        if preview_rows:
            write_png(staging / "preview.png", contact_sheet(preview_rows, captions))
    total = counts.sum()
    if counts[1] + counts[2] == 0:
        log.warning(
            "%s: no foot or leg pixel in any frame; check mount.pitch_deg / yaw_deg / roll_deg "
            "and the camera intrinsics",
            out_dir,
        )
    fractions = {
        name: float(c / total)
        for name, c in zip(("background", "foot", "leg"), counts, strict=True)
    }
    return DatasetResult(Path(out_dir), n_frames, fractions)
