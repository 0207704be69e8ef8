"""Adapting the segmenter to one's own footage (docs/recording.md): ``gaitnet segment
--label-frames`` writes pre-labelled frames as a labelme folder, the training script starts
from a segmenter's ONNX export (its weights read back from the graph), and the fine-tuned net
exports and segments again."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import cv2
import numpy as np
import onnx
import pytest
import torch
import yaml
from oneline import assert_one_line_exit
from scriptload import load_script

from gaitnet.cli import main
from gaitnet.config import load_config
from gaitnet.errors import InputError
from gaitnet.io import open_session
from gaitnet.segmentation.dataset import SegmentationFolder
from gaitnet.segmentation.label_frames import frames_to_label
from gaitnet.segmentation.onnx_runtime import export_segmenter_onnx
from gaitnet.segmentation.segment_session import accelerometer_gravity_C
from gaitnet.segmentation.segmenter_net import build_segmenter
from gaitnet.sim.config import SimConfig
from gaitnet.sim.dataset import simulate_dataset
from gaitnet.training.checkpoint import load_checkpoint
from gaitnet.training.onnx_weights import segmenter_from_onnx

ROOT = Path(__file__).parents[1]
COMMITTED = ROOT / "models" / "segmenter" / "fcn8s_fusion_small.onnx"


@pytest.fixture(scope="module")
def labelled(tmp_path_factory, tiny_sim_session: Path, tiny_model: Path) -> Path:
    out = tmp_path_factory.mktemp("own") / "frames"
    argv = ["segment", str(tiny_sim_session), "--out", str(out), "--model", str(tiny_model)]
    assert main([*argv, "--label-frames", "4"]) == 0
    return out


def _in_regions_of_at_least(labels: np.ndarray, pixels: int) -> np.ndarray:
    """Pixels in a 4-connected region of one class with at least ``pixels`` pixels."""
    keep = np.zeros(labels.shape, bool)
    for cls in np.unique(labels):
        n, comp, stats, _ = cv2.connectedComponentsWithStats((labels == cls).astype(np.uint8), 4)
        big = np.flatnonzero(stats[:, cv2.CC_STAT_AREA] >= pixels)
        keep |= np.isin(comp, big[big > 0]) & (labels == cls)
    return keep


def test_frames_to_label_spread_over_the_session() -> None:
    assert frames_to_label(10, 4) == [0, 3, 6, 9]
    assert frames_to_label(3, 8) == [0, 1, 2]
    assert frames_to_label(100, 1) == [0]


def test_label_frames_are_the_segmenters_labels_as_labelme_polygons(
    tmp_path: Path, labelled: Path, tiny_sim_session: Path, tiny_model: Path
) -> None:
    """Each pre-labelled frame read back as training data: its image and depth are the
    session's, its gravity the accelerometer's, and its polygons rasterise to the label map
    ``gaitnet segment`` writes for that frame (up to the polygons' pixel rounding)."""
    session = open_session(tiny_sim_session)
    seg = tmp_path / "seg"
    assert (
        main(["segment", str(tiny_sim_session), "--out", str(seg), "--model", str(tiny_model)]) == 0
    )
    picked = frames_to_label(len(session), 4)
    ids = [str(session.frame_times_ns[i]) for i in picked]
    folder = SegmentationFolder(labelled, None)
    assert sorted(folder.ids) == sorted(ids)
    with open(labelled / "frames.csv", newline="") as f:
        gravity = {row["id"]: row for row in csv.DictReader(f)}
    calib = session.calibration
    for index, frame_id in zip(picked, ids, strict=True):
        frame = session.frame(index)
        rgb = cv2.cvtColor(
            cv2.imread(str(labelled / "images" / f"{frame_id}.png")), cv2.COLOR_BGR2RGB
        )
        np.testing.assert_array_equal(rgb, frame.rgb)
        units = cv2.imread(str(labelled / "depth" / f"{frame_id}.png"), cv2.IMREAD_UNCHANGED)
        np.testing.assert_allclose(units * calib.depth_scale_m, frame.depth_m, atol=0.0005 + 1e-6)
        g = accelerometer_gravity_C(session.imu, calib.T_CfromI, frame.t_ns, 1.0)
        row = gravity[frame_id]
        np.testing.assert_allclose([float(row[f"gravity_c{a}"]) for a in "xyz"], g, atol=1e-8)
        expected = cv2.imread(str(seg / "labels" / f"{frame_id}.png"), cv2.IMREAD_UNCHANGED)
        got = folder[folder.ids.index(frame_id)]["label"].numpy()
        # The random model's labels are speckled: regions of 20 pixels or more (of any class)
        # are reproduced, specks below labelme_document's 4 px² are left out.
        large = _in_regions_of_at_least(expected, 20)
        assert large.sum() > 0.5 * large.size
        assert np.mean(got[large] == expected[large]) > 0.9  # 0.94: holes with specks stay filled
    doc = json.loads(next((labelled / "images").glob("*.json")).read_text())
    assert {s["label"] for s in doc["shapes"]} <= {"foot", "leg", "_background_"}
    assert (labelled / "labels.txt").read_text().split() == [
        "__ignore__", "_background_", "foot", "leg",
    ]  # fmt: skip


def test_label_frames_bad_count_is_one_line(tmp_path, tiny_sim_session, capsys) -> None:
    argv = ["segment", str(tiny_sim_session), "--out", str(tmp_path / "x"), "--label-frames"]
    assert_one_line_exit(capsys, main([*argv, "0"]), "--label-frames must be within 1–10000")
    assert_one_line_exit(capsys, main([*argv, "10001"]), "--label-frames must be within 1–10000")
    assert not (tmp_path / "x").exists()


def test_weights_read_back_from_an_export_are_the_nets(tmp_path: Path) -> None:
    torch.manual_seed(3)
    net = build_segmenter("fusion", width=1 / 16, input_scale=0.5, padding="same",
                          output_stride=4, logit_bias=[0.0, -0.5, 0.25]).eval()  # fmt: skip
    with torch.no_grad():
        for p in net.parameters():
            p.normal_(0.0, 0.1)
    path = tmp_path / "net.onnx"
    export_segmenter_onnx(net, path, height=48, width=64)
    back = segmenter_from_onnx(path)
    assert back.config() == net.config()
    ours, theirs = net.state_dict(), back.state_dict()
    assert ours.keys() == theirs.keys()
    for key in ours:
        assert torch.equal(ours[key], theirs[key]), key


def test_the_committed_segmenter_reads_back_within_parity() -> None:
    """The committed model's weights rebuild its net (segmenter_from_onnx refuses one whose
    logits differ from onnxruntime's by more than 1e-3)."""
    net = segmenter_from_onnx(COMMITTED)
    assert net.config()["arch"] == "fusion" and net.config()["output_stride"] == 4


def test_an_onnx_that_is_no_segmenter_export_is_refused(tmp_path: Path, tiny_model: Path) -> None:
    predictor = ROOT / "models" / "predictor" / "dctgcn_walk_small.onnx"
    with pytest.raises(InputError, match="not a gaitnet segmenter export"):
        segmenter_from_onnx(predictor)
    model = onnx.load(str(tiny_model))
    for node in model.graph.node:
        del node.metadata_props[:]
    stripped = tmp_path / "stripped.onnx"
    onnx.save(model, str(stripped))
    with pytest.raises(InputError, match="has no module scope"):
        segmenter_from_onnx(stripped)


def test_fine_tuning_from_an_export_on_labelme_frames_end_to_end(
    tmp_path: Path, labelled: Path, tiny_sim_session: Path, tiny_model: Path
) -> None:
    """Pre-labelled frames (as if corrected) mixed with simulated ones train a net that starts
    from the ONNX export's weights (at a learning rate of 1e-9 it stays there), which exports
    and segments the session again."""
    calib = open_session(tiny_sim_session).calibration
    intr = calib.color
    sim = tmp_path / "sim"
    cfg = load_config(
        SimConfig, ROOT / "configs" / "sim" / "tiny.yaml",
        [f"camera.width={intr.width}", f"camera.height={intr.height}", f"camera.fx={intr.fx}",
         f"camera.fy={intr.fy}", f"camera.cx={intr.cx}", f"camera.cy={intr.cy}",
         "output.preview_frames=0"],
    )  # fmt: skip
    simulate_dataset(cfg, 2, 9, sim)
    config = {
        "name": "own",
        "output_dir": str(tmp_path / "runs"),
        "data": {"train": str(labelled), "train_extra": [str(sim)], "val": str(labelled),
                 "augment": None},
        "model": {"arch": "fusion", "width": 0.0625, "input_scale": 1.0,
                  "init_checkpoint": str(tiny_model)},
        "optim": {"name": "adam", "lr": 1e-9, "weight_decay": 0.0},
        "train": {"epochs": 1, "batch_size": 2, "eval_batch_size": 2, "num_threads": 1,
                  "device": "cpu", "tensorboard": False},
        "eval": {"sets": [str(labelled)]},
    }  # fmt: skip
    path = tmp_path / "own.yaml"
    path.write_text(yaml.safe_dump(config))
    train = load_script(ROOT / "train" / "segmenter.py")
    assert train.main(train.get_args_parser().parse_args(["--config", str(path)])) == 0
    best = tmp_path / "runs" / "own" / "best.pt"
    start = segmenter_from_onnx(tiny_model).state_dict()
    trained = load_checkpoint(best)["model"]
    assert max(float((trained[k] - v).abs().max()) for k, v in start.items()) < 1e-6
    exported = tmp_path / "own.onnx"
    export = load_script(ROOT / "export" / "to_onnx.py")
    argv = ["segmenter", "--checkpoint", str(best), "--out", str(exported),
            "--height", str(intr.height), "--width", str(intr.width)]  # fmt: skip
    assert export.main(argv) == 0
    out = tmp_path / "seg"
    assert (
        main(["segment", str(tiny_sim_session), "--out", str(out), "--model", str(exported)]) == 0
    )
    assert len(list((out / "labels").glob("*.png"))) == len(open_session(tiny_sim_session))
