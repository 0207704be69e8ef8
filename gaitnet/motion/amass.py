"""AMASS motion files: read, resample to 30 fps, select walking clips, split (thesis sec. 4.2.2).

This module reads AMASS source files only; the prepared training file is
:mod:`gaitnet.motion.prepared`, heading normalisation :mod:`gaitnet.motion.heading` and the
torch Dataset of training windows :mod:`gaitnet.motion.windows`.

Reading. Two AMASS file flavours are understood (docs/thesis-notes.md, docs/ecosystem.md):

* SMPL+H G ``*_poses.npz``: ``poses`` (T, 156) (joint ``k``'s axis-angle at columns
  ``3k : 3k+3``, joint 0 the root orientation), ``trans`` (T, 3), ``betas`` (16),
  ``gender``, ``mocap_framerate``;
* SMPL-X ``*_stageii.npz``: ``root_orient`` (T, 3), ``pose_body`` (T, 63) (starting at joint
  1), ``trans``, ``betas``, ``gender``, ``mocap_frame_rate``.

From each we keep the root orientation, the local rotations of the 8 lower-body joints SMPL
``[1, 2, 4, 5, 7, 8, 10, 11]`` (:data:`ROTATED_SMPL_INDICES`), the translation, ``betas`` and
``gender``. A missing key, a NaN/inf, a wrong shape or a bad frame rate raises
:class:`AmassError` naming the file and the key.

Resampling (thesis: 30 fps). Frame rates differ between clips and AMASS versions (120, 60,
59.94, 100, ...), so clips are resampled BY TIME: output frame ``n`` is at ``t = n / 30`` s
over the clip's duration; rotations are slerped between the two bracketing source frames
(scipy ``Slerp``), the translation is interpolated linearly.

Selection and split. Walking clips are chosen by case-insensitive keywords in the file name
(default: contains ``"walk"``, and neither ``"backward"`` nor ``"stair"``) or by a clip-list
file (paths relative to the AMASS root, one per line, ``#`` comments). The split is by
sub-dataset, the first folder under the AMASS root, following LTD / HisRepItself
(:class:`DatasetSplit`): test = BMLrub (formerly BioMotionLab_NTroje); validation = HumanEva,
MPI_HDM05 (HDM05), SFU, MPI_mosh (MoSh); training = every other sub-dataset.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path, PurePosixPath
from typing import Literal

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from gaitnet.errors import InputError
from gaitnet.io.npz import npz_array, open_npz
from gaitnet.motion.skeleton import ROTATED_SMPL_INDICES

__all__ = [
    "DEFAULT_EXCLUDE",
    "DEFAULT_INCLUDE",
    "REST_JOINTS_KEY",
    "TARGET_FPS",
    "AmassError",
    "DatasetSplit",
    "MotionClip",
    "Split",
    "find_amass_files",
    "is_walking_clip",
    "load_amass_clip",
    "read_amass_npz",
    "read_clip_list",
    "resample_clip",
]

TARGET_FPS = 30.0
#: Optional extra key of a clip file: the subject's own rest joints (9, 3) [m] in SMPL's
#: canonical frame, order :data:`gaitnet.motion.skeleton.SMPL_JOINT_INDICES` (the synthetic
#: clips of :mod:`gaitnet.sim.amass_clips` carry it; AMASS files do not).
REST_JOINTS_KEY = "gaitnet_rest_joints"
DEFAULT_INCLUDE: tuple[str, ...] = ("walk",)
DEFAULT_EXCLUDE: tuple[str, ...] = ("backward", "stair")
_SMPLH_KEYS = ("poses", "trans", "betas", "gender", "mocap_framerate")
_SMPLX_KEYS = ("root_orient", "pose_body", "trans", "betas", "gender", "mocap_frame_rate")

Split = Literal["train", "val", "test"]


class AmassError(InputError):
    """An AMASS file, clip list or prepared file is unusable; the message names file and key."""


# --------------------------------------------------------------------------- clips


@dataclass(frozen=True, eq=False)
class MotionClip:
    """One clip's lower-body motion.

    ``root_orient`` (T, 3) world-from-pelvis axis-angle, ``joint_aa`` (T, 8, 3) local
    axis-angles of :data:`ROTATED_SMPL_INDICES`, ``trans`` (T, 3) [m], sampled at ``fps``;
    ``source_fps`` is the rate of the file it came from; ``rest_joints`` (9, 3) the subject's
    own skeleton when the file has :data:`REST_JOINTS_KEY` (else None).
    """

    name: str
    dataset: str
    fps: float
    root_orient: np.ndarray
    joint_aa: np.ndarray
    trans: np.ndarray
    betas: np.ndarray
    gender: str
    source_fps: float
    rest_joints: np.ndarray | None = None

    @property
    def n_frames(self) -> int:
        return int(self.root_orient.shape[0])

    @property
    def duration_s(self) -> float:
        return (self.n_frames - 1) / self.fps


def _get(data: np.lib.npyio.NpzFile, path: Path, key: str, flavour: str) -> np.ndarray:
    if key not in data.files:
        raise AmassError(
            f"{path}: missing key {key!r} (an AMASS {flavour} file needs "
            f"{', '.join(_SMPLH_KEYS if flavour.startswith('SMPL+H') else _SMPLX_KEYS)})"
        )
    return npz_array(data, path, key, AmassError)


def _finite(path: Path, key: str, a: np.ndarray) -> np.ndarray:
    if not np.issubdtype(a.dtype, np.number):
        raise AmassError(f"{path}: key {key!r} has non-numeric dtype {a.dtype}")
    a = np.asarray(a, dtype=np.float64)
    bad = ~np.isfinite(a)
    if bad.any():
        first = np.argwhere(bad)[0]
        where = f" at frame {int(first[0])}" if a.ndim >= 2 else ""
        raise AmassError(f"{path}: key {key!r} contains NaN or inf{where}")
    return a


def _string(path: Path, key: str, a: np.ndarray) -> str:
    if a.size != 1 or a.dtype.kind not in "SU":
        raise AmassError(f"{path}: key {key!r} must be one string, got {a.dtype} {a.shape}")
    value = a.reshape(()).item()
    return value.decode("utf-8", "replace") if isinstance(value, bytes) else str(value)


def _framerate(path: Path, key: str, a: np.ndarray) -> float:
    if a.size != 1 or not np.issubdtype(a.dtype, np.number):
        raise AmassError(f"{path}: key {key!r} must be one number, got {a.dtype} {a.shape}")
    fps = float(a.reshape(()))
    if not math.isfinite(fps) or fps <= 0:
        raise AmassError(f"{path}: key {key!r} must be a positive frame rate, got {fps}")
    return fps


def _pose_columns(path: Path, key: str, a: np.ndarray, first_joint: int, n_rows: int | None):
    """Check a (T, 3·J) pose array that starts at SMPL joint ``first_joint``."""
    need = 3 * (max(ROTATED_SMPL_INDICES) + 1 - first_joint)
    if a.ndim != 2 or a.shape[1] % 3 != 0 or a.shape[1] < need:
        raise AmassError(
            f"{path}: key {key!r} must have shape (T, 3·joints) with at least {need} columns, "
            f"got {a.shape}"
        )
    if n_rows is not None and a.shape[0] != n_rows:
        raise AmassError(f"{path}: key {key!r} has {a.shape[0]} frames, expected {n_rows}")


def _names(path: Path, amass_root: str | Path | None) -> tuple[str, str]:
    """The clip's name (its path under the root) and sub-dataset (the first folder of it).

    The path is taken as listed under the root, symbolic links NOT followed: a clip that is a
    link inside the AMASS folder (to a file stored elsewhere) keeps the sub-dataset of where
    it is linked, so it lands in that sub-dataset's split. Only a path outside the root (also
    after resolving links) has no sub-dataset.
    """
    if amass_root is None:
        return path.name, ""
    for here, root in (
        (Path(os.path.abspath(path)), Path(os.path.abspath(amass_root))),
        (path.resolve(), Path(amass_root).resolve()),
    ):
        try:
            rel = here.relative_to(root)
        except ValueError:
            continue
        parts = PurePosixPath(rel.as_posix()).parts
        return rel.as_posix(), (parts[0] if len(parts) > 1 else "")
    return path.name, ""


def read_amass_npz(path: str | Path, *, amass_root: str | Path | None = None) -> MotionClip:
    """Read one AMASS ``.npz`` (SMPL+H G ``poses`` or SMPL-X ``root_orient``/``pose_body``).

    Returns the clip at its source frame rate. With ``amass_root`` the clip is named by its
    path relative to the root and its sub-dataset is the first folder of that path.
    """
    path = Path(path)
    with open_npz(path, "an AMASS .npz file", AmassError) as data:
        if "root_orient" in data.files or "pose_body" in data.files:
            flavour = "SMPL-X stageii"
            root = _finite(path, "root_orient", _get(data, path, "root_orient", flavour))
            body = _finite(path, "pose_body", _get(data, path, "pose_body", flavour))
            if root.ndim != 2 or root.shape[1] != 3:
                raise AmassError(f"{path}: key 'root_orient' must be (T, 3), got {root.shape}")
            _pose_columns(path, "pose_body", body, 1, root.shape[0])
            full = np.concatenate([root, body], axis=1)
            fps_key = "mocap_frame_rate"
        else:
            flavour = "SMPL+H G poses"
            full = _finite(path, "poses", _get(data, path, "poses", flavour))
            _pose_columns(path, "poses", full, 0, None)
            fps_key = "mocap_framerate"
        T = full.shape[0]
        trans = _finite(path, "trans", _get(data, path, "trans", flavour))
        if trans.shape != (T, 3):
            raise AmassError(f"{path}: key 'trans' must have shape ({T}, 3), got {trans.shape}")
        betas = _finite(path, "betas", _get(data, path, "betas", flavour))
        if betas.ndim == 2 and betas.shape[0] == 1:
            betas = betas[0]
        if betas.ndim != 1:
            raise AmassError(f"{path}: key 'betas' must be a vector, got shape {betas.shape}")
        gender = _string(path, "gender", _get(data, path, "gender", flavour))
        # Each flavour has its own spelling; accept the other one too (re-saved files mix them).
        other = "mocap_framerate" if fps_key == "mocap_frame_rate" else "mocap_frame_rate"
        if fps_key not in data.files and other in data.files:
            fps_key = other
        fps = _framerate(path, fps_key, _get(data, path, fps_key, flavour))
        rest = None
        if REST_JOINTS_KEY in data.files:
            rest = _finite(path, REST_JOINTS_KEY, _get(data, path, REST_JOINTS_KEY, flavour))
            if rest.shape != (9, 3):
                raise AmassError(
                    f"{path}: key {REST_JOINTS_KEY!r} must have shape (9, 3), got {rest.shape}"
                )
    if T < 2:
        raise AmassError(f"{path}: needs at least 2 frames, found {T}")
    joints = full.reshape(T, -1, 3)
    name, dataset = _names(path, amass_root)
    return MotionClip(
        name=name,
        dataset=dataset,
        fps=fps,
        root_orient=joints[:, 0].copy(),
        joint_aa=joints[:, list(ROTATED_SMPL_INDICES)].copy(),
        trans=trans,
        betas=betas,
        gender=gender,
        source_fps=fps,
        rest_joints=rest,
    )


def resample_clip(clip: MotionClip, fps: float = TARGET_FPS) -> MotionClip:
    """Resample by time to ``fps``: output frame ``n`` at ``t = n / fps`` within the clip.

    Rotations (root and joints) are slerped between the bracketing source frames, the
    translation is linear in time. The output covers ``[0, duration]``.
    """
    if not (math.isfinite(fps) and fps > 0):
        raise InputError(f"resampling rate (fps) must be a positive number, got {fps}")
    t_src = np.arange(clip.n_frames) / clip.fps
    n_out = int(math.floor(clip.duration_s * fps + 1e-6)) + 1
    t_out = np.minimum(np.arange(n_out) / fps, t_src[-1])
    tracks = np.concatenate([clip.root_orient[:, None], clip.joint_aa], axis=1)  # (T, 9, 3)
    out = np.empty((n_out, tracks.shape[1], 3))
    for j in range(tracks.shape[1]):
        out[:, j] = Slerp(t_src, Rotation.from_rotvec(tracks[:, j]))(t_out).as_rotvec()
    trans = np.stack([np.interp(t_out, t_src, clip.trans[:, k]) for k in range(3)], axis=1)
    return replace(clip, fps=float(fps), root_orient=out[:, 0], joint_aa=out[:, 1:], trans=trans)


def load_amass_clip(
    path: str | Path, *, amass_root: str | Path | None = None, fps: float = TARGET_FPS
) -> MotionClip:
    """:func:`read_amass_npz` then :func:`resample_clip` to ``fps`` (30 by default)."""
    return resample_clip(read_amass_npz(path, amass_root=amass_root), fps)


# --------------------------------------------------------------------------- selection, split


@dataclass(frozen=True)
class DatasetSplit:
    """Split by AMASS sub-dataset (case-insensitive folder names); the rest is training.

    Default as LTD / HisRepItself, with AMASS's newer folder names added.
    """

    val: tuple[str, ...] = ("HumanEva", "MPI_HDM05", "HDM05", "SFU", "MPI_mosh", "MoSh")
    test: tuple[str, ...] = ("BMLrub", "BioMotionLab_NTroje")

    def split_of(self, dataset: str) -> Split:
        """``'test'``, ``'val'`` or ``'train'`` for a sub-dataset name."""
        name = dataset.lower()
        if name in {d.lower() for d in self.test}:
            return "test"
        if name in {d.lower() for d in self.val}:
            return "val"
        return "train"


def is_walking_clip(
    path: str | PurePosixPath,
    include: Sequence[str] = DEFAULT_INCLUDE,
    exclude: Sequence[str] = DEFAULT_EXCLUDE,
) -> bool:
    """Whether the FILE NAME contains any of ``include`` and none of ``exclude`` (any case)."""
    name = PurePosixPath(str(path).replace("\\", "/")).name.lower()
    return any(k.lower() in name for k in include) and not any(k.lower() in name for k in exclude)


def read_clip_list(path: str | Path) -> list[str]:
    """Clip paths relative to the AMASS root, one per line; blank lines and ``#`` comments skip."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except OSError as exc:
        raise AmassError(f"{path}: cannot read clip list ({exc})") from exc
    clips = []
    for line in lines:
        entry = line.split("#", 1)[0].strip()
        if entry:
            clips.append(PurePosixPath(entry.replace("\\", "/")).as_posix())
    if not clips:
        raise AmassError(f"{path}: clip list is empty")
    return clips


def find_amass_files(amass_root: str | Path) -> list[Path]:
    """Every ``*_poses.npz`` and ``*_stageii.npz`` under ``amass_root``, sorted.

    Shape files (``shape.npz``, ``*_stagei.npz``) are not motion and are skipped.
    """
    root = Path(amass_root)
    if not root.is_dir():
        raise AmassError(f"{root}: AMASS root folder does not exist")
    return sorted(p for p in root.rglob("*.npz") if p.name.endswith(("_poses.npz", "_stageii.npz")))
