"""Segment every frame of a recorded session (``gaitnet segment``, thesis sec. 4.1).

Per frame: the gravity direction in the camera frame (the accelerometer averaged over a window
centred on the frame, :func:`accelerometer_gravity_C`), HHA (:func:`~gaitnet.segmentation.hha.
hha_encode`, at the resolution the model's streams see: :func:`~gaitnet.segmentation.hha.
hha_stride`), the segmenter (onnxruntime, :class:`~gaitnet.segmentation.onnx_runtime.
OnnxSegmenter`), and the foot keypoints of sec. 4.1.4 (:func:`~gaitnet.segmentation.
postprocess.foot_keypoints`). Written into a staging folder that appears at the output path only
when complete (:func:`gaitnet.io.atomic.staged_folder`):

- ``labels/<t_ns>.png``: 8-bit label map per frame (0 background, 1 foot, 2 leg), the layout of a
  simulated session's ``groundtruth/labels/`` so ``gaitnet evaluate`` compares them: after the
  post-processing (foot pixels only where it kept a foot: the floor seen as foot at a foot's rim
  and blobs that fail the depth checks or lie beyond reach become background), or the
  network's own arg-max with :attr:`SegmentOptions.raw_labels`;
- ``keypoints.csv``: one row per frame, foot and keypoint (:data:`KEYPOINT_COLUMNS`);
- ``contact_sheet.png``: evenly spaced frames, RGB with the labels laid over it | label map;
- ``summary.json``: model, frames, feet seen, the foot blobs dropped as no foot by reason
  (``feet_dropped``: :data:`gaitnet.segmentation.postprocess.DROP_REASONS`), where the time
  went.

A session whose depth is not aligned to colour (``depth_aligned_to_color: false``) is refused
before anything is written (:func:`gaitnet.io.types.require_depth_aligned`): the keypoints read
the depth at the colour pixels of the labels.

The accelerometer's average is the gravity direction up to the walking accelerations that do
not cancel over the window (a few degrees at normal walking with a 1 s window); ``gaitnet
infer`` gives the filter's gravity instead.
"""

from __future__ import annotations

import csv
import io
import json
import logging
import time
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import numpy as np

from gaitnet.checks import check_int_range, check_positive
from gaitnet.errors import InputError
from gaitnet.io.atomic import staged_folder
from gaitnet.io.contact_sheet import colourise_labels, contact_sheet, write_png
from gaitnet.io.images import encode_png
from gaitnet.io.types import Frame, ImuSamples, SessionSource, require_depth_aligned
from gaitnet.segmentation.foot_types import FootDetection
from gaitnet.segmentation.hha import HhaParams, find_floor, hha_encode, hha_stride
from gaitnet.segmentation.midline import MidlineEstimate, pair_midpoint
from gaitnet.segmentation.onnx_runtime import OnnxSegmenter
from gaitnet.segmentation.postprocess import (
    FootKeypointParams,
    foot_keypoints,
    kept_feet_labels,
)

log = logging.getLogger(__name__)

__all__ = [
    "KEYPOINT_COLUMNS",
    "SegmentOptions",
    "SegmentResult",
    "DEFAULT_SEGMENTER",
    "accelerometer_gravity_C",
    "default_segmenter_path",
    "segment_session",
]

Progress = Callable[[Iterable, int], Iterable]

KEYPOINT_COLUMNS = ("t_ns", "side", "keypoint", "u", "v", "x_m", "y_m", "z_m", "depth_valid")
"""``keypoints.csv``: frame time, foot side (left / right / unknown), keypoint (top / mid /
bottom, eq. 4.1), pixel, camera-frame point [m] (empty where the depth is missing) and whether
it is valid."""


@dataclass(frozen=True)
class SegmentOptions:
    """Settings of ``gaitnet segment`` that are not the model's or the post-processing's."""

    gravity_window_s: float = 1.0
    """Accelerometer samples within ± half this window around a frame give its gravity [s]:
    about one stride, so the walking accelerations mostly cancel."""
    sheet_frames: int = 12
    """Frames on the contact sheet, evenly spaced over the session."""
    raw_labels: bool = False
    """Write the network's arg-max label maps instead of the post-processed ones (foot pixels
    only where the post-processing kept a foot:
    :func:`~gaitnet.segmentation.postprocess.kept_feet_labels`)."""

    def __post_init__(self) -> None:
        check_positive("gravity_window_s", self.gravity_window_s)
        check_int_range("sheet_frames", self.sheet_frames, 1, 100)


@dataclass
class SegmentResult:
    """What :func:`segment_session` wrote and measured."""

    path: Path
    n_frames: int
    frames_with_foot: int
    label_fractions: dict[str, float]
    timings_s: dict[str, float] = field(default_factory=dict)


def accelerometer_gravity_C(
    imu: ImuSamples, T_CfromI: np.ndarray, t_ns: int, window_s: float
) -> np.ndarray | None:
    """Unit gravity (pointing down) in the camera frame from the mean specific force within
    ``window_s`` centred on ``t_ns``; None when the window holds fewer than 5 samples.

    A still accelerometer reads ``-g`` (i.e. up); its mean over a stride is up to the residual
    walking accelerations. Rotated into the camera frame with ``T_CfromI``.
    """
    half = int(window_s * 0.5e9)
    lo, hi = np.searchsorted(imu.t_ns, [t_ns - half, t_ns + half])
    if hi - lo < 5:
        return None
    mean = imu.accel[lo:hi].mean(axis=0)
    norm = float(np.linalg.norm(mean))
    if not np.isfinite(norm) or norm < 1e-6:
        return None
    return -(np.asarray(T_CfromI)[:3, :3] @ (mean / norm))


def _overlay(rgb: np.ndarray, labels: np.ndarray, feet: list) -> np.ndarray:
    """RGB with the label colours blended over feet and legs, and the keypoints drawn."""
    out = rgb.copy()
    mask = labels > 0
    out[mask] = (0.45 * rgb[mask] + 0.55 * colourise_labels(labels)[mask]).astype(np.uint8)
    for foot in feet:
        colour = {"left": (255, 60, 60), "right": (60, 220, 60)}.get(foot.side, (255, 255, 0))
        for u, v in foot.keypoints_px.values():
            cv2.circle(out, (round(u), round(v)), 4, colour, -1, cv2.LINE_AA)
    return out


@dataclass
class SegmentedFrame:
    """One frame through :class:`FrameSegmenter`."""

    labels: np.ndarray
    """Label map after the post-processing (:func:`~gaitnet.segmentation.postprocess.
    kept_feet_labels`)."""
    network_labels: np.ndarray
    """The network's label map (edge refinement included)."""
    feet: list[FootDetection]
    gravity_C: np.ndarray | None
    """Unit gravity in the camera frame (:func:`accelerometer_gravity_C`), None without IMU."""
    seconds: tuple[float, float, float]
    """Time spent in HHA, the network and the keypoints."""


class FrameSegmenter:
    """The per-frame steps of :func:`segment_session`: gravity from the accelerometer, the floor
    fit, HHA, the network and the foot keypoints. The first frames' feet place the walker's
    midline (:class:`~gaitnet.segmentation.midline.MidlineEstimate`), which sides the later
    ones. Counts the foot blobs dropped (``dropped``) and the frames without gravity."""

    def __init__(
        self,
        session: SessionSource,
        segmenter: OnnxSegmenter,
        hha_params: HhaParams,
        keypoint_params: FootKeypointParams | None,
        gravity_window_s: float,
    ) -> None:
        self._session, self._segmenter = session, segmenter
        self._hha_params = hha_params
        self._keypoint_params = keypoint_params or FootKeypointParams()
        self._midline = MidlineEstimate(self._keypoint_params)
        self._window_s = gravity_window_s
        self._stride = hha_stride(segmenter.input_scale)
        self.dropped: Counter = Counter()
        self.no_gravity = 0
        self.n_frames = 0

    def __call__(self, frame: Frame) -> SegmentedFrame:
        calib = self._session.calibration
        K = calib.color.K
        t0 = time.perf_counter()
        gravity = accelerometer_gravity_C(
            self._session.imu, calib.T_CfromI, frame.t_ns, self._window_s
        )
        self.no_gravity += gravity is None
        self.n_frames += 1
        up = None if gravity is None else -gravity
        plane = find_floor(frame.depth_m, K, up, self._hha_params)  # one fit: HHA and the feet
        hha = hha_encode(
            frame.depth_m, K, gravity, self._hha_params, plane=plane, stride=self._stride
        )
        t1 = time.perf_counter()
        network_labels = self._segmenter.labels(frame.rgb, hha)
        t2 = time.perf_counter()
        params = self._keypoint_params
        feet = foot_keypoints(
            network_labels, frame.depth_m, K, params, gravity_C=gravity, plane=plane,
            dropped=self.dropped,
        )  # fmt: skip
        if self._midline.collecting:
            self._midline.add(pair_midpoint(feet, params), up_C=up)
            if not self._midline.collecting:
                self._keypoint_params = self._midline.params()
        labels = kept_feet_labels(network_labels, feet)
        t3 = time.perf_counter()
        return SegmentedFrame(labels, network_labels, feet, gravity, (t1 - t0, t2 - t1, t3 - t2))

    def warn_without_gravity(self) -> None:
        """Log how many frames found the floor without the gravity prior, if any."""
        if self.no_gravity:
            log.warning(
                "%d of %d frames had fewer than 5 IMU samples within ±%.2f s: HHA found the "
                "floor without the gravity prior there",
                self.no_gravity,
                self.n_frames,
                self._window_s / 2,
            )


def _keypoint_rows(t_ns: int, feet: list[FootDetection]) -> list[dict[str, object]]:
    """The ``keypoints.csv`` rows (:data:`KEYPOINT_COLUMNS`) of one frame's feet."""
    rows: list[dict[str, object]] = []
    for foot in feet:
        for name, (u, v) in foot.keypoints_px.items():
            p = foot.keypoints_C.get(name)
            ok = p is not None
            rows.append(
                {
                    "t_ns": t_ns,
                    "side": foot.side,
                    "keypoint": name,
                    "u": f"{u:.2f}",
                    "v": f"{v:.2f}",
                    "x_m": f"{p[0]:.5f}" if ok else "",
                    "y_m": f"{p[1]:.5f}" if ok else "",
                    "z_m": f"{p[2]:.5f}" if ok else "",
                    "depth_valid": int(ok),
                }
            )
    return rows


def segment_session(
    session: SessionSource,
    segmenter: OnnxSegmenter,
    out_dir: str | Path,
    *,
    overwrite: bool = False,
    hha_params: HhaParams | None = None,
    keypoint_params: FootKeypointParams | None = None,
    options: SegmentOptions | None = None,
    progress: Progress | None = None,
) -> SegmentResult:
    """Segment every frame of ``session`` into ``out_dir`` (module docstring)."""
    require_depth_aligned(session, "the segmenter")
    hha_params = hha_params or HhaParams()
    options = options or SegmentOptions()
    per_frame = FrameSegmenter(
        session, segmenter, hha_params, keypoint_params, options.gravity_window_s
    )
    n = len(session)
    sheet_at = set(np.linspace(0, n - 1, min(options.sheet_frames, n)).round().astype(int))
    timings = dict.fromkeys(("hha", "network", "keypoints", "write"), 0.0)
    counts = np.zeros(3, np.int64)
    rows: list[dict[str, object]] = []
    sheet: list[list[np.ndarray]] = []
    captions: list[str] = []
    with_foot = 0
    with staged_folder(out_dir, overwrite) as stage:
        (stage / "labels").mkdir()
        frames: Iterable = session.frames()
        if progress is not None:
            frames = progress(frames, n)
        for k, frame in enumerate(frames):
            seg = per_frame(frame)
            feet = seg.feet
            labels = seg.network_labels if options.raw_labels else seg.labels
            t3 = time.perf_counter()
            (stage / "labels" / f"{frame.t_ns}.png").write_bytes(encode_png(labels))
            counts += np.bincount(labels.ravel(), minlength=3)[:3]
            with_foot += bool(feet)
            rows += _keypoint_rows(frame.t_ns, feet)
            if k in sheet_at:
                sheet.append([_overlay(frame.rgb, labels, feet), colourise_labels(labels)])
                captions.append(f"t = {frame.t_ns * 1e-9:.2f} s, {len(feet)} foot blob(s)")
            for key, dt in zip(timings, (*seg.seconds, time.perf_counter() - t3), strict=True):
                timings[key] += dt
        per_frame.warn_without_gravity()
        text = io.StringIO()
        writer = csv.DictWriter(text, fieldnames=KEYPOINT_COLUMNS, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
        (stage / "keypoints.csv").write_text(text.getvalue())
        if sheet:
            write_png(stage / "contact_sheet.png", contact_sheet(sheet, captions, scale=0.5))
        total = max(int(counts.sum()), 1)
        fractions = {
            name: float(c) / total
            for name, c in zip(("background", "foot", "leg"), counts, strict=True)
        }
        summary = {
            "model": str(segmenter.path),
            "arch": segmenter.arch,
            "frames": n,
            "frames_with_foot": with_foot,
            "feet_dropped": dict(sorted(per_frame.dropped.items())),
            "frames_without_gravity": per_frame.no_gravity,
            "label_fractions": fractions,
            "hha": asdict(hha_params),
            "seconds": timings,
            "ms_per_frame": {k: 1e3 * v / max(n, 1) for k, v in timings.items()},
        }
        (stage / "summary.json").write_text(json.dumps(summary, indent=2, default=str) + "\n")
    return SegmentResult(Path(out_dir), n, with_foot, fractions, timings)


DEFAULT_SEGMENTER = "fcn8s_fusion_small.onnx"
"""File name of the committed small fusion model in the repository's ``models/segmenter/``."""


def default_segmenter_path() -> Path:
    """The committed small fusion model (docs/segmenter.md); an :class:`InputError` naming the
    path when it is missing (an install without the repository's ``models/``)."""
    path = Path(__file__).resolve().parents[2] / "models" / "segmenter" / DEFAULT_SEGMENTER
    if not path.is_file():
        raise InputError(f"{path}: the default segmenter is missing; give a segmenter .onnx file")
    return path
