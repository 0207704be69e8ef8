"""``gaitnet evaluate`` on label maps (gaitnet.evaluation.label_maps): scores against an
independent count, reference kinds (session ground truth, labelled set PNGs, labelme JSON),
and one-line errors."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from gaitnet.cli import main
from gaitnet.errors import InputError, SessionError
from gaitnet.evaluation.evaluate import evaluate_result
from gaitnet.evaluation.label_maps import evaluate_label_maps
from gaitnet.io.labelme_io import labelme_document, labels_txt


def _write(folder: Path, name: str, labels: np.ndarray) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    assert cv2.imwrite(str(folder / f"{name}.png"), labels)


def _pair(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    ref = np.zeros((40, 60), np.uint8)
    ref[10:30, 5:25] = 2
    ref[25:35, 30:50] = 1
    pred = ref.copy()
    flip = rng.random(ref.shape) < 0.1
    pred[flip] = rng.integers(0, 3, flip.sum())
    return pred, ref


def _iou_by_hand(preds: list[np.ndarray], refs: list[np.ndarray], c: int) -> float:
    p = np.concatenate([x.ravel() for x in preds])
    r = np.concatenate([x.ravel() for x in refs])
    keep = r != 255
    p, r = p[keep], r[keep]
    return float(np.sum((p == c) & (r == c)) / np.sum((p == c) | (r == c)))


def test_scores_against_session_ground_truth(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    preds, refs = [], []
    for t in (100, 200, 300):
        pred, ref = _pair(rng)
        ref[0, :] = 255  # ignored row
        _write(tmp_path / "res" / "labels", str(t), pred)
        _write(tmp_path / "ses" / "groundtruth" / "labels", str(t), ref)
        preds.append(pred)
        refs.append(ref)
    _write(tmp_path / "res" / "labels", "999", preds[0])  # no reference: counted, not scored
    metrics, counts = evaluate_label_maps(tmp_path / "res" / "labels", tmp_path / "ses")
    assert counts == {"label_frames": 3, "label_frames_unmatched": 1}
    ious = [_iou_by_hand(preds, refs, c) for c in range(3)]
    assert metrics["iou"] == pytest.approx(
        dict(zip(("background", "foot", "leg"), ious, strict=True))
    )
    assert metrics["miou"] == pytest.approx(np.mean(ious))
    keep = np.concatenate([r.ravel() for r in refs]) != 255
    same = np.concatenate([p.ravel() for p in preds]) == np.concatenate([r.ravel() for r in refs])
    assert metrics["pixel_acc"] == pytest.approx(same[keep].mean())
    # evaluate_result needs no other ground truth for label maps; the CLI writes the keys
    report = evaluate_result(tmp_path / "res", tmp_path / "ses")
    assert report.metrics["miou"] == pytest.approx(metrics["miou"])
    out = tmp_path / "m.json"
    assert (
        main(
            [
                "evaluate",
                str(tmp_path / "res"),
                "--session",
                str(tmp_path / "ses"),
                "--json",
                str(out),
            ]
        )
        == 0
    )
    assert {"miou", "pixel_acc", "fw_iou"} <= set(json.loads(out.read_text()))


def test_labelled_set_png_and_labelme_references_agree(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    pred, ref = _pair(rng)
    _write(tmp_path / "res" / "labels", "000007", pred)
    _write(tmp_path / "set" / "labels", "000007", ref)
    from_png, _ = evaluate_label_maps(tmp_path / "res" / "labels", tmp_path / "set")
    images = tmp_path / "lm" / "images"
    images.mkdir(parents=True)
    assert cv2.imwrite(str(images / "000007.png"), np.zeros((40, 60, 3), np.uint8))
    doc = labelme_document(ref, np.where(ref > 0, 1, 0).astype(np.int32), "000007.png")
    (images / "000007.json").write_text(json.dumps(doc))
    (tmp_path / "lm" / "labels.txt").write_text(labels_txt())
    from_json, _ = evaluate_label_maps(tmp_path / "res" / "labels", tmp_path / "lm")
    # polygons traced from the mask and rasterised by labelme differ by at most edge pixels
    assert from_json["miou"] == pytest.approx(from_png["miou"], abs=0.03)


def test_label_errors_name_the_file(tmp_path: Path) -> None:
    res = tmp_path / "res" / "labels"
    _write(res, "1", np.zeros((4, 5), np.uint8))
    with pytest.raises(SessionError, match="no ground truth for label maps: no reference labels"):
        evaluate_label_maps(res, tmp_path)
    _write(tmp_path / "ses" / "labels", "2", np.zeros((4, 5), np.uint8))
    with pytest.raises(InputError, match="no label map has a reference"):
        evaluate_label_maps(res, tmp_path / "ses")
    _write(tmp_path / "ses" / "labels", "1", np.zeros((5, 5), np.uint8))
    with pytest.raises(InputError, match=r"1\.png: label map is 5×4"):
        evaluate_label_maps(res, tmp_path / "ses")
    _write(res, "1", np.full((4, 5), 7, np.uint8))
    with pytest.raises(InputError, match="label value 7"):
        evaluate_label_maps(res, tmp_path / "ses")
    (res / "1.png").write_bytes(b"not a png")
    with pytest.raises(InputError, match=r"1\.png: not a readable PNG"):
        evaluate_label_maps(res, tmp_path / "ses")
