"""AMASS walking clips for the motion predictor (thesis sec. 4.2.2).

Reading. Two AMASS file flavours are understood (thesis-notes.md, ecosystem.md):

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

Heading normalisation. AMASS's world is z up. Each training window is rotated about the world
vertical so that the body's heading at the LAST OBSERVED frame is +x (DESIGN.md: x forward),
and its translation is taken relative to that frame horizontally (:func:`normalise_heading`).
The heading is the body's forward axis (SMPL's canonical +z, the way the rest pose faces)
mapped by the root orientation and projected onto the floor. This also keeps the root
axis-angle far from the ±π wrap (about 120° about (1, 1, 1)/√3 when upright and facing +x).

Prepared file. :func:`prepare_walking_subset` writes one compressed ``.npz`` (no pickles) with
the selected clips at 30 fps concatenated along time and an index (``clip_offset``); see
:data:`PREPARED_KEYS`. :class:`WalkingWindows` serves heading-normalised windows of
``n_past + n_future`` frames from it.
"""

from __future__ import annotations

import math
import zipfile
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path, PurePosixPath
from typing import Literal

import numpy as np
import torch
from scipy.spatial.transform import Rotation, Slerp
from torch.utils.data import Dataset

from gaitnet.errors import GaitnetError
from gaitnet.io.atomic import atomic_open
from gaitnet.motion.gcn import pose_features
from gaitnet.motion.skeleton import N_ROTATED, ROTATED_SMPL_INDICES

__all__ = [
    "DEFAULT_EXCLUDE",
    "DEFAULT_INCLUDE",
    "PREPARED_FORMAT_VERSION",
    "PREPARED_KEYS",
    "TARGET_FPS",
    "AmassError",
    "DatasetSplit",
    "MotionClip",
    "PrepareReport",
    "PreparedWalking",
    "WalkingWindows",
    "find_amass_files",
    "heading_angle",
    "is_walking_clip",
    "load_amass_clip",
    "load_prepared",
    "normalise_heading",
    "prepare_walking_subset",
    "read_amass_npz",
    "read_clip_list",
    "resample_clip",
]

TARGET_FPS = 30.0
DEFAULT_INCLUDE: tuple[str, ...] = ("walk",)
DEFAULT_EXCLUDE: tuple[str, ...] = ("backward", "stair")
PREPARED_FORMAT_VERSION = 1
#: Arrays of a prepared file: C clips, N frames in all, B = longest betas.
PREPARED_KEYS: dict[str, str] = {
    "format_version": "() int: PREPARED_FORMAT_VERSION",
    "fps": "() float: frame rate of every clip (30)",
    "clip_name": "(C,) str: path relative to the AMASS root",
    "clip_dataset": "(C,) str: sub-dataset (first folder under the root)",
    "clip_split": "(C,) str: 'train' | 'val' | 'test'",
    "clip_gender": "(C,) str",
    "clip_source_fps": "(C,) float64: frame rate of the source file",
    "clip_offset": "(C+1,) int64: frames of clip c are [offset[c], offset[c+1])",
    "betas": "(C, B) float32, zero-padded",
    "root_orient": "(N, 3) float32: world-from-pelvis axis-angle (AMASS world, z up)",
    "joint_aa": "(N, 8, 3) float32: local axis-angle of SMPL joints 1, 2, 4, 5, 7, 8, 10, 11",
    "trans": "(N, 3) float32: SMPL translation [m]",
}

_SMPLH_KEYS = ("poses", "trans", "betas", "gender", "mocap_framerate")
_SMPLX_KEYS = ("root_orient", "pose_body", "trans", "betas", "gender", "mocap_frame_rate")
_FORWARD_B = np.array([0.0, 0.0, 1.0])  # SMPL canonical frame: the rest pose faces +z

Split = Literal["train", "val", "test"]


class AmassError(GaitnetError):
    """An AMASS file, clip list or prepared file is unusable; the message names file and key."""


# --------------------------------------------------------------------------- clips


@dataclass(frozen=True, eq=False)
class MotionClip:
    """One clip's lower-body motion.

    ``root_orient`` (T, 3) world-from-pelvis axis-angle, ``joint_aa`` (T, 8, 3) local
    axis-angles of :data:`ROTATED_SMPL_INDICES`, ``trans`` (T, 3) [m], sampled at ``fps``;
    ``source_fps`` is the rate of the file it came from.
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
    try:
        return data[key]
    except ValueError as exc:  # object arrays need pickles, which we never load
        raise AmassError(f"{path}: key {key!r} is not a plain array ({exc})") from exc


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
    if amass_root is None:
        return path.name, ""
    try:
        rel = path.resolve().relative_to(Path(amass_root).resolve())
    except ValueError:
        return path.name, ""
    parts = PurePosixPath(rel.as_posix()).parts
    return rel.as_posix(), (parts[0] if len(parts) > 1 else "")


def read_amass_npz(path: str | Path, *, amass_root: str | Path | None = None) -> MotionClip:
    """Read one AMASS ``.npz`` (SMPL+H G ``poses`` or SMPL-X ``root_orient``/``pose_body``).

    Returns the clip at its source frame rate. With ``amass_root`` the clip is named by its
    path relative to the root and its sub-dataset is the first folder of that path.
    """
    path = Path(path)
    try:
        data = np.load(path, allow_pickle=False)
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise AmassError(f"{path}: not a readable .npz file ({exc})") from exc
    if not isinstance(data, np.lib.npyio.NpzFile):
        raise AmassError(f"{path}: expected an .npz archive of named arrays, found one array")
    with data:
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
    )


def resample_clip(clip: MotionClip, fps: float = TARGET_FPS) -> MotionClip:
    """Resample by time to ``fps``: output frame ``n`` at ``t = n / fps`` within the clip.

    Rotations (root and joints) are slerped between the bracketing source frames, the
    translation is linear in time. The output covers ``[0, duration]``.
    """
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
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


# --------------------------------------------------------------------------- heading


def heading_angle(root_orient: np.ndarray) -> np.ndarray:
    """Heading (yaw about world +z) [rad] of the body's forward axis for (..., 3) axis-angles.

    Forward is SMPL's canonical +z mapped by the root orientation, projected on the floor;
    0 means facing +x.
    """
    root_orient = np.asarray(root_orient, dtype=np.float64)
    flat = root_orient.reshape(-1, 3)
    f = Rotation.from_rotvec(flat).apply(_FORWARD_B)
    return np.arctan2(f[:, 1], f[:, 0]).reshape(root_orient.shape[:-1])


def normalise_heading(
    root_orient: np.ndarray, trans: np.ndarray, ref: int
) -> tuple[np.ndarray, np.ndarray, float]:
    """Rotate a window about world z so the heading at frame ``ref`` is +x.

    Returns ``(root_orient', trans', yaw)`` with ``R' = Rz(−yaw) R`` and
    ``trans' = Rz(−yaw) (trans − [trans_ref,x, trans_ref,y, 0])``. Joint positions from forward
    kinematics then equal ``Rz(−yaw)`` times the original ones plus a constant offset
    (``(I − Rz) J_0`` minus the reference shift), so the motion is unchanged relative to any of
    its frames; the pelvis at frame ``ref`` sits at the rest pelvis's x, y (a few mm).
    """
    root_orient = np.asarray(root_orient, dtype=np.float64)
    trans = np.asarray(trans, dtype=np.float64)
    yaw = float(heading_angle(root_orient[ref]))
    Rz = Rotation.from_rotvec([0.0, 0.0, -yaw])
    root_n = (Rz * Rotation.from_rotvec(root_orient)).as_rotvec()
    shift = np.array([trans[ref, 0], trans[ref, 1], 0.0])
    trans_n = Rz.apply(trans - shift)
    return root_n, trans_n, yaw


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


# --------------------------------------------------------------------------- prepared file


@dataclass(frozen=True)
class PrepareReport:
    """What :func:`prepare_walking_subset` wrote and skipped."""

    out_file: Path
    n_clips: dict[str, int]
    n_frames: dict[str, int]
    n_candidates: int
    skipped: list[tuple[str, str]] = field(default_factory=list)


def prepare_walking_subset(
    amass_root: str | Path,
    out_file: str | Path,
    *,
    include: Sequence[str] = DEFAULT_INCLUDE,
    exclude: Sequence[str] = DEFAULT_EXCLUDE,
    clip_list: str | Path | None = None,
    split: DatasetSplit | None = None,
    fps: float = TARGET_FPS,
    min_frames: int = 20,
    on_error: Literal["raise", "skip"] = "raise",
    progress: Callable[[Iterable[Path], int], Iterable[Path]] | None = None,
) -> PrepareReport:
    """Select walking clips under ``amass_root``, resample to ``fps`` and write ``out_file``.

    Clips come from ``clip_list`` (paths relative to the root; keywords are then ignored) or
    from the file-name keywords ``include``/``exclude``. Clips shorter than ``min_frames``
    after resampling are skipped (listed in the report). A broken file raises
    :class:`AmassError` (``on_error="raise"``) or is skipped and listed (``"skip"``).
    ``progress(iterable, total)`` may wrap the file loop (e.g. tqdm). The file is written
    atomically; its layout is :data:`PREPARED_KEYS`.
    """
    root = Path(amass_root)
    split = DatasetSplit() if split is None else split
    if clip_list is not None:
        wanted = read_clip_list(clip_list)
        files = [root / rel for rel in wanted]
        missing = [rel for rel, f in zip(wanted, files, strict=True) if not f.is_file()]
        if missing:
            shown = ", ".join(missing[:5]) + (" ..." if len(missing) > 5 else "")
            raise AmassError(
                f"{clip_list}: {len(missing)} listed clip(s) not found under {root}: {shown}"
            )
    else:
        files = [
            f
            for f in find_amass_files(root)
            if is_walking_clip(f.relative_to(root).as_posix(), include, exclude)
        ]
    if not files:
        raise AmassError(
            f"{root}: no walking clips found (include={list(include)}, exclude={list(exclude)})"
        )
    iterator: Iterable[Path] = files if progress is None else progress(files, len(files))
    clips: list[MotionClip] = []
    skipped: list[tuple[str, str]] = []
    for f in iterator:
        try:
            clip = load_amass_clip(f, amass_root=root, fps=fps)
        except AmassError as exc:
            if on_error == "raise":
                raise
            skipped.append((str(f), str(exc)))
            continue
        if clip.n_frames < min_frames:
            skipped.append((clip.name, f"{clip.n_frames} frames < min_frames {min_frames}"))
            continue
        clips.append(clip)
    if not clips:
        raise AmassError(f"{root}: none of {len(files)} candidate clips could be used")

    n_betas = max(c.betas.shape[0] for c in clips)
    betas = np.zeros((len(clips), n_betas), dtype=np.float32)
    for i, c in enumerate(clips):
        betas[i, : c.betas.shape[0]] = c.betas
    splits = [split.split_of(c.dataset) for c in clips]
    lengths = np.array([c.n_frames for c in clips], dtype=np.int64)
    arrays = {
        "format_version": np.array(PREPARED_FORMAT_VERSION, dtype=np.int64),
        "fps": np.array(float(fps)),
        "clip_name": np.array([c.name for c in clips], dtype=str),
        "clip_dataset": np.array([c.dataset for c in clips], dtype=str),
        "clip_split": np.array(splits, dtype=str),
        "clip_gender": np.array([c.gender for c in clips], dtype=str),
        "clip_source_fps": np.array([c.source_fps for c in clips], dtype=np.float64),
        "clip_offset": np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64),
        "betas": betas,
        "root_orient": np.concatenate([c.root_orient for c in clips]).astype(np.float32),
        "joint_aa": np.concatenate([c.joint_aa for c in clips]).astype(np.float32),
        "trans": np.concatenate([c.trans for c in clips]).astype(np.float32),
    }
    out_file = Path(out_file)
    with atomic_open(out_file, "wb") as handle:
        np.savez_compressed(handle, **arrays)
    n_clips = {s: 0 for s in ("train", "val", "test")}
    n_frames = {s: 0 for s in ("train", "val", "test")}
    for s, n in zip(splits, lengths, strict=True):
        n_clips[s] += 1
        n_frames[s] += int(n)
    return PrepareReport(out_file, n_clips, n_frames, len(files), skipped)


@dataclass(frozen=True, eq=False)
class PreparedWalking:
    """A prepared file in memory (see :data:`PREPARED_KEYS`)."""

    path: Path
    fps: float
    clip_name: np.ndarray
    clip_dataset: np.ndarray
    clip_split: np.ndarray
    clip_gender: np.ndarray
    clip_source_fps: np.ndarray
    clip_offset: np.ndarray
    betas: np.ndarray
    root_orient: np.ndarray
    joint_aa: np.ndarray
    trans: np.ndarray

    @property
    def n_clips(self) -> int:
        return int(self.clip_name.shape[0])

    def clip(self, i: int) -> MotionClip:
        """Clip ``i`` as a :class:`MotionClip` (float64 copies)."""
        a, b = int(self.clip_offset[i]), int(self.clip_offset[i + 1])
        return MotionClip(
            name=str(self.clip_name[i]),
            dataset=str(self.clip_dataset[i]),
            fps=self.fps,
            root_orient=self.root_orient[a:b].astype(np.float64),
            joint_aa=self.joint_aa[a:b].astype(np.float64),
            trans=self.trans[a:b].astype(np.float64),
            betas=self.betas[i].astype(np.float64),
            gender=str(self.clip_gender[i]),
            source_fps=float(self.clip_source_fps[i]),
        )


def load_prepared(path: str | Path) -> PreparedWalking:
    """Load and check a file written by :func:`prepare_walking_subset`."""
    path = Path(path)
    try:
        data = np.load(path, allow_pickle=False)
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise AmassError(f"{path}: not a readable prepared .npz ({exc})") from exc
    with data:
        missing = [k for k in PREPARED_KEYS if k not in data.files]
        if missing:
            raise AmassError(f"{path}: missing key(s) {missing}; re-run the AMASS preparation")
        arrays = {k: data[k] for k in PREPARED_KEYS}
    version = int(arrays.pop("format_version"))
    if version != PREPARED_FORMAT_VERSION:
        raise AmassError(
            f"{path}: key 'format_version' is {version}, this gaitnet reads "
            f"{PREPARED_FORMAT_VERSION}; re-run the AMASS preparation"
        )
    C = arrays["clip_name"].shape[0]
    offset = arrays["clip_offset"]
    N = arrays["root_orient"].shape[0]
    checks = {
        "clip_offset": offset.shape == (C + 1,)
        and offset[0] == 0
        and offset[-1] == N
        and bool(np.all(np.diff(offset) > 0)),
        "root_orient": arrays["root_orient"].shape == (N, 3),
        "joint_aa": arrays["joint_aa"].shape == (N, N_ROTATED, 3),
        "trans": arrays["trans"].shape == (N, 3),
        "betas": arrays["betas"].ndim == 2 and arrays["betas"].shape[0] == C,
    }
    for key in ("clip_dataset", "clip_split", "clip_gender", "clip_source_fps"):
        checks[key] = arrays[key].shape == (C,)
    for key, ok in checks.items():
        if not ok:
            raise AmassError(f"{path}: key {key!r} has an inconsistent shape")
    for key in ("root_orient", "joint_aa", "trans", "betas"):
        if not np.all(np.isfinite(arrays[key])):
            raise AmassError(f"{path}: key {key!r} contains NaN or inf")
    fps = float(arrays.pop("fps"))
    return PreparedWalking(path=path, fps=fps, **arrays)


class WalkingWindows(Dataset):
    """Heading-normalised windows of ``n_past + n_future`` frames from a prepared file.

    Windows start every ``stride`` frames inside each clip of ``split``. Item ``i`` is a dict
    of float32 tensors: ``poses`` (W, 21) in the node layout of :mod:`gaitnet.motion.gcn`,
    ``trans`` (W, 3), ``betas`` (B,), and ``clip`` (int index into the prepared file). With
    ``normalise_heading`` (default) each window goes through :func:`normalise_heading` with
    the last observed frame (``n_past − 1``) as reference.
    """

    def __init__(
        self,
        prepared: str | Path | PreparedWalking,
        split: Split = "train",
        *,
        n_past: int = 10,
        n_future: int = 10,
        stride: int = 5,
        normalise_heading: bool = True,
    ):
        self.data = prepared if isinstance(prepared, PreparedWalking) else load_prepared(prepared)
        if split not in ("train", "val", "test"):
            raise ValueError(f"split must be 'train', 'val' or 'test', got {split!r}")
        if n_past < 1 or n_future < 0 or stride < 1:
            raise ValueError(
                f"need n_past >= 1, n_future >= 0, stride >= 1; got {n_past}, {n_future}, {stride}"
            )
        self.split = split
        self.n_past = int(n_past)
        self.window = int(n_past + n_future)
        self.normalise = bool(normalise_heading)
        index = []
        for c in np.flatnonzero(self.data.clip_split == split):
            a, b = int(self.data.clip_offset[c]), int(self.data.clip_offset[c + 1])
            for start in range(a, b - self.window + 1, int(stride)):
                index.append((int(c), start))
        if not index:
            raise AmassError(
                f"{self.data.path}: no windows of {self.window} frames in split {split!r}"
            )
        self.index = np.array(index, dtype=np.int64)

    @property
    def fps(self) -> float:
        return self.data.fps

    def __len__(self) -> int:
        return int(self.index.shape[0])

    def __getitem__(self, i: int) -> dict[str, torch.Tensor]:
        clip, start = (int(v) for v in self.index[i])
        sl = slice(start, start + self.window)
        root = self.data.root_orient[sl].astype(np.float64)
        trans = self.data.trans[sl].astype(np.float64)
        if self.normalise:
            root, trans, _ = normalise_heading(root, trans, self.n_past - 1)
        poses = pose_features(root, self.data.joint_aa[sl])
        return {
            "poses": torch.from_numpy(poses.astype(np.float32)),
            "trans": torch.from_numpy(trans.astype(np.float32)),
            "betas": torch.from_numpy(self.data.betas[clip].astype(np.float32)),
            "clip": torch.tensor(clip),
        }
