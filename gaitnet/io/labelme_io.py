"""labelme annotations: label maps ⇄ labelme JSON polygons, and the ``labels.txt`` class list.

Class values follow docs/design.md, *Conventions*: ``_background_`` 0, ``foot`` 1, ``leg`` 2,
``__ignore__`` 255.
Masks are rasterised with labelme's own ``labelme.utils.shapes_to_label``, so what we read is
exactly what labelme's converters (``labelme_export_json``, ``labelme2voc.py``) would produce.
Shapes are painted in file order; we write legs before feet, so a foot drawn over a leg wins.

Reading checks every value before labelme sees it; each problem is an
:class:`~gaitnet.errors.InputError` with one line naming the file (and the shape): JSON that
does not parse or is not UTF-8, missing or wrongly typed keys, shapes other than polygons (≥ 3
points) and rectangles (2 points), points that are not finite ``[x, y]`` pairs, labels not in
the class list, an ``imagePath`` outside the JSON's folder or holding a NUL character, a
missing image, and an image whose size differs from ``imageWidth`` × ``imageHeight``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from gaitnet.errors import InputError

DEFAULT_CLASSES = ("__ignore__", "_background_", "foot", "leg")
MAX_IMAGE_SIDE = 32768
"""Largest ``imageWidth`` / ``imageHeight`` accepted (guards the mask allocation)."""
MAX_COORDINATE = 1e6
SHAPE_POINTS = {"polygon": 3, "rectangle": 2}  # supported shape types -> (minimum) points
CLASS_VALUES = {"__ignore__": 255, "_background_": 0, "foot": 1, "leg": 2}
INSTANCE_GROUPS = {1: "left", 2: "right"}


def labels_txt(classes: Sequence[str] = DEFAULT_CLASSES) -> str:
    """The ``labels.txt`` labelme expects (``__ignore__`` and ``_background_`` first)."""
    return "\n".join(classes) + "\n"


def _read_text(path: Path) -> str:
    try:
        raw = Path(path).read_bytes()
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror})") from None
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not UTF-8 text (bad byte at offset {exc.start})") from None


def read_labels_txt(path: Path) -> dict[str, int]:
    """Class name → label value from a labelme ``labels.txt``.

    ``__ignore__`` maps to 255 and ``_background_`` to 0; the remaining classes must be ours.
    """
    names = [n.strip() for n in _read_text(path).splitlines() if n.strip()]
    if names[:2] != ["__ignore__", "_background_"]:
        raise InputError(f"{path}: must start with '__ignore__' and '_background_'")
    unknown = [n for n in names if n not in CLASS_VALUES]
    if unknown:
        raise InputError(f"{path}: unknown class(es) {unknown}; known: {sorted(CLASS_VALUES)}")
    return {n: CLASS_VALUES[n] for n in names}


def _outlines(mask: np.ndarray, min_area_px: float) -> tuple[list, list[list[list[float]]]]:
    """The outer contours of ``mask``'s regions (OpenCV's) and the same as ``[x, y]`` point
    lists; regions enclosing less than ``min_area_px`` are left out."""
    contours, _ = cv2.findContours(
        mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE
    )
    kept = [c for c in contours if len(c) >= 3 and cv2.contourArea(c) >= min_area_px]
    return kept, [[[float(x), float(y)] for x, y in c[:, 0, :]] for c in kept]


def _polygons(
    mask: np.ndarray, min_area_px: float, background: np.ndarray
) -> tuple[list[list[list[float]]], list[list[list[float]]]]:
    """The outlines of ``mask``'s regions, and the outlines of the holes inside them that hold
    ``background`` pixels alone (the pixels the filled outlines cover that are not ``mask``'s;
    a hole with anything else inside stays filled, so that painting it as background cannot
    erase a region drawn before it)."""
    contours, outer = _outlines(mask, min_area_px)
    filled = np.zeros(mask.shape, np.uint8)
    cv2.drawContours(filled, contours, -1, 1, thickness=cv2.FILLED)
    hole_contours, hole_points = _outlines((filled > 0) & ~mask.astype(bool), min_area_px)
    holes = []
    for contour, points in zip(hole_contours, hole_points, strict=True):
        x, y, w, h = cv2.boundingRect(contour)
        inside = np.zeros((h, w), np.uint8)
        cv2.drawContours(inside, [contour], -1, 1, thickness=cv2.FILLED, offset=(-x, -y))
        if background[y : y + h, x : x + w][inside > 0].all():
            holes.append(points)
    return outer, holes


def labelme_document(
    labels: np.ndarray,
    instances: np.ndarray,
    image_path: str,
    min_area_px: float = 4.0,
) -> dict:
    """A labelme JSON document (dict) with one polygon per connected region of each class,
    followed by a ``_background_`` polygon per hole in those regions that holds background
    alone (labelme polygons have no holes; painted in order, the hole is background again; a
    hole with another region inside stays filled with its region's class).

    ``group_id`` is 1 for the left and 2 for the right side (from ``instances``); regions of
    side 0 (unknown) have none.
    """
    shapes = []
    for name in ("leg", "foot"):
        value = CLASS_VALUES[name]
        for group_id in (*sorted(INSTANCE_GROUPS), 0):
            mask = (labels == value) & (instances == group_id)
            outer, holes = _polygons(mask, min_area_px, labels == 0)
            for label, polygons in ((name, outer), ("_background_", holes)):
                shapes += [
                    {
                        "label": label,
                        "points": points,
                        "group_id": group_id or None if label == name else None,
                        "description": INSTANCE_GROUPS.get(group_id, "") if label == name else "",
                        "shape_type": "polygon",
                        "flags": {},
                    }
                    for points in polygons
                ]
    height, width = labels.shape
    return {
        "version": "5.5.0",
        "flags": {},
        "shapes": shapes,
        "imagePath": image_path,
        "imageData": None,
        "imageHeight": int(height),
        "imageWidth": int(width),
    }


def resolve_image_path(json_path: Path, image_path: str) -> Path:
    """The image a labelme JSON refers to; it must stay inside the JSON's folder tree and be
    a name a file system can hold (no NUL character)."""
    if "\x00" in image_path:
        raise InputError(
            f"{json_path}: imagePath {image_path!r:.80} holds a NUL character (not a file name)"
        )
    folder = json_path.parent.resolve()
    candidate = (folder / image_path).resolve()
    if not candidate.is_relative_to(folder):
        raise InputError(f"{json_path}: imagePath {image_path!r} escapes the annotation folder")
    return candidate


def _check_shape(json_path: Path, k: int, shape: Any, class_values: dict[str, int]) -> None:
    where = f"{json_path}: shapes[{k}]"
    if not isinstance(shape, dict):
        raise InputError(f"{where} must be a mapping, got {type(shape).__name__}")
    label = shape.get("label")
    if label not in class_values:
        raise InputError(f"{where}: unknown label {label!r} (known: {sorted(class_values)})")
    shape_type = shape.get("shape_type") or "polygon"
    if shape_type not in SHAPE_POINTS:
        raise InputError(
            f"{where}: shape_type {shape_type!r} is not supported "
            f"(supported: {', '.join(SHAPE_POINTS)})"
        )
    group_id = shape.get("group_id")
    if group_id is not None and (isinstance(group_id, bool) or not isinstance(group_id, int)):
        raise InputError(f"{where}: group_id must be an integer or null, got {group_id!r}")
    points = shape.get("points")
    if not isinstance(points, list):
        raise InputError(f"{where}: 'points' must be a list of [x, y], got {points!r:.60}")
    need = SHAPE_POINTS[shape_type]
    if len(points) < need or (shape_type == "rectangle" and len(points) != need):
        raise InputError(f"{where}: a {shape_type} needs {need} points, got {len(points)}")
    for point in points:
        ok = isinstance(point, list) and len(point) == 2
        ok = ok and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in point)
        if not ok or not all(math.isfinite(v) and abs(v) < MAX_COORDINATE for v in point):
            raise InputError(f"{where}: point {point!r:.60} is not a finite [x, y] pair")


def _image_size(json_path: Path, image: Path) -> tuple[int, int]:
    from PIL import Image, UnidentifiedImageError  # a labelme dependency

    if not image.is_file():
        raise InputError(f"{json_path}: image {image} not found")
    try:
        with Image.open(image) as im:
            width, height = im.size
    except (UnidentifiedImageError, OSError) as exc:
        raise InputError(f"{json_path}: image {image} cannot be read ({exc})") from None
    return int(width), int(height)


def read_labelme(json_path: Path, class_values: dict[str, int] | None = None):
    """Read a labelme JSON: (label map uint8, instance map int32, image path).

    Every value is checked first (module docstring); errors are one-line
    :class:`~gaitnet.errors.InputError` messages naming the file.
    """
    from labelme.utils import shapes_to_label

    json_path = Path(json_path)
    class_values = class_values or CLASS_VALUES
    text = _read_text(json_path)
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{json_path}: not valid JSON ({exc})") from None
    except RecursionError:
        raise InputError(f"{json_path}: not valid JSON (nested too deeply)") from None
    if not isinstance(doc, dict):
        raise InputError(f"{json_path}: must be a JSON object, got {type(doc).__name__}")
    for key in ("shapes", "imagePath", "imageHeight", "imageWidth"):
        if key not in doc:
            raise InputError(f"{json_path}: missing key '{key}'")
    if not isinstance(doc["shapes"], list):
        raise InputError(f"{json_path}: 'shapes' must be a list")
    if not isinstance(doc["imagePath"], str) or not doc["imagePath"]:
        raise InputError(f"{json_path}: 'imagePath' must be a file name")
    size = []
    for key in ("imageWidth", "imageHeight"):
        value = doc[key]
        if isinstance(value, bool) or not isinstance(value, int):
            raise InputError(f"{json_path}: '{key}' must be an integer, got {value!r:.40}")
        if not 0 < value <= MAX_IMAGE_SIDE:
            raise InputError(f"{json_path}: '{key}' {value} is outside 1..{MAX_IMAGE_SIDE}")
        size.append(value)
    for k, shape in enumerate(doc["shapes"]):
        _check_shape(json_path, k, shape, class_values)
    image = resolve_image_path(json_path, doc["imagePath"])
    actual = _image_size(json_path, image)
    if actual != tuple(size):
        raise InputError(
            f"{json_path}: image {image.name} is {actual[0]}×{actual[1]} but the annotation "
            f"says {size[0]}×{size[1]} (imageWidth × imageHeight)"
        )
    cls, ins = shapes_to_label((size[1], size[0]), doc["shapes"], class_values)
    return cls.astype(np.uint8), ins, image
