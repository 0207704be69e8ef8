"""``gaitnet segment`` (gaitnet.segmentation.segment_session): every frame's label map, the foot
keypoints, the contact sheet and summary; compared with an independent per-frame computation;
gravity from the accelerometer against the simulator's truth; one-line errors."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from oneline import assert_one_line_exit
from sessionfactory import make_tiny_session

from gaitnet.cli import main
from gaitnet.io import open_session
from gaitnet.io.trajectory import read_tum
from gaitnet.segmentation.edge_refine import EdgeRefineParams, argmax_classes, refine_labels
from gaitnet.segmentation.hha import HhaParams, find_floor, hha_encode
from gaitnet.segmentation.onnx_runtime import (
    OnnxSegmenter,
    network_input,
)
from gaitnet.segmentation.postprocess import DROP_REASONS, foot_keypoints, kept_feet_labels
from gaitnet.segmentation.segment_session import KEYPOINT_COLUMNS, accelerometer_gravity_C

DEFAULT_REFINE = EdgeRefineParams()  # gaitnet segment's


def _middle_frame_by_hand(
    session,
    model_path: Path,
    flip_average: bool = False,
    refine: EdgeRefineParams | None = DEFAULT_REFINE,
):
    """The session's middle frame and, computed step by step as ``gaitnet segment`` does, the
    network's labels for it (with ``flip_average``: the arg-max of the mean of the logits of
    the frame and, mirrored back, of the mirrored frame; refined by ``refine`` unless None),
    its gravity and its floor plane."""
    K = session.calibration.color.K
    frame = session.frame(len(session) // 2)
    gravity = accelerometer_gravity_C(session.imu, session.calibration.T_CfromI, frame.t_ns, 1.0)
    plane = find_floor(frame.depth_m, K, -gravity, HhaParams())
    hha = hha_encode(frame.depth_m, K, gravity, HhaParams(), plane=plane)
    x = network_input("fusion", frame.rgb, hha)
    net = OnnxSegmenter(model_path)
    logits = net(x)
    if flip_average:
        logits = (logits + net(np.ascontiguousarray(x[..., ::-1]))[..., ::-1]) / 2
    labels = argmax_classes(logits)[0]
    if refine is not None:
        labels = refine_labels(logits[0], frame.rgb, labels, refine)
    return frame, labels, gravity, plane


def test_segment_matches_a_per_frame_computation(
    tmp_path: Path, tiny_sim_session: Path, tiny_model: Path
) -> None:
    out = tmp_path / "seg"
    status = main(["segment", str(tiny_sim_session), "--out", str(out), "--model", str(tiny_model)])
    assert status == 0
    session = open_session(tiny_sim_session)
    files = sorted(int(p.stem) for p in (out / "labels").glob("*.png"))
    assert files == sorted(int(t) for t in session.frame_times_ns)
    frame, raw, gravity, plane = _middle_frame_by_hand(session, tiny_model)
    K = session.calibration.color.K
    feet = foot_keypoints(raw, frame.depth_m, K, gravity_C=gravity, plane=plane)
    written = cv2.imread(str(out / "labels" / f"{frame.t_ns}.png"), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(written, kept_feet_labels(raw, feet))
    assert (written != raw).any()  # the random model's foot labels on the floor are dropped
    with open(out / "keypoints.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert rows and tuple(rows[0]) == KEYPOINT_COLUMNS
    mine = [r for r in rows if int(r["t_ns"]) == frame.t_ns]
    assert len(mine) == 3 * len(feet)
    for foot in feet:
        for name, (u, v) in foot.keypoints_px.items():
            row = next(r for r in mine if r["keypoint"] == name and float(r["u"]) == round(u, 2))
            assert row["side"] == foot.side
            assert float(row["v"]) == pytest.approx(v, abs=0.01)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["frames"] == len(session)
    assert summary["arch"] == "fusion"
    assert sum(summary["label_fractions"].values()) == pytest.approx(1.0)
    assert set(summary["feet_dropped"]) <= set(DROP_REASONS)
    assert (out / "contact_sheet.png").stat().st_size > 0
    # the evaluation reads these label maps against the session's ground truth
    assert main(["evaluate", str(out), "--session", str(tiny_sim_session)]) == 0


def test_raw_labels_are_the_networks_own(
    tmp_path: Path, tiny_sim_session: Path, tiny_model: Path
) -> None:
    args = ["segment", str(tiny_sim_session), "--model", str(tiny_model), "--raw-labels"]
    assert main([*args, "--out", str(tmp_path / "seg"), "--refine-radius", "0"]) == 0
    session = open_session(tiny_sim_session)
    frame, raw, _, _ = _middle_frame_by_hand(session, tiny_model, refine=None)
    path = f"labels/{frame.t_ns}.png"
    written = cv2.imread(str(tmp_path / "seg" / path), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(written, raw)
    # by default the arg-max is refined (feet region), and the region and radius act
    maps = [raw]
    for extra, refine in (
        ([], EdgeRefineParams()),
        (["--refine-region", "frame"], EdgeRefineParams(region="frame")),
        (["--refine-radius", "2", "--refine-eps", "0.01"], EdgeRefineParams(2, 0.01)),
    ):
        out = tmp_path / f"seg{len(extra)}"
        assert main([*args, "--out", str(out), *extra]) == 0
        _, refined, _, _ = _middle_frame_by_hand(session, tiny_model, refine=refine)
        written = cv2.imread(str(out / path), cv2.IMREAD_UNCHANGED)
        np.testing.assert_array_equal(written, refined)
        assert all((written != other).any() for other in maps)
        maps.append(written)


def test_flip_average_labels_are_the_mirror_averaged_networks(
    tmp_path: Path, tiny_sim_session: Path, tiny_model: Path
) -> None:
    out = tmp_path / "seg"
    args = ["segment", str(tiny_sim_session), "--out", str(out), "--model", str(tiny_model)]
    assert main([*args, "--raw-labels", "--flip-average"]) == 0
    session = open_session(tiny_sim_session)
    frame, averaged, _, _ = _middle_frame_by_hand(session, tiny_model, flip_average=True)
    written = cv2.imread(str(out / "labels" / f"{frame.t_ns}.png"), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(written, averaged)
    _, plain, _, _ = _middle_frame_by_hand(session, tiny_model)
    assert (written != plain).any()  # the option acts


def test_accelerometer_gravity_follows_the_true_attitude(tiny_sim_session: Path) -> None:
    """Within a few degrees of the true gravity (the walking accelerations over 1 s)."""
    session = open_session(tiny_sim_session)
    t, T = read_tum(tiny_sim_session / "groundtruth" / "camera_frames.tum")
    errors = []
    for k in range(0, len(t), 5):
        t_ns = int(round(t[k] * 1e9))
        g = accelerometer_gravity_C(session.imu, session.calibration.T_CfromI, t_ns, 1.0)
        true = T[k, :3, :3].T @ np.array([0.0, 0.0, -1.0])
        errors.append(np.degrees(np.arccos(np.clip(g @ true, -1, 1))))
    assert np.median(errors) < 5.0
    far = int(session.imu.t_ns[-1]) + 10**10
    assert accelerometer_gravity_C(session.imu, session.calibration.T_CfromI, far, 1.0) is None


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--model", "{tmp}/missing.onnx"], "missing.onnx"),
        (["--threads", "-1"], "threads"),
        (["--threads", "x"], "expected an integer"),
        (["--refine-radius", "-1"], "--refine-radius"),
        (["--refine-eps", "0"], "eps must be"),
        (["--refine-region", "legs"], "invalid choice"),
    ],
)
def test_segment_errors_are_one_line(
    tmp_path: Path, tiny_sim_session: Path, tiny_model: Path, capsys, extra, message
) -> None:
    args = ["segment", str(tiny_sim_session), "--out", str(tmp_path / "o")]
    args += [a.replace("{tmp}", str(tmp_path)) for a in extra]
    if "--model" not in extra:
        args += ["--model", str(tiny_model)]
    assert main(args) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and message in err
    assert not (tmp_path / "o").exists()


def test_segment_refuses_depth_not_aligned_to_colour(tmp_path: Path, capsys) -> None:
    """``depth_aligned_to_color: false``: refused as gaitnet vio refuses it (the same check),
    naming session.yaml; nothing is written."""
    root = make_tiny_session(tmp_path / "session")
    yaml_path = root / "session.yaml"
    text = yaml_path.read_text()
    yaml_path.write_text(
        text.replace("depth_aligned_to_color: true", "depth_aligned_to_color: false")
    )
    for command, who in (("segment", "the segmenter"), ("vio", "the filter")):
        rc = main([command, str(root), "--out", str(tmp_path / "o")])
        assert_one_line_exit(capsys, rc, f"{yaml_path}: depth_aligned_to_color is false", who)
        assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("arch", ["rgb", "hha", "fusion"])
def test_network_input_is_the_channel_planes_over_255(arch: str) -> None:
    rng = np.random.default_rng(2)
    rgb, hha = (rng.integers(0, 256, (5, 7, 3), dtype=np.uint8) for _ in range(2))
    parts = {"rgb": [rgb], "hha": [hha], "fusion": [rgb, hha]}[arch]
    expected = np.concatenate(parts, axis=2).transpose(2, 0, 1)[None] / np.float32(255.0)
    x = network_input(arch, rgb, hha)
    assert x.dtype == np.float32 and x.flags.c_contiguous
    np.testing.assert_allclose(x, expected, rtol=1e-6)


def test_frames_after_the_first_are_sided_with_their_midline(
    tmp_path: Path, tiny_sim_session: Path, tiny_model: Path, monkeypatch
) -> None:
    """``gaitnet segment`` sides the frames after the first ``midline_frames`` with the median
    midpoint of the feet pairs in those (gaitnet.segmentation.midline)."""
    import gaitnet.segmentation.segment_session as seg
    from gaitnet.segmentation.postprocess import FootDetection, FootKeypointParams

    used: list[float] = []

    def spy(labels, depth_m, K, params, **kwargs) -> list[FootDetection]:
        k = len(used)
        used.append(params.lateral_offset_m)
        empty = np.zeros(labels.shape, bool)
        px = {name: (1.0, 1.0) for name in ("top", "mid", "bottom")}
        pts = dict.fromkeys(px)
        return [  # a pair sided apart, its midpoint 0.01 k on the camera's scale
            FootDetection("left", px, pts, 10, 0.01 * k + 0.1 - 0.2, empty),  # type: ignore[arg-type]
            FootDetection("right", px, pts, 9, 0.01 * k - 0.1 - 0.2, empty),  # type: ignore[arg-type]
        ]

    monkeypatch.setattr(seg, "foot_keypoints", spy)
    params = FootKeypointParams(midline_frames=6, lateral_offset_m=0.2)
    session = open_session(tiny_sim_session)
    seg.segment_session(
        session, OnnxSegmenter(tiny_model), tmp_path / "out", keypoint_params=params
    )
    assert len(used) == len(session) > 6
    assert used[:6] == [0.2] * 6
    np.testing.assert_allclose(used[6:], np.median(0.01 * np.arange(6)))
