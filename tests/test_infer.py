"""``gaitnet infer`` (gaitnet.pipeline): the result folder's files agree with each other and with
an independent forward kinematics, the evaluation reads them, config keys act, and the joining
helpers give known answers."""

from __future__ import annotations

import csv
import json
import logging
import shutil
from dataclasses import replace
from pathlib import Path

import ezc3d
import numpy as np
import pytest

from gaitnet.cli import main
from gaitnet.evaluation.evaluate import evaluate_result
from gaitnet.geometry import so3_exp
from gaitnet.io import open_session
from gaitnet.motion.skeleton import builtin_skeleton, forward_kinematics
from gaitnet.pipeline.c3d_export import c3d_frame_grid
from gaitnet.pipeline.config import InferConfig, PipelineParams
from gaitnet.pipeline.foot_points import floor_in_camera
from gaitnet.pipeline.infer import _contact
from gaitnet.pipeline.pelvis_extrinsic import standing_feet, standing_frames
from gaitnet.segmentation.edge_refine import EdgeRefineParams
from gaitnet.vio.result import StanceFoot


@pytest.fixture(scope="module")
def inferred(tmp_path_factory, tiny_sim_session: Path, tiny_model: Path) -> Path:
    out = tmp_path_factory.mktemp("inf") / "out"
    args = ["infer", str(tiny_sim_session), "--out", str(out), "--segmenter", str(tiny_model)]
    assert main([*args, "--save-labels", "pipeline.subject_height_m=1.7"]) == 0
    return out


def test_files_agree_with_forward_kinematics(inferred: Path, tiny_sim_session: Path) -> None:
    data = np.load(inferred / "joints.npz")
    n = len(data["t_ns"])
    assert data["positions"].shape == (n, 9, 3) and np.all(np.isfinite(data["positions"]))
    skel = builtin_skeleton(1.7)  # pipeline.subject_height_m acts: the skeleton is this one
    aa = np.concatenate([data["poses"][:, 3:].reshape(n, 6, 3), np.zeros((n, 2, 3))], axis=1)
    fk = forward_kinematics(skel, data["poses"][:, :3], data["trans"], aa)
    np.testing.assert_allclose(data["positions"], fk, atol=1e-9)
    with open(inferred / "feet.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["t_ns"]) for r in rows] == list(data["t_ns"])
    marker = np.array([[float(r[f"marker_left_{a}"]) for a in "xyz"] for r in rows])
    # the marker is the ankle plus the pipeline's offset in the ankle frame, scaled by height
    R_ankle = so3_exp(data["poses"][:, :3])
    for j in (1, 3, 5):  # L_hip, L_knee, L_ankle local rotations
        R_ankle = R_ankle @ so3_exp(data["poses"][:, 3 * j : 3 * j + 3])
    offset = np.array(PipelineParams().marker_offset_m) * 1.7 / 1.70
    np.testing.assert_allclose(marker, fk[:, 5] + R_ankle @ offset, atol=2e-5)
    assert len(list((inferred / "labels").glob("*.png"))) == n
    for name in ("foot_left.tum", "foot_right.tum", "camera_frames.tum", "strides.csv"):
        assert (inferred / name).stat().st_size > 0
    report = (inferred / "report.html").read_text()
    assert report.count("data:image/png;base64,") == 4 and "http://" not in report
    for name in ("foot_trajectories", "top_view", "joint_angles", "gait_phases"):
        assert (inferred / f"{name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (inferred / "gait_strides.csv").read_text().startswith("side,")
    c3d = ezc3d.c3d(str(inferred / "gait.c3d"))  # the joints and feet of the files above, mm
    xyz = np.transpose(c3d["data"]["points"][:3], (2, 1, 0)) / 1000.0
    _, slots, _ = c3d_frame_grid(data["t_ns"] * 1e-9)
    np.testing.assert_allclose(xyz[slots, :7], data["positions"][:, :7], atol=1e-6)
    np.testing.assert_allclose(xyz[slots, 7], marker, atol=2e-5)
    assert c3d["parameters"]["PROCESSING"]["Height"]["value"][0] == pytest.approx(1700.0)


def test_evaluate_reads_the_result(inferred: Path, tiny_sim_session: Path, capsys) -> None:
    assert main(["evaluate", str(inferred), "--session", str(tiny_sim_session)]) == 0
    out = capsys.readouterr().out
    for key in ("mpjpe_m", "foot_nmate_m", "body_ate_m", "miou"):
        assert key in out


def test_reliability_and_dropped_feet_are_recorded(inferred: Path) -> None:
    from gaitnet.pipeline.infer import _too_few_feet
    from gaitnet.segmentation.postprocess import DROP_REASONS

    summary = json.loads((inferred / "summary.json").read_text())
    seen = summary["feet_measured_fraction"]
    assert summary["reliable"] == (min(seen.values()) >= 0.2)
    assert set(summary["feet_dropped"]) <= set(DROP_REASONS)
    assert ("RELIABLE" in (inferred / "report.html").read_text()) != summary["reliable"]
    measured = np.full((10, 2, 3), np.nan)
    measured[:3, 0] = 0.0  # left seen in 30 % of the frames
    measured[:1, 1] = 0.0  # right in 10 %
    assert _too_few_feet(measured, 0.1) == []
    assert _too_few_feet(measured, 0.0) == []
    assert _too_few_feet(measured, 0.2) == [
        "feet measured in too few frames (left 30 %, right 10 %; need 20 %)"
    ]


def test_world_frame_is_recorded_and_evaluate_warns_on_its_own(
    inferred: Path, tiny_sim_session: Path, tmp_path: Path, caplog
) -> None:
    summary = json.loads((inferred / "summary.json").read_text())
    world = summary["world_frame"]
    assert world["initialisation"] in ("apriltag", "gravity_floor") and world["note"]
    shown = "start AprilTag sheet" if world["initialisation"] == "apriltag" else "no AprilTag"
    assert shown in (inferred / "report.html").read_text()
    for init in ("apriltag", "gravity_floor"):
        copy = tmp_path / init
        shutil.copytree(inferred, copy)
        summary["world_frame"]["initialisation"] = init
        (copy / "summary.json").write_text(json.dumps(summary))
        caplog.clear()
        with caplog.at_level(logging.WARNING):
            metrics = evaluate_result(copy, tiny_sim_session).metrics
        warned = [r for r in caplog.records if "mpjpe_aligned_m" in r.getMessage()]
        assert len(warned) == (init == "gravity_floor")
        assert metrics["mpjpe_aligned_m"] > 0 and metrics["mpjpe_m"] > 0


def test_bad_arguments_are_one_line(
    tmp_path: Path, tiny_sim_session: Path, tiny_model: Path, capsys
) -> None:
    args = ["infer", str(tiny_sim_session), "--out", str(tmp_path / "o")]
    args += ["--segmenter", str(tiny_model)]
    assert main([*args, "pipeline.foot_keypoint=toe"]) == 1
    assert "foot_keypoint" in capsys.readouterr().err
    assert main([*args, "--predictor", str(tmp_path / "none.onnx")]) == 1
    assert "none.onnx" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_floor_in_camera_is_the_world_floor() -> None:
    rng = np.random.default_rng(0)
    T = np.eye(4)
    T[:3, :3] = so3_exp(rng.normal(size=3))
    T[:3, 3] = [0.3, -1.0, 0.95]
    plane = floor_in_camera(T)
    p_W = np.array([[1.0, 2.0, 0.0], [-0.5, 0.1, 0.0], [0.2, 0.2, 0.4]])
    p_C = (p_W - T[:3, 3]) @ T[:3, :3]
    np.testing.assert_allclose(plane.height(p_C), p_W[:, 2], atol=1e-12)


def test_standing_frames_and_contact() -> None:
    t = np.arange(60) / 30.0
    T = np.tile(np.eye(4), (60, 1, 1))
    T[20:, 0, 3] = (t[20:] - t[19]) * 1.0  # walks at 1 m/s from frame 20
    p = PipelineParams()
    assert standing_frames(t, T, p.standing_s, p.standing_max_speed_mps) == 20
    assert standing_frames(t, T, 0.3, p.standing_max_speed_mps) == 10  # frames at 0 … 0.3 s

    class Vio:
        stance_feet = [
            StanceFoot(0, "left", 0.1, 0.5, np.zeros(2), np.zeros(2), 3),
            StanceFoot(1, "right", 0.4, 0.9, np.zeros(2), np.zeros(2), 3),
        ]

    c = _contact(Vio(), np.array([0.0, 0.2, 0.45, 0.7, 1.0]))
    np.testing.assert_array_equal(c, [[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]])


def test_standing_feet_take_only_what_was_seen_while_standing() -> None:
    t = np.arange(60) / 30.0
    measured = np.full((60, 2, 3), np.nan)
    measured[:20, 0] = [0.1, 0.1, 0.05]  # the left foot seen while standing (20 frames)
    measured[30:, 1] = [0.9, -0.1, 0.05]  # the right one only once walking

    class Vio:
        t_s = t
        stance_feet = [  # the filter's landmarks: the right foot while standing, then a step
            StanceFoot(0, "right", 0.5, 1.5, np.array([0.0, -0.1]), np.zeros(2), 3),
            StanceFoot(1, "right", 1.6, 1.9, np.array([0.8, -0.1]), np.zeros(2), 3),
        ]

    feet = standing_feet(measured, Vio(), 0.04, 20)  # type: ignore[arg-type]
    np.testing.assert_allclose(feet, [[0.1, 0.1, 0.05], [0.0, -0.1, 0.04]])
    Vio.stance_feet = Vio.stance_feet[1:]  # only the step: first seen after standing
    feet = standing_feet(measured, Vio(), 0.04, 20)  # type: ignore[arg-type]
    assert np.all(np.isnan(feet[1])) and np.all(np.isfinite(feet[0]))


def test_default_yaml_is_the_built_in_config_and_unused_keys_are_refused() -> None:
    from gaitnet.config import load_config
    from gaitnet.errors import ConfigError

    root = Path(__file__).parents[1]
    assert load_config(InferConfig, root / "configs" / "infer" / "default.yaml") == InferConfig()
    for key in ("hha.floor.seed=3", "feet.use_floor=false", "hha.no_imu_pitch_deg=50"):
        with pytest.raises(ConfigError, match=key.split("=")[0].rsplit(".", 1)[0]):
            load_config(InferConfig, None, [key])


#: One filter run without the smoother (the workers only concern the segmentation beside it).
FIRST_RUN_ONLY = ["vio.smoother.enabled=false", "pipeline.segmented_stances=false"]


def test_workers_act_and_do_not_change_the_result(
    tiny_sim_session: Path, tiny_model: Path, monkeypatch
) -> None:
    """``pipeline.workers`` sets the threads that segment frames; the measured feet are the
    same for 1 and 3 threads (each frame is measured on its own)."""
    import gaitnet.pipeline.infer as infer
    from gaitnet.config import load_config
    from gaitnet.segmentation.onnx_runtime import OnnxSegmenter

    seen = []
    real = infer.ThreadPoolExecutor

    def spy(max_workers: int):
        seen.append(max_workers)
        return real(max_workers=max_workers)

    monkeypatch.setattr(infer, "ThreadPoolExecutor", spy)
    session = open_session(tiny_sim_session)
    seg = OnnxSegmenter(tiny_model)
    one = infer.observe(
        session,
        load_config(InferConfig, None, [*FIRST_RUN_ONLY, "pipeline.workers=1"]),
        seg,
    )
    three = infer.observe(
        session,
        load_config(InferConfig, None, [*FIRST_RUN_ONLY, "pipeline.workers=3"]),
        seg,
    )
    assert seen == [1, 3]
    np.testing.assert_array_equal(one.foot_W, three.foot_W)
    np.testing.assert_array_equal(one.t_ns, three.t_ns)


def test_models_keys_reach_the_segmenter(
    tmp_path: Path, tiny_sim_session: Path, tiny_model: Path, monkeypatch, capsys
) -> None:
    """``models.threads``, ``models.segmenter_flip_average`` and the ``edge_refine`` keys are
    the segmenter's settings in ``gaitnet infer`` (their effects: test_segmentation_onnx.py,
    test_edge_refine.py)."""
    import gaitnet.segmentation.onnx_runtime as onnx_runtime
    from gaitnet.errors import InputError

    made = []

    class Spy(onnx_runtime.OnnxSegmenter):
        def __init__(self, *args, **kwargs) -> None:
            super().__init__(*args, **kwargs)
            made.append(self)
            raise InputError("stop here")

    monkeypatch.setattr(onnx_runtime, "OnnxSegmenter", Spy)
    args = ["infer", str(tiny_sim_session), "--out", str(tmp_path / "o")]
    args += ["--segmenter", str(tiny_model)]
    assert main([*args, "models.threads=2", "models.segmenter_flip_average=true"]) == 1
    assert "stop here" in capsys.readouterr().err
    assert made[-1].flip_average
    assert made[-1].session.get_session_options().intra_op_num_threads == 2
    assert made[-1].edge_refine == EdgeRefineParams()
    assert main(args) == 1
    assert not made[-1].flip_average
    keys = ["edge_refine.radius_px=3", "edge_refine.eps=0.01", "edge_refine.region=frame"]
    assert main([*args, *keys]) == 1
    assert made[-1].edge_refine == EdgeRefineParams(3, 0.01, "frame")
    capsys.readouterr()
    assert main([*args, "edge_refine.region=legs"]) == 1
    assert "key 'edge_refine.region' must be one of 'feet', 'frame'" in capsys.readouterr().err
    assert main([*args, "edge_refine.radius_px=-1"]) == 1
    assert "edge_refine: radius_px must be an integer within [0, 64]" in capsys.readouterr().err


def test_feet_measured_on_the_filter_pose_end_on_the_smoothed_one(
    tiny_sim_session: Path, tiny_model: Path, monkeypatch
) -> None:
    """The frames are segmented with the filter's pose while it runs; a point the segmenter
    finds at a fixed place in the camera frame ends at the smoothed camera pose's world point."""
    import gaitnet.pipeline.infer as infer
    from gaitnet.config import load_config
    from gaitnet.pipeline.foot_points import FrameFeet
    from gaitnet.segmentation.onnx_runtime import OnnxSegmenter

    p_C = np.array([[0.1, 0.5, 1.0], [-0.1, 0.45, 0.9]])
    poses_seen: list[np.ndarray] = []

    def fixed_feet(frame, K, T_WfromC, *args, **kwargs) -> FrameFeet:
        poses_seen.append(np.array(T_WfromC))
        foot_W = p_C @ T_WfromC[:3, :3].T + T_WfromC[:3, 3]
        if frame.index % 3 == 0:
            foot_W[1] = np.nan  # a foot not seen stays not seen
        return FrameFeet(foot_W, np.zeros(frame.depth_m.shape, np.uint8), 2)

    real_run_vio = infer.run_vio

    def smoothed_elsewhere(*args, **kwargs):
        """The filter's result with a smoothed trajectory 3 cm and 2° away from the filter's."""
        result = real_run_vio(*args, **kwargs)
        shift = np.eye(4)
        shift[:3, :3], shift[:3, 3] = so3_exp(np.radians([0.0, 0.0, 2.0])), [0.03, -0.02, 0.01]
        return replace(result, T_WfromC_smoothed=shift @ result.T_WfromC_filter)

    monkeypatch.setattr(infer, "measure_feet", fixed_feet)
    monkeypatch.setattr(infer, "run_vio", smoothed_elsewhere)
    cfg = load_config(InferConfig, None, ["pipeline.workers=2"])
    obs = infer.observe(open_session(tiny_sim_session), cfg, OnnxSegmenter(tiny_model))
    vio = obs.vio
    np.testing.assert_allclose(np.array(poses_seen), vio.T_WfromC_filter, atol=1e-12)
    expected = np.einsum("kij,sj->ksi", vio.T_WfromC_smoothed[:, :3, :3], p_C)
    expected += vio.T_WfromC_smoothed[:, None, :3, 3]
    unseen = vio.session_index % 3 == 0
    np.testing.assert_allclose(obs.foot_W[~unseen], expected[~unseen], atol=1e-9)
    np.testing.assert_allclose(obs.foot_W[unseen, 0], expected[unseen, 0], atol=1e-9)
    assert np.isnan(obs.foot_W[unseen, 1]).all()
    assert list(obs.t_ns) == list(open_session(tiny_sim_session).frame_times_ns[vio.session_index])
    assert obs.timings_s["segmenter_cpu"] >= 0 and obs.timings_s["filter"] > 0


def test_feet_unseen_while_standing_are_placed_behind_the_camera(
    tiny_sim_session: Path, monkeypatch, caplog
) -> None:
    """Neither the segmenter nor the filter saw a foot while standing: the standing feet lie
    ``pipeline.standing_feet_behind_camera_m`` behind the camera, so the standing pelvis moves
    with the key along the camera's heading, and a warning names the key."""
    import gaitnet.pipeline.infer as infer
    from gaitnet.config import load_config
    from gaitnet.motion.onnx_runtime import OnnxPredictor
    from gaitnet.pipeline.foot_points import FrameFeet

    def unseen(frame, *args, **kwargs) -> FrameFeet:
        return FrameFeet(np.full((2, 3), np.nan), np.zeros(frame.depth_m.shape, np.uint8), 0)

    monkeypatch.setattr(infer, "measure_feet", unseen)
    cfg = load_config(InferConfig, None, ["vio.smoother.enabled=false"])

    class NoSegmenter:
        arch, input_scale, path = "rgb", 0.5, Path("none")

    obs = infer.observe(open_session(tiny_sim_session), cfg, segmenter=NoSegmenter())  # type: ignore[arg-type]
    obs = replace(obs, vio=replace(obs.vio, stance_feet=[]))
    predictor = OnnxPredictor(infer.default_predictor_path())
    pelvis = {}
    for behind in (0.1, 0.3):
        keys = ["vio.smoother.enabled=false", f"pipeline.standing_feet_behind_camera_m={behind}"]
        with caplog.at_level("WARNING", logger="gaitnet.pipeline.infer"):
            result = infer.reconstruct(obs, load_config(InferConfig, None, keys), predictor)
        assert f"{behind:.2f} m behind the camera" in caplog.text
        assert np.all(np.isfinite(result.joints_W))
        pelvis[behind] = result.extrinsic.T_WfromP[:3, 3]
    heading = obs.vio.T_WfromC[0][:2, 2] / np.linalg.norm(obs.vio.T_WfromC[0][:2, 2])
    shift = pelvis[0.3] - pelvis[0.1]
    np.testing.assert_allclose(shift[:2], -0.2 * heading, atol=1e-9)
    assert abs(shift[2]) < 1e-9


def test_frames_after_the_first_are_sided_with_their_midline(
    tiny_sim_session: Path, monkeypatch
) -> None:
    """The first ``feet.midline_frames`` frames are segmented with the configured parameters;
    every later one with ``lateral_offset_m`` set to the median of their pair midpoints and
    ``forward_in_camera`` to the normalised median of their horizontal optical axes (with the
    filter's gravity), whatever the number of segmentation threads."""
    import gaitnet.pipeline.infer as infer
    from gaitnet.config import load_config
    from gaitnet.pipeline.foot_points import FrameFeet
    from gaitnet.segmentation.body_axes import horizontal_forward

    class NoSegmenter:
        arch, input_scale, path = "rgb", 0.5, Path("none")

    for workers in (1, 2):
        offsets: dict[int, float] = {}
        forwards: dict[int, object] = {}
        ups: dict[int, np.ndarray] = {}

        def spy(
            frame, K, T_WfromC, segmenter, keypoint, hha, params, *args,
            seen=offsets, forwards=forwards, ups=ups,
        ):  # fmt: skip
            seen[frame.index] = params.lateral_offset_m
            forwards[frame.index] = params.forward_in_camera
            ups[frame.index] = T_WfromC[:3, :3].T @ [0.0, 0.0, 1.0]
            labels = np.zeros(frame.depth_m.shape, np.uint8)
            return FrameFeet(np.full((2, 3), np.nan), labels, 2, 0.01 * frame.index**2)

        monkeypatch.setattr(infer, "measure_feet", spy)
        keys = [
            "vio.smoother.enabled=false",
            "feet.midline_frames=8",
            "feet.lateral_offset_m=0.3",
            f"pipeline.workers={workers}",
        ]
        cfg = load_config(InferConfig, None, keys)
        obs = infer.observe(open_session(tiny_sim_session), cfg, segmenter=NoSegmenter())  # type: ignore[arg-type]
        indices = sorted(offsets)
        assert len(indices) == len(obs.t_ns) > 8
        median = float(np.median([0.01 * i**2 for i in indices[:8]]))  # the later ones ignored
        assert [offsets[i] for i in indices[:8]] == [0.3] * 8
        np.testing.assert_allclose([offsets[i] for i in indices[8:]], median)
        assert [forwards[i] for i in indices[:8]] == [None] * 8
        forward = np.median([horizontal_forward(ups[i]) for i in indices[:8]], axis=0)
        forward /= np.linalg.norm(forward)
        np.testing.assert_allclose(
            [forwards[i] for i in indices[8:]], [forward] * (len(indices) - 8)
        )


def test_a_camera_too_high_for_a_waist_warns_and_the_height_key_silences_it(
    tiny_sim_session: Path, caplog
) -> None:
    """The body height from the standing camera's height is clipped to HEIGHT_RANGE_M; a
    camera that stands too high for a waist (worn on the chest) gives a warning naming
    ``pipeline.subject_height_m``, and given that key the skeleton is the given height."""
    import gaitnet.pipeline.infer as infer
    from gaitnet.config import load_config
    from gaitnet.motion.onnx_runtime import OnnxPredictor
    from gaitnet.pipeline.foot_points import FrameFeet

    class NoSegmenter:
        arch, input_scale, path = "rgb", 0.5, Path("none")

    def unseen(frame, *args, **kwargs) -> FrameFeet:
        return FrameFeet(np.full((2, 3), np.nan), np.zeros(frame.depth_m.shape, np.uint8), 0)

    cfg = load_config(InferConfig, None, ["vio.smoother.enabled=false"])
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(infer, "measure_feet", unseen)
        obs = infer.observe(open_session(tiny_sim_session), cfg, segmenter=NoSegmenter())  # type: ignore[arg-type]
    predictor = OnnxPredictor(infer.default_predictor_path())
    assert obs.vio.T_WfromC_smoothed is None  # the smoother is off: the filter's poses
    T = obs.vio.T_WfromC_filter.copy()
    T[:, 2, 3] += 0.6  # the camera 0.6 m higher: a waist at 1.6 m or more
    high = replace(obs, vio=replace(obs.vio, T_WfromC_filter=T))
    for keys, warned, height in (
        ([], True, infer.HEIGHT_RANGE_M[1]),
        (["pipeline.subject_height_m=1.75"], False, 1.75),
    ):
        caplog.clear()
        with caplog.at_level("WARNING", logger="gaitnet.pipeline.infer"):
            result = infer.reconstruct(high, load_config(InferConfig, None, keys), predictor)
        assert ("pipeline.subject_height_m" in caplog.text) == warned
        assert result.subject_height_m == pytest.approx(height)
    caplog.clear()
    with caplog.at_level("WARNING", logger="gaitnet.pipeline.infer"):
        infer.reconstruct(obs, cfg, predictor)
    assert "pipeline.subject_height_m" not in caplog.text


@pytest.mark.parametrize("segmented", [True, False])
def test_segmented_stances_run_the_filter_again_with_the_foot_pixels(
    tiny_sim_session: Path, tiny_model: Path, monkeypatch, segmented: bool
) -> None:
    """``pipeline.segmented_stances``: the filter runs a second time, handed each frame's foot
    pixels by its time stamp, and its result is kept; the feet measured on the first run's
    filter poses end on the second's (smoothed) poses. False: one run, no foot pixels."""
    import gaitnet.pipeline.infer as infer
    from gaitnet.config import load_config
    from gaitnet.pipeline.foot_points import FrameFeet
    from gaitnet.segmentation.onnx_runtime import OnnxSegmenter
    from gaitnet.vio.feet_segmented import FootMask

    p_C = np.array([[0.1, 0.5, 1.0], [-0.1, 0.45, 0.9]])
    mask = FootMask((3, 4), np.ones((2, 2), bool))

    def fixed_feet(frame, K, T_WfromC, *args, **kwargs) -> FrameFeet:
        foot_W = p_C @ T_WfromC[:3, :3].T + T_WfromC[:3, 3]
        return FrameFeet(foot_W, np.zeros(frame.depth_m.shape, np.uint8), 2, None, mask)

    real_run_vio = infer.run_vio
    calls: list[dict] = []

    def recorded(*args, **kwargs):
        calls.append(kwargs)
        result = real_run_vio(*args, **kwargs)
        if kwargs.get("foot_masks") is None:
            return result
        shift = np.eye(4)  # the second run's poses: 3 cm and 2° away from the first's
        shift[:3, :3], shift[:3, 3] = so3_exp(np.radians([0.0, 0.0, 2.0])), [0.03, -0.02, 0.01]
        return replace(result, T_WfromC_smoothed=shift @ result.T_WfromC_filter)

    monkeypatch.setattr(infer, "measure_feet", fixed_feet)
    monkeypatch.setattr(infer, "run_vio", recorded)
    keys = [f"pipeline.segmented_stances={str(segmented).lower()}"]
    cfg = load_config(InferConfig, None, [*keys, "pipeline.segmented_stances_always=true"])
    obs = infer.observe(open_session(tiny_sim_session), cfg, OnnxSegmenter(tiny_model))
    assert len(calls) == (2 if segmented else 1)
    assert calls[0].get("foot_masks") is None
    assert ("filter_segmented" in obs.timings_s) == segmented
    expected = np.einsum("kij,sj->ksi", obs.vio.T_WfromC[:, :3, :3], p_C)
    expected += obs.vio.T_WfromC[:, None, :3, 3]
    np.testing.assert_allclose(obs.foot_W, expected, atol=1e-9)
    moved = np.linalg.norm(obs.vio.T_WfromC[:, :3, 3] - obs.vio.T_WfromC_filter[:, :3, 3], axis=1)
    assert (moved > 0.02).all() == segmented  # the second run's (shifted) poses were kept
    if segmented:
        masks = calls[1]["foot_masks"]
        assert sorted(masks) == sorted(obs.t_ns.tolist())
        assert all(m is mask for m in masks.values())


def _masked_feet(frame, K, T_WfromC, *args, **kwargs):
    """A ``measure_feet`` stand-in: no foot point, a 2 × 2 patch of foot pixels."""
    from gaitnet.pipeline.foot_points import FrameFeet
    from gaitnet.vio.feet_segmented import FootMask

    mask = FootMask((3, 4), np.ones((2, 2), bool))
    return FrameFeet(np.full((2, 3), np.nan), np.zeros(frame.depth_m.shape, np.uint8), 0,
                     None, mask)  # fmt: skip


@pytest.mark.parametrize(("missed", "always", "runs"), [(True, False, 2), (False, False, 1),
                                                       (False, True, 2)])  # fmt: skip
def test_the_second_run_only_where_a_stance_was_missed(
    tiny_sim_session: Path, tiny_model: Path, monkeypatch, missed: bool, always: bool, runs: int
) -> None:
    """By default the filter runs again with the foot pixels only where its first run's
    landmarks show a missed stance (:func:`gaitnet.pipeline.stance_gaps.stance_missed`, given
    the first run's landmarks); ``pipeline.segmented_stances_always`` runs it everywhere."""
    import gaitnet.pipeline.infer as infer
    from gaitnet.config import load_config
    from gaitnet.segmentation.onnx_runtime import OnnxSegmenter

    real_run_vio = infer.run_vio
    calls: list = []
    judged: list = []

    def recorded(*args, **kwargs):
        calls.append(real_run_vio(*args, **kwargs))
        return calls[-1]

    def judge(stance_feet):
        judged.append(stance_feet)
        return missed

    monkeypatch.setattr(infer, "measure_feet", _masked_feet)
    monkeypatch.setattr(infer, "run_vio", recorded)
    monkeypatch.setattr(infer, "stance_missed", judge)
    keys = [f"pipeline.segmented_stances_always={str(always).lower()}"]
    cfg = load_config(InferConfig, None, keys)
    obs = infer.observe(open_session(tiny_sim_session), cfg, OnnxSegmenter(tiny_model))
    assert len(calls) == runs
    assert obs.vio is calls[-1]
    assert ("filter_segmented" in obs.timings_s) == (runs == 2)
    if not always:
        assert judged == [calls[0].stance_feet]


@pytest.mark.parametrize("hidden", [True, False])
def test_hidden_stances_key_lays_them_on_the_final_result(
    tiny_sim_session: Path, tiny_model: Path, monkeypatch, hidden: bool
) -> None:
    """``pipeline.hidden_stances`` hands the filter's final result, with
    ``pipeline.step_dip_m`` and the stance tracker's line window, to
    :func:`gaitnet.pipeline.hidden_stances.with_hidden_stances`, whose result is kept;
    false: the filter's landmarks only."""
    import gaitnet.pipeline.infer as infer
    from gaitnet.config import load_config
    from gaitnet.segmentation.onnx_runtime import OnnxSegmenter

    calls: list = []

    def laid(vio, min_dip_m, line_window_s, limits):
        calls.append((vio, min_dip_m, line_window_s, limits))
        return replace(vio, initialisation_note="with hidden stances")

    monkeypatch.setattr(infer, "measure_feet", _masked_feet)
    monkeypatch.setattr(infer, "with_hidden_stances", laid)
    keys = [f"pipeline.hidden_stances={str(hidden).lower()}", "pipeline.step_dip_m=0.02",
            "vio.stance.line_window_s=0.4", "pipeline.segmented_stances=false"]  # fmt: skip
    cfg = load_config(InferConfig, None, keys)
    obs = infer.observe(open_session(tiny_sim_session), cfg, OnnxSegmenter(tiny_model))
    assert len(calls) == int(hidden)
    assert (obs.vio.initialisation_note == "with hidden stances") == hidden
    if hidden:
        assert calls[0][1:3] == (0.02, 0.4)


def test_a_failed_run_with_the_segmented_feet_keeps_the_first(
    tiny_sim_session: Path, tiny_model: Path, monkeypatch, caplog
) -> None:
    """A second run of the filter that diverges (or refuses the session) leaves the first
    run's result, with a warning saying so."""
    import gaitnet.pipeline.infer as infer
    from gaitnet.config import load_config
    from gaitnet.segmentation.onnx_runtime import OnnxSegmenter
    from gaitnet.vio.errors import FilterDivergedError

    real_run_vio = infer.run_vio
    first: list = []

    def diverging(*args, **kwargs):
        if kwargs.get("foot_masks") is not None:
            raise FilterDivergedError("position covariance exploded at frame 3")
        first.append(real_run_vio(*args, **kwargs))
        return first[-1]

    monkeypatch.setattr(infer, "measure_feet", _masked_feet)
    monkeypatch.setattr(infer, "run_vio", diverging)
    cfg = load_config(InferConfig, None, ["pipeline.segmented_stances_always=true"])
    with caplog.at_level(logging.WARNING, logger="gaitnet.pipeline.infer"):
        obs = infer.observe(open_session(tiny_sim_session), cfg, OnnxSegmenter(tiny_model))
    assert obs.vio is first[0]
    assert "segmented feet failed (position covariance exploded" in caplog.text
