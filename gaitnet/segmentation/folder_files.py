"""The files of a labelled segmentation folder (layout: :mod:`gaitnet.segmentation.dataset`):
frame ids and split files, ``camera.yaml``, ``frames.csv`` (gravity), images with their size and
value checks, and the sides of labelme shapes. Every problem is a one-line
:class:`~gaitnet.errors.InputError` naming the file."""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import re
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
import yaml

from gaitnet.errors import InputError
from gaitnet.io.atomic import atomic_write_text
from gaitnet.io.types import CameraIntrinsics

__all__ = [
    "IMAGE_SUFFIXES",
    "LABEL_VALUES",
    "SIDE_VALUES",
    "SPLIT_FRACTIONS",
    "camera_yaml_text",
    "check_id",
    "check_size",
    "check_values",
    "default_split",
    "find_image",
    "labelme_sides",
    "list_frames",
    "read_camera_yaml",
    "read_gravity_csv",
    "read_image",
    "read_split",
    "write_split",
]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
SPLIT_FRACTIONS = {"train": 0.8, "val": 0.1, "test": 0.1}
LABEL_VALUES = (0, 1, 2, 255)
SIDE_VALUES = (0, 1, 2)
SIDE_NAMES = {"left": 1, "right": 2}
MAX_ID_LENGTH = 200
_ID = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$")


# ----------------------------------------------------------------------------------- ids


def check_id(frame_id: str, where: str) -> str:
    if (
        not isinstance(frame_id, str)
        or not _ID.match(frame_id)
        or ".." in frame_id
        or len(frame_id) > MAX_ID_LENGTH
    ):
        raise InputError(
            f"{where}: frame id {frame_id!r:.60} is not a plain file name (letters, digits, "
            "'_', '-', '.'; no '..' or '/')"
        )
    return frame_id


def read_split(path: str | Path, root: str | Path | None = None) -> list[str]:
    """Frame ids of a split file (one per line; blank lines and ``#`` comments skipped).

    Ids must be plain file names and unique; with ``root``, each must have an image in
    ``root/images`` (else an :class:`InputError` naming the split file and the id).
    """
    path = Path(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except OSError as exc:
        raise InputError(f"{path}: cannot read split file ({exc.strerror})") from None
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not UTF-8 text (bad byte at offset {exc.start})") from None
    ids: list[str] = []
    seen: set[str] = set()
    for n, line in enumerate(text.splitlines(), 1):
        item = line.split("#", 1)[0].strip()
        if not item:
            continue
        check_id(item, f"{path}:{n}")
        if item in seen:
            raise InputError(f"{path}:{n}: frame id {item!r} listed twice")
        seen.add(item)
        ids.append(item)
    if root is not None:
        for frame_id in ids:
            if find_image(Path(root), frame_id) is None:
                raise InputError(
                    f"{path}: unknown frame id {frame_id!r} (no image {frame_id}.png or .jpg "
                    f"in {Path(root) / 'images'})"
                )
    return ids


def write_split(path: str | Path, ids: Sequence[str]) -> None:
    """Write a split file (one id per line) atomically; ids are checked as in read_split."""
    ids = list(ids)
    for frame_id in ids:
        check_id(frame_id, str(path))
    if len(set(ids)) != len(ids):
        raise InputError(f"{path}: frame ids listed twice")
    atomic_write_text(path, "".join(f"{i}\n" for i in ids))


def default_split(
    ids: Sequence[str], fractions: dict[str, float] | None = None
) -> dict[str, list[str]]:
    """Deterministic split by a hash of each id alone (module docstring); ids keep their order.

    ``fractions`` (default :data:`SPLIT_FRACTIONS`) maps split name → share (summing to 1).
    """
    fractions = fractions or SPLIT_FRACTIONS
    total = sum(fractions.values())
    if not fractions or not math.isclose(total, 1.0, abs_tol=1e-6):
        raise InputError(f"split fractions must sum to 1, got {fractions}")
    bounds = np.cumsum(list(fractions.values()))
    out: dict[str, list[str]] = {name: [] for name in fractions}
    names = list(fractions)
    for frame_id in ids:
        digest = hashlib.sha256(f"gaitnet-split:{frame_id}".encode()).digest()
        x = int.from_bytes(digest[:8], "big") / 2.0**64
        out[names[min(int(np.searchsorted(bounds, x, side="right")), len(names) - 1)]].append(
            frame_id
        )
    return out


def find_image(root: Path, frame_id: str) -> Path | None:
    for suffix in IMAGE_SUFFIXES:
        path = root / "images" / f"{frame_id}{suffix}"
        if path.is_file():
            return path
    return None


def list_frames(root: str | Path) -> list[str]:
    """Sorted ids of the labelled frames: an image with a labelme JSON or a label PNG."""
    root = Path(root)
    images = root / "images"
    if not images.is_dir():
        raise InputError(f"{root}: no images/ folder (not a segmentation data set)")
    ids = set()
    for path in images.iterdir():
        if path.suffix.lower() not in IMAGE_SUFFIXES or not _ID.match(path.stem):
            continue
        if (images / f"{path.stem}.json").is_file() or (
            root / "labels" / f"{path.stem}.png"
        ).is_file():
            ids.add(path.stem)
    return sorted(ids)


# ------------------------------------------------------------------ camera.yaml, frames.csv


def camera_yaml_text(intr: CameraIntrinsics, depth_scale_m: float) -> str:
    """A folder's camera.yaml (what :func:`read_camera_yaml` reads) for these intrinsics."""
    camera = {
        "width": intr.width,
        "height": intr.height,
        "fx": intr.fx,
        "fy": intr.fy,
        "cx": intr.cx,
        "cy": intr.cy,
        "depth_scale_m": depth_scale_m,
    }
    return yaml.safe_dump(camera, sort_keys=False)


def read_camera_yaml(path: Path) -> tuple[CameraIntrinsics, float]:
    """(intrinsics, depth scale [m per unit]) of a folder's camera.yaml."""
    try:
        data = yaml.safe_load(path.read_bytes())
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror})") from None
    except yaml.YAMLError as exc:
        raise InputError(f"{path}: not valid YAML ({str(exc).splitlines()[0]})") from None
    if not isinstance(data, dict):
        raise InputError(f"{path}: must be a mapping of width, height, fx, fy, cx, cy")
    keys = ("width", "height", "fx", "fy", "cx", "cy")
    missing = [k for k in keys if k not in data]
    if missing:
        raise InputError(f"{path}: missing key(s) {missing}")
    unknown = sorted(set(data) - {*keys, "depth_scale_m", "distortion"})
    if unknown:
        raise InputError(f"{path}: unknown key(s) {unknown}")
    try:
        intr = CameraIntrinsics(**{k: data[k] for k in keys if k in data})
    except (TypeError, ValueError) as exc:
        raise InputError(f"{path}: {exc}") from None
    scale = data.get("depth_scale_m", 0.001)
    if (
        isinstance(scale, bool)
        or not isinstance(scale, (int, float))
        or not math.isfinite(scale)
        or not 0 < scale <= 1
    ):
        raise InputError(f"{path}: depth_scale_m must be within (0, 1] m, got {scale!r}")
    return intr, float(scale)


def read_gravity_csv(path: Path) -> dict[str, np.ndarray | None]:
    """id → unit gravity (camera frame, pointing down) or None (empty cells) from frames.csv."""
    try:
        text = path.read_bytes().decode("utf-8")
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror})") from None
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not UTF-8 text (bad byte at offset {exc.start})") from None
    reader = csv.DictReader(io.StringIO(text))
    cols = ("gravity_cx", "gravity_cy", "gravity_cz")
    if reader.fieldnames is None or "id" not in reader.fieldnames:
        raise InputError(f"{path}: needs a header with an 'id' column")
    if not set(cols) <= set(reader.fieldnames):
        return {}
    out: dict[str, np.ndarray | None] = {}
    for n, row in enumerate(reader, 2):
        cells = [(row.get(c) or "").strip() for c in cols]
        frame_id = (row.get("id") or "").strip()
        if not any(cells):
            out[frame_id] = None
            continue
        try:
            g = np.array([float(c) for c in cells])
        except ValueError:
            raise InputError(f"{path}:{n}: gravity {cells} is not three numbers") from None
        norm = float(np.linalg.norm(g))
        if not np.isfinite(g).all() or not 0.5 < norm < 2.0:
            raise InputError(f"{path}:{n}: gravity {cells} is not a unit vector")
        out[frame_id] = g / norm
    return out


# ------------------------------------------------------------------------------ readers


def read_image(path: Path, flags: int, what: str) -> np.ndarray:
    if not path.is_file():
        raise InputError(f"{path}: {what} not found")
    data = np.fromfile(path, np.uint8)
    image = cv2.imdecode(data, flags) if data.size else None
    if image is None:
        raise InputError(f"{path}: cannot decode {what} (corrupt or not an image)")
    return image


def check_size(path: Path, image: np.ndarray, intr: CameraIntrinsics, what: str) -> None:
    if image.shape[:2] != (intr.height, intr.width):
        raise InputError(
            f"{path}: {what} is {image.shape[1]}×{image.shape[0]}, expected "
            f"{intr.width}×{intr.height} (camera.yaml)"
        )


def check_values(path: Path, image: np.ndarray, allowed: tuple[int, ...], what: str) -> None:
    bad = np.setdiff1d(np.unique(image), allowed)
    if bad.size:
        raise InputError(f"{path}: {what} has values {bad[:5].tolist()}, allowed {allowed}")


def _side_of(shape: dict) -> str:
    group = shape.get("group_id")
    if group in (1, 2) and not isinstance(group, bool):
        return "left" if group == 1 else "right"
    text = str(shape.get("description") or "").lower()
    has = [name for name in SIDE_NAMES if re.search(rf"\b{name}\b", text)]
    return has[0] if len(has) == 1 else "none"


def labelme_sides(json_path: Path, height: int, width: int) -> np.ndarray:
    """Side map (uint8) of a labelme JSON already checked by ``read_labelme``."""
    from labelme.utils import shapes_to_label

    doc = json.loads(json_path.read_bytes().decode("utf-8"))
    shapes = [{**s, "label": _side_of(s), "group_id": None} for s in doc["shapes"]]
    side, _ = shapes_to_label((height, width), shapes, {"none": 0, **SIDE_NAMES})
    return side.astype(np.uint8)


# ------------------------------------------------------------------------------ the set
