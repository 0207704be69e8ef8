"""A motion clip drives the simulator (``gaitnet simulate --motion``): playback, conventions on
a real CMU walk, the lead-in and lead-out, gait events measured on the shoes, bad clips."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from oneline import assert_one_line_exit, assert_one_line_message

from gaitnet.config import load_config
from gaitnet.errors import InputError
from gaitnet.geometry import so3_exp, so3_log
from gaitnet.sim.amass_clips import walk_to_amass, write_amass_poses
from gaitnet.sim.clip_lead import warp_advance
from gaitnet.sim.clip_pose import PoseSamples, lowpass_poses
from gaitnet.sim.clip_walk import ClipWalk, build_clip_walk
from gaitnet.sim.config import SimConfig
from gaitnet.sim.gait import GaitConfig, generate_walk
from gaitnet.sim.scene import SIDES
from gaitnet.sim.subject import sample_subject

CMU = Path(__file__).parent / "data" / "cmu_walking_01_poses.npz"


def _cfg(clip: Path, *overrides: str) -> SimConfig:
    return load_config(SimConfig, None, [f"motion.clip={json.dumps(str(clip))}", *overrides])


def _clip_walk(clip: Path, *overrides: str, seed: int = 0) -> ClipWalk:
    return build_clip_walk(_cfg(clip, *overrides), np.random.default_rng(seed))


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    """A generated 3 m walk and the same walk written as a 120 Hz AMASS clip."""
    rng = np.random.default_rng(11)
    subject = sample_subject(rng, height_m=1.75)
    cfg = GaitConfig(speed_mps=1.2, walk_length_m=3.0, stand_start_s=1.0, stand_end_s=1.0)
    walk = generate_walk(subject, cfg, rng)
    path = tmp_path_factory.mktemp("clip") / "gen_walk_poses.npz"
    write_amass_poses(path, walk_to_amass(walk, 120.0))
    return walk, path


@pytest.fixture(scope="module")
def cmu() -> ClipWalk:
    return _clip_walk(CMU)


def test_generated_walk_played_back_gives_its_joints(generated) -> None:
    walk, path = generated
    played = _clip_walk(path, "motion.lead_in_s=0", "motion.lead_out_s=0", "motion.lowpass_hz=0")
    T = np.array(json.loads(played.source.to_json())["T_session_from_clip"])
    t = np.arange(int(np.floor(walk.duration_s * 120.0 + 1e-9)) + 1) / 120.0
    expected = walk.joints(t) @ T[:3, :3].T + T[:3, 3]
    np.testing.assert_allclose(played.joints(t), expected, atol=1e-6)
    # the clip stands on its generated floor: levelling it turns it by less than 0.05°
    assert T[2, 2] > np.cos(np.radians(0.05))
    # the events measured on the shoes are the generator's: the same stances, heel strikes
    # within 40 ms, strides within 1 cm
    for side in SIDES:
        mine, truth = played.events[side], walk.events[side]
        assert len(mine.hs_s) == len(truth.hs_s)
        np.testing.assert_allclose(mine.hs_s[1:], truth.hs_s[1:], atol=0.04)
        np.testing.assert_allclose(mine.stride_lengths_m, truth.stride_lengths_m, atol=0.01)


def test_playback_between_frames_stays_on_the_motion(generated) -> None:
    walk, path = generated
    played = _clip_walk(path, "motion.lead_in_s=0", "motion.lead_out_s=0", "motion.lowpass_hz=0")
    T = np.array(json.loads(played.source.to_json())["T_session_from_clip"])
    t = (np.arange(200, 600) + 0.5) / 120.0  # halfway between the clip's frames
    expected = walk.joints(t) @ T[:3, :3].T + T[:3, 3]
    assert np.abs(played.joints(t) - expected).max() < 2e-3


def test_imu_kinematics_are_the_pelvis_derivatives(cmu: ClipWalk) -> None:
    t = np.linspace(0.5, cmu.duration_s - 0.5, 400)
    h = 1e-4
    _, p, v, a, _ = cmu.pelvis_kinematics(t)
    _, p1 = cmu.pelvis_pose(t + h)
    _, p0 = cmu.pelvis_pose(t - h)
    np.testing.assert_allclose(v, (p1 - p0) / (2 * h), atol=1e-5)
    _, _, v1, _, _ = cmu.pelvis_kinematics(t + h)
    _, _, v0, _, _ = cmu.pelvis_kinematics(t - h)
    np.testing.assert_allclose(a, (v1 - v0) / (2 * h), atol=1e-3)


def test_cmu_walk_conventions(cmu: ClipWalk) -> None:
    """AMASS's conventions as our reader and FK take them, checked on a real CMU walk: z up
    (pelvis about a metre over the floor the feet stand on), facing the walking direction,
    left on the left, knees flexing forwards."""
    motion = cmu.source.motion
    real = ~motion.synthetic
    t = motion.poses.t[real]
    J = cmu.joints(t)
    R_P, p_P = cmu.pelvis_pose(t)
    assert 0.85 < np.median(p_P[:, 2]) < 1.1
    soles = cmu.sole_centres(t)
    assert np.median(soles[..., 2].min(axis=1)) < 0.01  # a foot on the floor at every instant
    for side in SIDES:  # each foot rests on the floor every stride
        assert np.isfinite(cmu.events[side].hs_s).sum() >= 1
    walking = p_P[-1, :2] - p_P[0, :2]
    walking /= np.linalg.norm(walking)
    facing = np.degrees(np.arccos(np.clip(R_P[:, :2, 0] @ walking, -1, 1)))
    assert np.median(facing) < 15
    left_of_walk = np.array([-walking[1], walking[0]])
    assert np.all((J[:, 1, :2] - J[:, 2, :2]) @ left_of_walk > 0.1)  # left hip on the left
    for i in range(2):  # knees bend forwards: in front of the hip–ankle line when flexed
        hip, knee, ankle = J[:, 1 + i], J[:, 3 + i], J[:, 5 + i]
        e = (ankle - hip) / np.linalg.norm(ankle - hip, axis=1, keepdims=True)
        off = (knee - hip) - np.sum((knee - hip) * e, axis=1, keepdims=True) * e
        bent = np.linalg.norm(off, axis=1) > 0.05
        assert bent.sum() > 20
        assert np.all(np.sum(off[bent] * R_P[bent, :, 0], axis=1) > 0)


def test_lead_in_and_out_are_continuous_and_stand_still(cmu: ClipWalk) -> None:
    t = np.arange(0.0, cmu.duration_s, 1e-3)
    J = cmu.joints(t)
    step = np.linalg.norm(np.diff(J, axis=0), axis=-1)
    assert step.max() < 0.01  # no joint jumps: under 1 cm per ms (10 m/s)
    motion = cmu.source.motion
    assert motion.synthetic[0] and motion.synthetic[-1]
    cfg = GaitConfig()
    for window in ((0.0, cfg.stand_start_s), (cmu.duration_s - cfg.stand_end_s, cmu.duration_s)):
        tt = np.linspace(*window, 50)
        assert np.ptp(cmu.joints(tt), axis=0).max() < 1e-9  # standing still
        _, _, v, a, w = cmu.pelvis_kinematics(tt)
        assert np.abs(v).max() < 1e-5 and np.abs(w).max() < 1e-5
    soles = cmu.sole_centres(np.array([0.0, cmu.duration_s]))
    width = np.linalg.norm(soles[:, 0, :2] - soles[:, 1, :2], axis=1)
    np.testing.assert_allclose(width, 0.165, atol=0.02)
    # the session starts at the origin facing +x (as a generated walk)
    np.testing.assert_allclose(soles[0, :, :2].mean(axis=0), 0.0, atol=1e-9)
    R, _ = cmu.pelvis_pose(np.array([0.0]))
    assert abs(np.arctan2(R[0, 1, 0], R[0, 0, 0])) < 1e-9


def test_lead_in_follows_the_clip_at_its_own_speed(cmu: ClipWalk) -> None:
    m = cmu.source.motion
    fps = cmu.source.segment.fps
    real = np.flatnonzero(~m.synthetic)
    assert len(real) > 0.5 * fps  # at least half a second of the clip as recorded
    np.testing.assert_allclose(np.diff(m.clip_time_s[real]), 1.0 / fps, atol=1e-9)
    assert np.all(np.diff(m.clip_time_s[: real[0] + 1]) >= -1e-12)  # never backwards
    assert warp_advance(np.array([1.0]))[0] == pytest.approx(0.5)
    assert warp_advance(np.array([3.0]))[0] == pytest.approx(2.5)


def test_motion_keys_act(generated) -> None:
    _, path = generated
    short = _clip_walk(path, "motion.start_s=1.0", "motion.duration_s=3.0", "motion.lead_in_s=0")
    seg = short.source.segment.poses.t
    assert seg[0] == pytest.approx(1.0, abs=1 / 120) and seg[-1] == pytest.approx(4.0, abs=1 / 120)
    assert not short.source.motion.synthetic[0]  # no lead-in: the clip's own first frame
    t = np.arange(300) / 120.0
    poses = PoseSamples(
        t,
        np.zeros((300, 3)),
        np.column_stack([np.sin(2 * np.pi * 15 * t)] * 3),
        np.zeros((300, 8, 3)),
    )
    assert np.abs(lowpass_poses(poses, 5.0).trans[90:-90]).max() < 0.01  # 15 Hz is cut
    np.testing.assert_array_equal(lowpass_poses(poses, 0.0).trans, poses.trans)


def test_rest_joints_or_height_or_estimate(generated, tmp_path: Path) -> None:
    walk, path = generated
    played = _clip_walk(path, "motion.lead_in_s=0", "motion.lead_out_s=0")
    assert played.source.segment.skeleton_source == "rest_joints"
    np.testing.assert_array_equal(played.skeleton.rest_joints, walk.skeleton.rest_joints)
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files if k != "gaitnet_rest_joints"}
    bare = write_amass_poses(tmp_path / "bare_poses.npz", arrays)
    given = _clip_walk(bare, "subject.height_m=1.6", "motion.lead_in_s=0", "motion.lead_out_s=0")
    assert given.source.segment.skeleton_source == "subject.height_m"
    assert given.subject.height_m == pytest.approx(1.6)
    estimated = _clip_walk(bare, "motion.lead_in_s=0", "motion.lead_out_s=0")
    assert estimated.source.segment.skeleton_source == "estimated"
    # the generated subject's legs are 0.491 of 1.75 m ± 3 %: the least sliding height is near
    assert estimated.source.segment.height_m == pytest.approx(1.75, abs=0.1)


def test_mount_pitch_is_from_horizontal_while_standing(cmu: ClipWalk) -> None:
    from gaitnet.sim.scene_setup import build_scene, rng_streams

    cfg = _cfg(CMU, "scene.clutter_count=0", "scene.room=false")
    scene = build_scene(cfg, rng_streams(0))
    T = scene.T_WfromC(np.array([0.0]))[0]
    pitch = np.degrees(np.arcsin(-T[2, 2]))  # the optical axis below horizontal
    assert pitch == pytest.approx(cfg.mount.pitch_deg, abs=0.01)
    assert scene.pitch_deg == pytest.approx(cfg.mount.pitch_deg)


def _write(path: Path, **arrays) -> Path:
    np.savez(path, **arrays)
    return path


def _cmu_arrays() -> dict[str, np.ndarray]:
    with np.load(CMU) as data:
        return {k: data[k] for k in data.files}


@pytest.mark.parametrize(
    ("change", "fragments"),
    [
        ({"drop": "poses"}, ["missing key 'poses'"]),
        ({"nan": "trans"}, ["'trans'", "NaN"]),
        ({"mocap_framerate": np.array(0.0)}, ["'mocap_framerate'", "positive"]),
    ],
)
def test_bad_clip_files_are_one_line(tmp_path: Path, change: dict, fragments: list[str]) -> None:
    arrays = _cmu_arrays()
    if "drop" in change:
        arrays.pop(change["drop"])
    elif "nan" in change:
        arrays[change["nan"]] = arrays[change["nan"]].copy()
        arrays[change["nan"]][10, 0] = np.nan
    else:
        arrays.update(change)
    path = _write(tmp_path / "bad_poses.npz", **arrays)
    with pytest.raises(InputError) as info:
        _clip_walk(path)
    assert_one_line_message(info.value, str(path), *fragments)


def test_a_missing_clip_or_broken_rest_joints_is_one_line(tmp_path: Path, generated) -> None:
    missing = tmp_path / "nowhere_poses.npz"
    with pytest.raises(InputError) as info:
        _clip_walk(missing)
    assert_one_line_message(info.value, str(missing))
    _, path = generated
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    arrays["gaitnet_rest_joints"] = np.zeros((9, 3))  # every bone of length 0
    broken = _write(tmp_path / "broken_poses.npz", **arrays)
    with pytest.raises(InputError) as info:
        _clip_walk(broken)
    assert_one_line_message(info.value, str(broken), "gaitnet_rest_joints")


def test_bad_segments_are_one_line(tmp_path: Path) -> None:
    for overrides, fragments in (
        (["motion.start_s=100"], ["motion.start_s", "outside the clip"]),
        (["motion.duration_s=0.6"], ["motion.duration_s", "less than one stride"]),
    ):
        with pytest.raises(InputError) as info:
            _clip_walk(CMU, *overrides)
        assert_one_line_message(info.value, str(CMU), *fragments)


def test_clips_without_walking_are_refused(tmp_path: Path, generated) -> None:
    walk, _ = generated
    arrays = walk_to_amass(walk, 120.0)
    t = np.arange(len(arrays["trans"])) / 120.0
    still = dict(arrays, trans=arrays["trans"] - np.outer(1.2 * t, [1.0, 0.0, 0.0]))
    treadmill = write_amass_poses(tmp_path / "treadmill_poses.npz", still)  # feet slide back
    with pytest.raises(InputError) as info:
        _clip_walk(treadmill)
    assert_one_line_message(info.value, str(treadmill), "walk")  # slides or never rests
    n = int(0.9 * 120)  # the standing start alone: both feet down, nobody walks
    standing = {k: (v[:n] if k in ("poses", "trans", "dmpls") else v) for k, v in arrays.items()}
    path = write_amass_poses(tmp_path / "standing_poses.npz", standing)
    with pytest.raises(InputError) as info:
        _clip_walk(path)
    assert_one_line_message(info.value, str(path), "motion.duration_s")


def test_simulate_motion_writes_the_motion_truth(tmp_path: Path) -> None:
    out = tmp_path / "s"
    result = subprocess.run(
        [sys.executable, "-m", "gaitnet.cli", "simulate", "--config", "configs/sim/tiny.yaml",
         "--motion", str(CMU), "--out", str(out), "output.preview_frames=0"],
        capture_output=True, text=True, cwd=Path(__file__).parents[1],
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    info = json.loads((out / "groundtruth" / "motion.json").read_text())
    assert info["source"] == "clip" and info["clip"] == str(CMU.resolve())
    frames = np.genfromtxt(out / "groundtruth" / "motion_frames.csv", delimiter=",", names=True)
    assert frames["synthetic"][0] == 1 and (frames["synthetic"] == 0).sum() > 10
    assert "clip:" in (out / "sim_config.yaml").read_text()
    bad = subprocess.run(
        [sys.executable, "-m", "gaitnet.cli", "simulate", "--motion", str(tmp_path / "no.npz"),
         "--out", str(tmp_path / "o")],
        capture_output=True, text=True,
    )  # fmt: skip
    assert_one_line_exit(bad.stderr, bad.returncode, "--motion", "no such file")


def test_clip_walk_turns_with_its_clip(tmp_path: Path) -> None:
    """A clip turned about z plays the same walk, turned back to face +x."""
    a = _clip_walk(CMU)
    arrays = _cmu_arrays()
    R = so3_exp(np.array([0.0, 0.0, 1.0]))
    poses = arrays["poses"].copy()
    poses[:, :3] = so3_log(R @ so3_exp(poses[:, :3]))
    arrays.update(poses=poses, trans=arrays["trans"] @ R.T)
    b = _clip_walk(_write(tmp_path / "turned_poses.npz", **arrays))
    t = np.linspace(0, a.duration_s, 50)
    assert b.duration_s == pytest.approx(a.duration_s)
    np.testing.assert_allclose(b.joints(t), a.joints(t), atol=5e-3)


def test_subject_has_the_skeleton_lengths(cmu: ClipWalk) -> None:
    s = cmu.subject
    assert s.thigh_m == pytest.approx(np.mean(cmu.skeleton.thigh_lengths))
    assert s.shank_m == pytest.approx(np.mean(cmu.skeleton.shank_lengths))
    assert s.height_m == cmu.source.segment.height_m
