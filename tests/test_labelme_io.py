"""labelme JSON: masks → polygons → labelme's own rasteriser gives the masks back."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from gaitnet.errors import InputError
from gaitnet.io.labelme_io import labelme_document, labels_txt, read_labelme, read_labels_txt


def synthetic_masks() -> tuple[np.ndarray, np.ndarray]:
    labels = np.zeros((120, 160), np.uint8)
    instances = np.zeros_like(labels)
    for side, cx in ((1, 50), (2, 110)):
        leg = np.zeros_like(labels)
        cv2.ellipse(leg, (cx, 40), (12, 45), 5, 0, 360, 1, -1)
        foot = np.zeros_like(labels)
        cv2.ellipse(foot, (cx + 3, 90), (14, 24), -8, 0, 360, 1, -1)
        labels[leg > 0] = 2
        labels[foot > 0] = 1
        instances[(leg > 0) | (foot > 0)] = side
    return labels, instances


def iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / max(1, (a | b).sum()))


def test_round_trip_through_labelme(tmp_path: Path) -> None:
    labels, instances = synthetic_masks()
    cv2.imwrite(str(tmp_path / "f.png"), np.zeros((120, 160, 3), np.uint8))
    doc = labelme_document(labels, instances, "f.png")
    assert {s["label"] for s in doc["shapes"]} == {"foot", "leg"}
    (tmp_path / "f.json").write_text(json.dumps(doc))
    cls, ins, image = read_labelme(tmp_path / "f.json")
    assert image == (tmp_path / "f.png").resolve()
    for value in (1, 2):
        assert iou(cls == value, labels == value) > 0.93
    for side in (1, 2):
        inst_values = np.unique(ins[(instances == side) & (labels == 1)])
        assert len(inst_values) == 1 and inst_values[0] > 0


def test_image_path_may_not_escape(tmp_path: Path) -> None:
    labels, instances = synthetic_masks()
    doc = labelme_document(labels, instances, "../../etc/passwd")
    (tmp_path / "x.json").write_text(json.dumps(doc))
    with pytest.raises(InputError, match="escapes the annotation folder"):
        read_labelme(tmp_path / "x.json")


def test_unknown_label_and_missing_key(tmp_path: Path) -> None:
    labels, instances = synthetic_masks()
    doc = labelme_document(labels, instances, "f.png")
    doc["shapes"][0]["label"] = "hand"
    (tmp_path / "a.json").write_text(json.dumps(doc))
    with pytest.raises(InputError, match=r"a.json: shapes\[0\]: unknown label 'hand'"):
        read_labelme(tmp_path / "a.json")
    del doc["imageHeight"]
    (tmp_path / "b.json").write_text(json.dumps(doc))
    with pytest.raises(InputError, match="b.json: missing key 'imageHeight'"):
        read_labelme(tmp_path / "b.json")


def test_labels_txt(tmp_path: Path) -> None:
    (tmp_path / "labels.txt").write_text(labels_txt())
    assert read_labels_txt(tmp_path / "labels.txt") == {
        "__ignore__": 255,
        "_background_": 0,
        "foot": 1,
        "leg": 2,
    }
    (tmp_path / "bad.txt").write_text("foot\nleg\n")
    with pytest.raises(InputError, match="must start with"):
        read_labels_txt(tmp_path / "bad.txt")


def test_holes_and_unsided_regions_round_trip(tmp_path: Path) -> None:
    """A leg ring keeps its hole (a ``_background_`` polygon painted after it) and a region of
    unknown side is written without a group id."""
    labels = np.zeros((120, 160), np.uint8)
    cv2.circle(labels, (60, 60), 40, 2, -1)
    cv2.circle(labels, (60, 60), 15, 0, -1)
    cv2.rectangle(labels, (120, 20), (140, 60), 1, -1)
    instances = np.where(labels == 2, 1, 0).astype(np.int32)  # the foot's side unknown
    cv2.imwrite(str(tmp_path / "f.png"), np.zeros((120, 160, 3), np.uint8))
    doc = labelme_document(labels, instances, "f.png")
    assert [(s["label"], s["group_id"]) for s in doc["shapes"]] == [
        ("leg", 1), ("_background_", None), ("foot", None),
    ]  # fmt: skip
    (tmp_path / "f.json").write_text(json.dumps(doc))
    cls, _, _ = read_labelme(tmp_path / "f.json")
    assert cls[60, 60] == 0
    for value in (0, 1, 2):
        assert iou(cls == value, labels == value) > 0.95


def test_a_hole_with_a_region_inside_is_not_painted_over_it(tmp_path: Path) -> None:
    """A foot inside the hole of a leg ring survives (the hole stays the leg's), and a foot
    ring's empty hole is background again."""
    labels = np.zeros((100, 120), np.uint8)
    cv2.circle(labels, (50, 50), 40, 2, -1)
    cv2.circle(labels, (50, 50), 15, 0, -1)
    cv2.circle(labels, (50, 50), 5, 1, -1)
    cv2.circle(labels, (100, 30), 12, 1, -1)
    cv2.circle(labels, (100, 30), 5, 0, -1)
    cv2.imwrite(str(tmp_path / "f.png"), np.zeros((100, 120, 3), np.uint8))
    doc = labelme_document(labels, np.zeros(labels.shape, np.int32), "f.png")
    assert [s["label"] for s in doc["shapes"]] == ["leg", "foot", "foot", "_background_"]
    (tmp_path / "f.json").write_text(json.dumps(doc))
    cls, _, _ = read_labelme(tmp_path / "f.json")
    assert cls[50, 50] == 1 and iou(cls == 1, labels == 1) > 0.9
    assert cls[30, 100] == 0
    assert cls[50, 38] == 2  # the leg's hole around the foot stays the leg's
