"""The prepared walking file: selected AMASS clips at 30 fps in one compressed ``.npz``.

:func:`prepare_walking_subset` selects walking clips under an AMASS root (or the synthetic clips
of the simulator, which use the same file layout), resamples them to 30 fps
(:mod:`gaitnet.motion.amass`) and writes them concatenated along time with an index
(``clip_offset``) into one compressed ``.npz`` without pickles; :data:`PREPARED_KEYS` is the
layout. :func:`load_prepared` reads such a file back and checks every key (presence, dtype,
shape, finiteness, consistency of the index): a broken file is an :class:`AmassError` naming
the file and the key, never a numpy traceback.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from gaitnet.io.atomic import atomic_open
from gaitnet.io.npz import npz_array, open_npz
from gaitnet.motion.amass import (
    DEFAULT_EXCLUDE,
    DEFAULT_INCLUDE,
    TARGET_FPS,
    AmassError,
    DatasetSplit,
    MotionClip,
    find_amass_files,
    is_walking_clip,
    load_amass_clip,
    read_clip_list,
)
from gaitnet.motion.skeleton import N_ROTATED

__all__ = [
    "PREPARED_FORMAT_VERSION",
    "OPTIONAL_KEYS",
    "PREPARED_KEYS",
    "SPLITS",
    "PrepareReport",
    "PreparedWalking",
    "load_prepared",
    "prepare_walking_subset",
]

PREPARED_FORMAT_VERSION = 1
#: The split names a clip can have.
SPLITS: tuple[str, ...] = ("train", "val", "test")
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
#: Optional arrays (files of earlier versions lack them): each clip's own skeleton.
OPTIONAL_KEYS: dict[str, str] = {
    "clip_rest_joints": "(C, 9, 3) float32: the clip's rest joints (zeros where unknown)",
    "clip_has_rest_joints": "(C,) bool: whether the clip file carried its rest joints",
}
_STRING_KEYS = ("clip_name", "clip_dataset", "clip_split", "clip_gender")
_FLOAT_KEYS = ("clip_source_fps", "betas", "root_orient", "joint_aa", "trans")


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
        "clip_rest_joints": np.array(
            [np.zeros((9, 3)) if c.rest_joints is None else c.rest_joints for c in clips],
            dtype=np.float32,
        ),
        "clip_has_rest_joints": np.array([c.rest_joints is not None for c in clips]),
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
    clip_rest_joints: np.ndarray | None = None
    clip_has_rest_joints: np.ndarray | None = None

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
            rest_joints=self.rest_joints_of(i),
        )

    def rest_joints_of(self, i: int) -> np.ndarray | None:
        """Clip ``i``'s own rest joints (9, 3) float64, or None when its file had none."""
        if self.clip_has_rest_joints is None or not bool(self.clip_has_rest_joints[i]):
            return None
        return self.clip_rest_joints[i].astype(np.float64)


def _scalar(path: Path, key: str, value: np.ndarray, kind: str) -> float:
    if value.size != 1 or value.dtype.kind not in kind:
        raise AmassError(f"{path}: key {key!r} must be one number, got {value.dtype} {value.shape}")
    number = float(value.reshape(()))
    if not math.isfinite(number):
        raise AmassError(f"{path}: key {key!r} must be finite, got {number}")
    return number


def load_prepared(path: str | Path) -> PreparedWalking:
    """Load and check a file written by :func:`prepare_walking_subset`.

    Every key of :data:`PREPARED_KEYS` must be present with its dtype kind and shape, the
    clip index must cover the frames in increasing order, the split names must be known and
    every number finite; anything else raises :class:`AmassError` naming the file and key.
    """
    path = Path(path)
    what = "a prepared walking file (data/prepare_amass.py writes one)"
    with open_npz(path, what, AmassError) as data:
        missing = [k for k in PREPARED_KEYS if k not in data.files]
        if missing:
            raise AmassError(f"{path}: missing key(s) {missing}; re-run the AMASS preparation")
        arrays = {key: npz_array(data, path, key, AmassError) for key in PREPARED_KEYS}
        optional = {k: npz_array(data, path, k, AmassError) for k in OPTIONAL_KEYS if k in data}
    version = _scalar(path, "format_version", arrays.pop("format_version"), "iu")
    if version != PREPARED_FORMAT_VERSION:
        raise AmassError(
            f"{path}: key 'format_version' is {version:g}, this gaitnet reads "
            f"{PREPARED_FORMAT_VERSION}; re-run the AMASS preparation"
        )
    fps = _scalar(path, "fps", arrays.pop("fps"), "iuf")
    if fps <= 0:
        raise AmassError(f"{path}: key 'fps' must be positive, got {fps}")
    for key in _STRING_KEYS:
        if arrays[key].dtype.kind not in "SU":
            raise AmassError(f"{path}: key {key!r} must hold strings, got {arrays[key].dtype}")
    for key in (*_FLOAT_KEYS, "clip_offset"):
        if arrays[key].dtype.kind not in ("iu" if key == "clip_offset" else "iuf"):
            raise AmassError(f"{path}: key {key!r} has dtype {arrays[key].dtype}")
    C = arrays["clip_name"].shape[0] if arrays["clip_name"].ndim == 1 else -1
    offset = arrays["clip_offset"].astype(np.int64)
    N = arrays["root_orient"].shape[0] if arrays["root_orient"].ndim >= 1 else -1
    checks = {
        "clip_name": C > 0,
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
    for key in _FLOAT_KEYS:
        if not np.all(np.isfinite(arrays[key])):
            raise AmassError(f"{path}: key {key!r} contains NaN or inf")
    unknown = sorted(set(arrays["clip_split"].tolist()) - set(SPLITS))
    if unknown:
        raise AmassError(f"{path}: key 'clip_split' holds {unknown}, expected {list(SPLITS)}")
    arrays["clip_offset"] = offset
    if optional:
        rest, has = optional.get("clip_rest_joints"), optional.get("clip_has_rest_joints")
        if rest is None or has is None:
            raise AmassError(f"{path}: keys {list(OPTIONAL_KEYS)} must come together")
        if rest.shape != (C, 9, 3) or rest.dtype.kind not in "f" or not np.all(np.isfinite(rest)):
            raise AmassError(f"{path}: key 'clip_rest_joints' must be finite (C, 9, 3) numbers")
        if has.shape != (C,) or has.dtype.kind != "b":
            raise AmassError(f"{path}: key 'clip_has_rest_joints' must be (C,) booleans")
        arrays.update(clip_rest_joints=rest, clip_has_rest_joints=has)
    return PreparedWalking(path=path, fps=fps, **arrays)
