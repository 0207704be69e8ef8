"""The scene check before the filter (gaitnet/vio/scene_check.py): what a waist-worn camera sees,
IMU coverage, gravity against the floor the depth shows; refusal, --force and the reliable flag."""

from __future__ import annotations

import json
import re
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gaitnet.cli import main
from gaitnet.config import load_config
from gaitnet.io import open_session
from gaitnet.io.bag_index import RosBag
from gaitnet.io.imu_csv import imu_csv_text
from gaitnet.io.ros_image import decode_color, decode_depth
from gaitnet.io.session_folder import SessionWriter
from gaitnet.io.types import CameraIntrinsics, ImuSamples, SessionCalibration
from gaitnet.vio.config import VioConfig
from gaitnet.vio.errors import SceneError
from gaitnet.vio.initialise import standing_up
from gaitnet.vio.scene_check import check_scene, imu_coverage, screen_session

BAG = Path(__file__).parent / "data" / "single_depth_color_640x480.bag"


def test_imu_coverage_known_answers() -> None:
    imu = np.array([0, 10, 20, 30, 200, 210], dtype=np.int64) * 1_000_000  # a 170 ms gap
    frames = np.array([-5, 0, 15, 30, 100, 205, 211], dtype=np.int64) * 1_000_000
    got = imu_coverage(imu, frames, max_gap_s=0.1)
    assert got.tolist() == [False, True, True, True, False, True, False]
    assert imu_coverage(imu, frames, max_gap_s=0.2)[4]  # the gap is allowed now
    assert not imu_coverage(imu[:1], frames, 0.1).any()  # one sample covers nothing


def _scene(session: Path, cfg: VioConfig, **changes) -> list[str]:
    source = open_session(session)
    first = [source.frame(i) for i in range(3)]
    imu = changes.pop("imu", source.imu)
    up = changes.pop("up", standing_up(source.imu, int(first[0].t_ns), cfg.init))
    first = changes.pop("frames", first)
    return check_scene(
        first, imu, source.frame_times_ns, source.calibration, up, cfg.scene, cfg.floor
    )


def test_a_simulated_walk_passes_and_each_fault_is_named(tiny_sim_session: Path) -> None:
    cfg = VioConfig()
    assert _scene(tiny_sim_session, cfg) == []
    imu = open_session(tiny_sim_session).imu
    up = standing_up(imu, int(open_session(tiny_sim_session).frame_times_ns[0]), cfg.init)
    pitch, upside_down = _scene(tiny_sim_session, cfg, up=-up)
    assert pitch.startswith("the camera looks -7")  # looking up: the pitch is named too
    assert float(re.search(r"is (\d+)° from", upside_down).group(1)) > 170
    assert "T_CfromI" in upside_down
    turned = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]) @ up
    assert any("T_CfromI" in p for p in _scene(tiny_sim_session, cfg, up=turned))
    late = ImuSamples(imu.t_ns + 100_000_000_000, imu.accel, imu.gyro)
    assert _scene(tiny_sim_session, cfg, imu=late)[0].startswith("the IMU covers 0 % of the")
    half = len(imu) // 2
    first_half = ImuSamples(imu.t_ns[:half], imu.accel[:half], imu.gyro[:half])
    (problem,) = _scene(tiny_sim_session, cfg, imu=first_half)
    assert problem.startswith("the IMU covers 4") or problem.startswith("the IMU covers 5")
    frames = [open_session(tiny_sim_session).frame(i) for i in range(3)]
    empty = [replace(f, depth_m=np.zeros_like(f.depth_m)) for f in frames]
    assert _scene(tiny_sim_session, cfg, frames=empty) == [
        "depth: 0 % of the pixels have depth (need 30 %)"
    ]


@pytest.mark.parametrize(
    ("override", "needle"),
    [
        ("scene.min_height_m=1.4", "m below the camera"),
        ("scene.max_height_m=0.6", "m below the camera"),
        ("scene.min_floor_fraction=0.999", "% of the depth points (need 100 %)"),
        ("scene.below_floor_m=-0.0", "below the floor plane"),
        ("scene.min_valid_depth=1.0", "pixels have depth"),
        ("scene.min_imu_coverage=1.0", None),  # every frame is covered: still passes
        ("scene.max_pitch_deg=60", "below the horizon"),  # the simulated mount: 70°
        ("scene.min_pitch_deg=80", "below the horizon"),
        ("scene.min_leg_fraction=0.5", "no legs under the camera"),
        ("scene.leg_reach_m=0.01", "no legs under the camera"),
        ("scene.leg_min_height_m=0.95", "no legs under the camera"),
    ],
)
def test_every_threshold_acts(tiny_sim_session: Path, override: str, needle: str | None) -> None:
    cfg = load_config(
        VioConfig,
        None,
        [override] + (["scene.max_below_floor_fraction=0"] if "below_floor_m" in override else []),
    )
    problems = _scene(tiny_sim_session, cfg)
    if needle is None:
        assert problems == []
    else:
        assert any(needle in p for p in problems), problems


def test_imu_gap_and_coverage_keys_act(tiny_sim_session: Path) -> None:
    imu = open_session(tiny_sim_session).imu
    keep = np.ones(len(imu), dtype=bool)
    n = len(imu)
    keep[n // 10 : n // 10 + n // 5] = False  # a fifth of the stream missing
    holed = ImuSamples(imu.t_ns[keep], imu.accel[keep], imu.gyro[keep])
    assert "the IMU covers" in _scene(tiny_sim_session, VioConfig(), imu=holed)[0]
    wide_gap = load_config(VioConfig, None, ["scene.max_imu_gap_s=10"])
    assert _scene(tiny_sim_session, wide_gap, imu=holed) == []
    lenient = load_config(VioConfig, None, ["scene.min_imu_coverage=0.5"])
    assert _scene(tiny_sim_session, lenient, imu=holed) == []


def test_n_frames_picks_the_best_of_the_first_frames(tiny_sim_session: Path) -> None:
    source = open_session(tiny_sim_session)
    cfg = VioConfig()
    frames = [source.frame(i) for i in range(3)]
    frames[0] = replace(frames[0], depth_m=np.zeros_like(frames[0].depth_m))
    up = standing_up(source.imu, int(frames[1].t_ns), cfg.init)
    one = load_config(VioConfig, None, ["scene.n_frames=1"])
    assert _scene(tiny_sim_session, one, frames=frames, up=up) != []
    assert _scene(tiny_sim_session, cfg, frames=frames, up=up) == []


def _with_imu(session: Path, out: Path, accel_sign: float = 1.0, keep: float = 1.0) -> Path:
    shutil.copytree(session, out)
    imu = open_session(session).imu
    n = int(len(imu) * keep)
    (out / "imu.csv").write_text(
        imu_csv_text(ImuSamples(imu.t_ns[:n], accel_sign * imu.accel[:n], imu.gyro[:n]))
    )
    return out


def test_vio_refuses_an_upside_down_imu(tiny_sim_session: Path, tmp_path: Path, capsys) -> None:
    session = _with_imu(tiny_sim_session, tmp_path / "flipped", accel_sign=-1.0)
    assert main(["vio", str(session), "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "T_CfromI" in err and "--force" in err
    assert not (tmp_path / "o").exists()
    assert main(["infer", str(session), "--out", str(tmp_path / "i")]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "T_CfromI" in err and not (tmp_path / "i").exists()


def test_force_runs_and_marks_the_result_unreliable(
    tiny_sim_session: Path, tmp_path: Path, capsys
) -> None:
    session = _with_imu(tiny_sim_session, tmp_path / "half", keep=0.6)
    assert main(["vio", str(session), "--out", str(tmp_path / "o")]) == 1
    assert "the IMU covers" in capsys.readouterr().err
    rc = main(["vio", str(session), "--out", str(tmp_path / "o"), "--force"])
    out = capsys.readouterr().out
    assert rc == 0 and "UNRELIABLE: the IMU covers" in out
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["reliable"] is False
    assert summary["unreliable_reasons"][0].startswith("the IMU covers")
    skipped = summary["measurements_skipped"]["frame"]
    assert skipped["after the IMU stream's last sample"] > 0


def test_frames_beyond_the_imu_are_skipped(tiny_sim_session: Path, tmp_path: Path) -> None:
    session = _with_imu(tiny_sim_session, tmp_path / "short", keep=0.93)
    cfg = load_config(VioConfig, None, ["smoother.enabled=false"])
    source = open_session(session)
    screening = screen_session(source, cfg.scene, cfg.init, cfg.floor, 3)
    assert screening.problems == []
    times = source.frame_times_ns
    assert times[screening.last_index] <= source.imu.t_ns[-1] < times[screening.last_index + 1]
    with pytest.raises(SceneError, match="the IMU covers"):
        strict = load_config(VioConfig, None, ["scene.min_imu_coverage=1.0"])
        screen_session(source, strict.scene, strict.init, strict.floor, 3)


def _bag_frames() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The real recording's colour image, first depth image [m] and depth camera matrix."""
    bag = RosBag(BAG)
    depth_topic = next(t for t in bag.topics if "Depth" in t and t.endswith("image/data"))
    color_topic = next(t for t in bag.topics if "Color" in t and t.endswith("image/data"))
    info_topic = next(t for t in bag.topics if "Depth" in t and t.endswith("camera_info"))
    K = np.array(bag.decode_all(info_topic)[0].K, dtype=np.float64).reshape(3, 3)
    depth = decode_depth(bag.decode(bag.refs(depth_topic)[0], depth_topic), 0.001)
    rgb = decode_color(bag.decode(bag.refs(color_topic)[0], color_topic))
    bag.close()
    return rgb, depth, K


@pytest.mark.parametrize("up_axis", range(6))
def test_a_real_office_without_a_walker_is_refused(tmp_path: Path, up_axis: int) -> None:
    """Real D435 frames of an office (no person) as a 1 s session, with a still IMU whose up is
    each camera axis in turn: whatever the IMU claims, the scene is refused. The depth camera's
    matrix stands for colour's (the scene check only reads depth)."""
    rgb, depth, K = _bag_frames()
    h, w = depth.shape
    intr = CameraIntrinsics(width=w, height=h, fx=K[0, 0], fy=K[1, 1], cx=K[0, 2], cy=K[1, 2])
    calib = SessionCalibration(
        color=intr, depth=intr, depth_scale_m=0.001, depth_aligned_to_color=True,
        T_CfromI=np.eye(4),
        imu_noise=None, apriltag_boards=(), device="Intel RealSense D435 (real frames)",
    )  # fmt: skip
    up = np.concatenate([np.eye(3), -np.eye(3)])[up_axis]
    t_imu = np.arange(0, 1_100_000_000, 5_000_000, dtype=np.int64)
    imu = ImuSamples(t_imu, np.tile(9.81 * up, (len(t_imu), 1)), np.zeros((len(t_imu), 3)))
    with SessionWriter(tmp_path / "office", calib) as writer:
        for i in range(30):
            writer.add_frame(10_000_000 + i * 33_333_333, rgb, depth)
        writer.set_imu(imu)
    cfg = VioConfig()
    with pytest.raises(SceneError, match="does not show what a waist-worn camera sees"):
        screen_session(open_session(tmp_path / "office"), cfg.scene, cfg.init, cfg.floor, 3)


def test_scale_says_when_it_rests_on_depth_alone() -> None:
    from collections import Counter

    from gaitnet.vio.report import SCALE_FROM_DEPTH, SCALE_FROM_SHEETS, scale_source
    from gaitnet.vio.result import VioResult

    poses = np.tile(np.eye(4), (2, 1, 1))
    result = VioResult(
        t_s=np.array([0.0, 0.1]), T_WfromI_filter=poses, T_WfromC_filter=poses,
        T_WfromC_imu_only=poses, T_WfromI_smoothed=None, T_WfromC_smoothed=None,
        stance_feet=[], strides=[], initialisation="gravity_floor", initialisation_note="",
    )  # fmt: skip
    assert scale_source(result) == SCALE_FROM_DEPTH and "no AprilTag sheet" in SCALE_FROM_DEPTH
    result.used = Counter(tag=3)  # a sheet seen later, at the end of the walk
    assert scale_source(result) == SCALE_FROM_SHEETS
    result.used, result.initialisation = Counter(), "apriltag"
    assert scale_source(result) == SCALE_FROM_SHEETS


def _floor_only(frame, K: np.ndarray, up_C: np.ndarray, cfg: VioConfig):
    """``frame`` with its depth replaced by the depth of its fitted floor alone (the walker
    and everything else removed): ``n·(z r) + h = 0`` along each pixel's ray ``r``."""
    from gaitnet.geometry.floor_plane import fit_floor, floor_points

    pts = floor_points(frame.depth_m, K, cfg.floor.stride, cfg.floor.max_range_m)
    plane = fit_floor(pts, up_C, cfg.floor)
    h, w = frame.depth_m.shape
    u, v = np.meshgrid(np.arange(w), np.arange(h))
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones(u.shape)], -1)
    facing = rays @ plane.n_C
    depth = np.where(facing < -1e-6, -plane.h / np.minimum(facing, -1e-6), 0.0)
    return replace(frame, depth_m=depth.astype(np.float32))


def test_a_floor_without_the_walkers_legs_is_refused(tiny_sim_session: Path) -> None:
    """The same first frames with only their floor left: a camera that does not see its
    wearer's legs (a tripod, a hand) is refused; the walk itself shows them."""
    from gaitnet.geometry.floor_plane import fit_floor, floor_points
    from gaitnet.vio.scene_check import leg_fraction

    cfg = VioConfig()
    source = open_session(tiny_sim_session)
    K = source.calibration.color.K
    frames = [source.frame(i) for i in range(3)]
    up_I = standing_up(source.imu, int(frames[0].t_ns), cfg.init)
    up_C = source.calibration.T_CfromI[:3, :3] @ up_I
    pts = floor_points(frames[0].depth_m, K, cfg.floor.stride, cfg.floor.max_range_m)
    plane = fit_floor(pts, up_C, cfg.floor)
    assert leg_fraction(pts, plane.height(pts), plane, cfg.scene) > 5 * cfg.scene.min_leg_fraction
    bare = [_floor_only(f, K, up_C, cfg) for f in frames]
    (problem,) = _scene(tiny_sim_session, cfg, frames=bare)
    assert problem.startswith("no legs under the camera: 0.00 % of the depth points")
    relaxed = replace(cfg, scene=replace(cfg.scene, min_leg_fraction=0.0))
    assert _scene(tiny_sim_session, relaxed, frames=bare) == []


def test_leg_fraction_counts_the_volume_under_the_camera() -> None:
    """Known answer: a floor 1 m below a camera looking straight down; points at 0.5 m height
    count within the reach of the plumb line and below 0.15 m under the camera only."""
    from gaitnet.geometry.floor_plane import FloorPlane
    from gaitnet.vio.scene_check import SceneParams, leg_fraction

    plane = FloorPlane(n_C=np.array([0.0, 0.0, -1.0]), h=1.0)  # camera z down, floor at z 1
    points = np.array([
        [0.1, 0.0, 0.5],   # a leg: 0.5 m up, 0.1 m off the plumb line
        [0.6, 0.0, 0.5],   # beyond the 0.5 m reach
        [0.0, 0.0, 0.97],  # 3 cm above the floor: the floor's relief
        [0.0, 0.1, 0.1],   # 0.9 m up: 0.1 m under the camera, its strap
    ])  # fmt: skip
    assert leg_fraction(points, plane.height(points), plane, SceneParams()) == 0.25
