"""Fuzz the labelme input (no CLI command reads it: the library function is the boundary):
broken annotation files → :class:`InputError` with one line naming the file; valid ones read.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest
from oneline import assert_one_line_message

from gaitnet.errors import InputError
from gaitnet.io.labelme_io import labelme_document, labels_txt, read_labelme, read_labels_txt

H, W = 60, 80


def valid_document() -> dict:
    labels = np.zeros((H, W), np.uint8)
    instances = np.zeros_like(labels)
    cv2.rectangle(labels, (10, 5), (25, 40), 2, -1)
    cv2.rectangle(labels, (10, 41), (30, 55), 1, -1)
    instances[labels > 0] = 1
    return labelme_document(labels, instances, "frame.png")


def _doc(edit: Callable[[dict], object]) -> Callable[[Path], None]:
    def build(path: Path) -> None:
        doc = valid_document()
        edit(doc)
        path.write_text(json.dumps(doc))

    return build


def _raw(data: bytes) -> Callable[[Path], None]:
    return lambda path: path.write_bytes(data)


def _shape(**changes) -> Callable[[dict], None]:
    return lambda doc: doc["shapes"][0].update(changes)


def _image(size: tuple[int, int] | None) -> Callable[[Path], None]:
    """A valid document whose image is ``size`` (w, h) instead of 80×60, or missing."""

    def build(path: Path) -> None:
        path.write_text(json.dumps(valid_document()))
        image = path.parent / "frame.png"
        if size is None:
            image.unlink()
        else:
            cv2.imwrite(str(image), np.zeros((size[1], size[0], 3), np.uint8))

    return build


BROKEN: dict[str, Callable[[Path], None]] = {
    "not_json": _raw(b'{"shapes": [}'),
    "not_utf8": _raw(b'{"imagePath": "\xff"}'),
    "empty_file": _raw(b""),
    "top_level_list": _raw(b"[1, 2, 3]"),
    "deeply_nested": _raw(b"[" * 100_000 + b"]" * 100_000),
    "missing_shapes": _doc(lambda d: d.pop("shapes")),
    "missing_image_height": _doc(lambda d: d.pop("imageHeight")),
    "shapes_not_a_list": _doc(lambda d: d.update(shapes={"a": 1})),
    "shape_not_a_mapping": _doc(lambda d: d["shapes"].append("leg")),
    "unknown_label": _doc(_shape(label="hand")),
    "missing_label": _doc(lambda d: d["shapes"][0].pop("label")),
    "polygon_two_points": _doc(_shape(points=[[1.0, 2.0], [3.0, 4.0]])),
    "polygon_nan_point": _doc(_shape(points=[[1.0, 2.0], [float("nan"), 4.0], [5.0, 9.0]])),
    "polygon_infinite_point": _doc(_shape(points=[[1.0, 2.0], [3.0, 1e400], [5.0, 9.0]])),
    "point_of_three_values": _doc(_shape(points=[[1, 2, 3], [3, 4, 5], [5, 9, 1]])),
    "point_strings": _doc(_shape(points=[["1", "2"], ["3", "4"], ["5", "9"]])),
    "points_missing": _doc(lambda d: d["shapes"][0].pop("points")),
    "unsupported_shape_type": _doc(_shape(shape_type="mask")),
    "group_id_text": _doc(_shape(group_id="left")),
    "image_height_negative": _doc(lambda d: d.update(imageHeight=-60)),
    "image_width_float": _doc(lambda d: d.update(imageWidth=80.5)),
    "image_width_huge": _doc(lambda d: d.update(imageWidth=10**9)),
    "image_path_escapes": _doc(lambda d: d.update(imagePath="../../etc/passwd")),
    "image_path_not_text": _doc(lambda d: d.update(imagePath=7)),
    "image_path_nul": _doc(lambda d: d.update(imagePath="frame.png\x00.jpg")),
    "image_size_mismatch": _image((81, 60)),
    "image_missing": _image(None),
    "image_not_an_image": lambda path: (
        path.write_text(json.dumps(valid_document())),
        (path.parent / "frame.png").write_bytes(b"not a png"),
    ),
}


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    cv2.imwrite(str(tmp_path / "frame.png"), np.zeros((H, W, 3), np.uint8))
    return tmp_path


@pytest.mark.parametrize("case", sorted(BROKEN))
def test_broken_labelme_file_is_a_one_line_input_error(case, folder):
    path = folder / f"{case}.json"
    BROKEN[case](path)
    with pytest.raises(InputError) as excinfo:
        read_labelme(path)
    message = assert_one_line_message(excinfo, error_type=InputError)
    assert message.startswith(f"{path}: "), message


def test_messages_say_what_is_wrong(folder):
    expected = {
        "polygon_two_points": "shapes[0]: a polygon needs 3 points, got 2",
        "polygon_nan_point": "shapes[0]: point [nan, 4.0] is not a finite [x, y] pair",
        "image_size_mismatch": "image frame.png is 81×60 but the annotation says 80×60",
        "unknown_label": "shapes[0]: unknown label 'hand'",
        "image_path_nul": "holds a NUL character",
    }
    for case, fragment in expected.items():
        path = folder / f"{case}.json"
        BROKEN[case](path)
        with pytest.raises(InputError, match=fragment.replace("[", r"\[").replace("]", r"\]")):
            read_labelme(path)


@pytest.mark.parametrize(
    "content", [b"", b"\xff\xfe", b"foot\nleg\n", b"__ignore__\n_background_\nhand\n"]
)
def test_broken_labels_txt(folder, content):
    path = folder / "labels.txt"
    path.write_bytes(content)
    with pytest.raises(InputError) as excinfo:
        read_labels_txt(path)
    message = assert_one_line_message(excinfo, error_type=InputError)
    assert message.startswith(f"{path}: "), message


def test_valid_files_still_read(folder):
    (folder / "frame.json").write_text(json.dumps(valid_document()))
    cls, ins, image = read_labelme(folder / "frame.json")
    assert image == (folder / "frame.png").resolve()
    assert cls.shape == (H, W) and set(np.unique(cls)) == {0, 1, 2}
    assert (ins[cls > 0] > 0).all()
    # a rectangle (2 points) and a shape without shape_type (labelme's default polygon)
    doc = valid_document()
    doc["shapes"] = [
        {"label": "foot", "points": [[50, 10], [60, 20]], "shape_type": "rectangle"},
        {"label": "leg", "points": [[0, 0], [5, 0], [5, 5]]},
    ]
    (folder / "other.json").write_text(json.dumps(doc))
    cls, _, _ = read_labelme(folder / "other.json")
    assert (cls[10:21, 50:61] == 1).all() and cls[2, 4] == 2
    (folder / "labels.txt").write_text(labels_txt())
    assert read_labels_txt(folder / "labels.txt")["leg"] == 2
