"""labelme annotations: label maps ⇄ labelme JSON polygons, and the ``labels.txt`` class list.

Class values follow DESIGN.md: ``_background_`` 0, ``foot`` 1, ``leg`` 2, ``__ignore__`` 255.
Masks are rasterised with labelme's own ``labelme.utils.shapes_to_label``, so what we read is
exactly what labelme's converters (``labelme_export_json``, ``labelme2voc.py``) would produce.
Shapes are painted in file order; we write legs before feet, so a foot drawn over a leg wins.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from gaitnet.errors import SessionError

DEFAULT_CLASSES = ("__ignore__", "_background_", "foot", "leg")
CLASS_VALUES = {"__ignore__": 255, "_background_": 0, "foot": 1, "leg": 2}
INSTANCE_GROUPS = {1: "left", 2: "right"}


def labels_txt(classes: Sequence[str] = DEFAULT_CLASSES) -> str:
    """The ``labels.txt`` labelme expects (``__ignore__`` and ``_background_`` first)."""
    return "\n".join(classes) + "\n"


def read_labels_txt(path: Path) -> dict[str, int]:
    """Class name → label value from a labelme ``labels.txt``.

    ``__ignore__`` maps to 255 and ``_background_`` to 0; the remaining classes must be ours.
    """
    names = [n.strip() for n in path.read_text(encoding="utf-8").splitlines() if n.strip()]
    if names[:2] != ["__ignore__", "_background_"]:
        raise SessionError(f"{path}: must start with '__ignore__' and '_background_'")
    unknown = [n for n in names if n not in CLASS_VALUES]
    if unknown:
        raise SessionError(f"{path}: unknown class(es) {unknown}; known: {sorted(CLASS_VALUES)}")
    return {n: CLASS_VALUES[n] for n in names}


def _polygons(mask: np.ndarray, min_area_px: float) -> list[list[list[float]]]:
    contours, _ = cv2.findContours(
        mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE
    )
    polygons = []
    for contour in contours:
        if cv2.contourArea(contour) < min_area_px or len(contour) < 3:
            continue
        polygons.append([[float(x), float(y)] for x, y in contour[:, 0, :]])
    return polygons


def labelme_document(
    labels: np.ndarray,
    instances: np.ndarray,
    image_path: str,
    min_area_px: float = 4.0,
) -> dict:
    """A labelme JSON document (dict) with one polygon per connected region of each class.

    ``group_id`` is 1 for the left and 2 for the right side (from ``instances``).
    """
    shapes = []
    for name in ("leg", "foot"):
        value = CLASS_VALUES[name]
        for group_id in sorted(INSTANCE_GROUPS):
            mask = (labels == value) & (instances == group_id)
            for points in _polygons(mask, min_area_px):
                shapes.append(
                    {
                        "label": name,
                        "points": points,
                        "group_id": group_id,
                        "description": INSTANCE_GROUPS[group_id],
                        "shape_type": "polygon",
                        "flags": {},
                    }
                )
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
    """The image a labelme JSON refers to; it must stay inside the JSON's folder tree."""
    folder = json_path.parent.resolve()
    candidate = (folder / image_path).resolve()
    if not candidate.is_relative_to(folder):
        raise SessionError(f"{json_path}: imagePath {image_path!r} escapes the annotation folder")
    return candidate


def read_labelme(json_path: Path, class_values: dict[str, int] | None = None):
    """Read a labelme JSON: (label map uint8, instance map int32, image path).

    Unknown labels, missing keys and image paths outside the folder are errors naming the file.
    """
    from labelme.utils import shapes_to_label

    class_values = class_values or CLASS_VALUES
    try:
        doc = json.loads(Path(json_path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise SessionError(f"{json_path}: not a readable labelme JSON ({exc})") from exc
    for key in ("shapes", "imagePath", "imageHeight", "imageWidth"):
        if key not in doc:
            raise SessionError(f"{json_path}: missing key '{key}'")
    image = resolve_image_path(Path(json_path), doc["imagePath"])
    for shape in doc["shapes"]:
        if shape.get("label") not in class_values:
            raise SessionError(
                f"{json_path}: unknown label {shape.get('label')!r} (known: {sorted(class_values)})"
            )
    shape_hw = (int(doc["imageHeight"]), int(doc["imageWidth"]))
    cls, ins = shapes_to_label(shape_hw, doc["shapes"], class_values)
    return cls.astype(np.uint8), ins, image
