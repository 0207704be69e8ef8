"""Frames of a recorded session to label with labelme, pre-labelled by the segmenter
(``gaitnet segment SESSION --label-frames N``; docs/recording.md, *Adapting the segmenter to
your footage*).

:func:`write_frames_to_label` picks ``N`` frames spread evenly over the session
(:func:`frames_to_label`), runs each through the same steps as ``gaitnet segment``
(:class:`~gaitnet.segmentation.segment_session.FrameSegmenter`: gravity, HHA, network, foot
post-processing) and writes a labelled-frame folder in the layout the segmenter trains on
(``data/README.md``, :class:`~gaitnet.segmentation.dataset.SegmentationFolder`)::

    images/<t_ns>.png    the colour frame
    images/<t_ns>.json   labelme polygons of the post-processed labels: legs, then feet (a foot
                         drawn over its leg wins); feet sided (group_id 1 left, 2 right) where
                         the post-processing sided them
    depth/<t_ns>.png     16-bit depth aligned to colour, in units of the session's depth scale
    camera.yaml          the colour intrinsics and the depth scale
    frames.csv           id, unit gravity in the camera frame (empty cells without IMU)
    labels.txt           the labelme class list

Open ``images/`` in labelme, correct each frame's polygons (the pre-labels are the committed
segmenter's guesses, not ground truth) and train on the folder. The folder appears only when
complete (:func:`gaitnet.io.atomic.staged_folder`).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gaitnet.checks import check_int_range
from gaitnet.errors import InputError
from gaitnet.io.atomic import atomic_write_text, staged_folder
from gaitnet.io.images import depth_to_units, encode_png
from gaitnet.io.labelme_io import INSTANCE_GROUPS, labelme_document, labels_txt
from gaitnet.io.types import SessionSource, require_depth_aligned
from gaitnet.segmentation.folder_files import camera_yaml_text
from gaitnet.segmentation.foot_types import FootDetection, FootKeypointParams
from gaitnet.segmentation.hha import HhaParams
from gaitnet.segmentation.onnx_runtime import OnnxSegmenter
from gaitnet.segmentation.segment_session import FrameSegmenter

__all__ = ["LabelFramesResult", "frames_to_label", "write_frames_to_label"]

Progress = Callable[[Iterable, int], Iterable]

MAX_FRAMES_TO_LABEL = 10_000

_SIDE_VALUE = {side: value for value, side in INSTANCE_GROUPS.items()}


@dataclass
class LabelFramesResult:
    """What :func:`write_frames_to_label` wrote."""

    path: Path
    frame_ids: list[str]
    shapes: int
    """labelme shapes written over all frames (the pre-labels to check)."""


def frames_to_label(n_session: int, n_frames: int) -> list[int]:
    """Indices of ``n_frames`` frames spread evenly over a session of ``n_session`` frames,
    first and last included (all of them when the session is shorter)."""
    n = min(n_frames, n_session)
    return sorted({int(i) for i in np.linspace(0, n_session - 1, n).round()})


def _side_map(shape: tuple[int, int], feet: list[FootDetection]) -> np.ndarray:
    """Per-pixel side of the kept feet (1 left, 2 right, 0 elsewhere or unsided)."""
    sides = np.zeros(shape, np.int32)
    for foot in feet:
        sides[foot.mask] = _SIDE_VALUE.get(foot.side, 0)
    return sides


def write_frames_to_label(
    session: SessionSource,
    segmenter: OnnxSegmenter,
    out_dir: str | Path,
    n_frames: int,
    *,
    overwrite: bool = False,
    hha_params: HhaParams | None = None,
    keypoint_params: FootKeypointParams | None = None,
    gravity_window_s: float = 1.0,
    progress: Progress | None = None,
) -> LabelFramesResult:
    """Write ``n_frames`` pre-labelled frames of ``session`` into ``out_dir`` (module
    docstring). A session whose depth is not aligned to colour is refused before anything is
    written; ``n_frames`` must be within 1–10000."""
    try:
        check_int_range("--label-frames", n_frames, 1, MAX_FRAMES_TO_LABEL)
    except ValueError as exc:
        raise InputError(str(exc)) from None
    require_depth_aligned(session, "the segmenter")
    calib = session.calibration
    per_frame = FrameSegmenter(
        session, segmenter, hha_params or HhaParams(), keypoint_params, gravity_window_s
    )
    indices: Iterable[int] = frames_to_label(len(session), n_frames)
    rows = ["id,gravity_cx,gravity_cy,gravity_cz"]
    ids: list[str] = []
    shapes = 0
    with staged_folder(out_dir, overwrite) as stage:
        for sub in ("images", "depth"):
            (stage / sub).mkdir()
        if progress is not None:
            indices = progress(indices, min(n_frames, len(session)))
        for index in indices:
            frame = session.frame(index)
            seg = per_frame(frame)
            name = str(frame.t_ns)
            ids.append(name)
            (stage / "images" / f"{name}.png").write_bytes(encode_png(frame.rgb))
            depth = depth_to_units(frame.depth_m, calib.depth_scale_m)
            (stage / "depth" / f"{name}.png").write_bytes(encode_png(depth))
            sides = _side_map(seg.labels.shape, seg.feet)
            doc = labelme_document(seg.labels, sides, f"{name}.png")
            shapes += len(doc["shapes"])
            (stage / "images" / f"{name}.json").write_text(json.dumps(doc, indent=1))
            g = seg.gravity_C
            rows.append(f"{name}," + ("," * 2 if g is None else ",".join(f"{x:.9f}" for x in g)))
        per_frame.warn_without_gravity()
        atomic_write_text(stage / "frames.csv", "\n".join(rows) + "\n")
        atomic_write_text(stage / "labels.txt", labels_txt())
        atomic_write_text(stage / "camera.yaml", camera_yaml_text(calib.color, calib.depth_scale_m))
    return LabelFramesResult(Path(out_dir), ids, shapes)
