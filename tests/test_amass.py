"""AMASS reader, prepared file, windows: flavours, resampling by time, heading, split, errors."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from amassfactory import walking_like_clip, write_smplh_poses, write_smplx_stageii
from scipy.spatial.transform import Rotation

from gaitnet.errors import InputError
from gaitnet.motion.amass import (
    REST_JOINTS_KEY,
    AmassError,
    DatasetSplit,
    find_amass_files,
    is_walking_clip,
    load_amass_clip,
    read_amass_npz,
)
from gaitnet.motion.gcn import split_pose_features
from gaitnet.motion.heading import heading_angle, normalise_heading
from gaitnet.motion.prepared import load_prepared, prepare_walking_subset
from gaitnet.motion.skeleton import ROTATED_SMPL_INDICES, builtin_skeleton, forward_kinematics
from gaitnet.motion.windows import WalkingWindows

LOWER = list(ROTATED_SMPL_INDICES)


def _analytic(fps: float, duration: float):
    """Constant-rate rotations about fixed body axes and a linear translation, at ``fps``.

    Every track is ``R(t) = R0 exp(omega t · axis)``: a geodesic at constant speed, so slerp
    between any two samples reproduces it exactly, while interpolating the axis-angle vectors
    (or picking the nearest frames) would not. The exact value at any time is known.
    """
    rng = np.random.default_rng(int(fps * 100))
    n_tracks = 22  # root + 21 body joints
    R0 = Rotation.from_rotvec(rng.normal(scale=1.0, size=(n_tracks, 3)))
    axes = rng.normal(size=(n_tracks, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    omega = rng.uniform(-2.0, 2.0, size=n_tracks)
    v, c = rng.normal(size=3), rng.normal(size=3)

    def at(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        steps = Rotation.from_rotvec(
            (axes[None] * (omega[None] * t[:, None])[..., None]).reshape(-1, 3)
        )
        R = Rotation.concatenate([R0] * len(t)) * steps
        return R.as_rotvec().reshape(len(t), n_tracks, 3), c + v * t[:, None]

    T = int(round(duration * fps)) + 1
    return at, at(np.arange(T) / fps)


def _angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    shape = a.shape[:-1]
    d = Rotation.from_rotvec(a.reshape(-1, 3)).inv() * Rotation.from_rotvec(b.reshape(-1, 3))
    return d.magnitude().reshape(shape)


@pytest.mark.parametrize(("fps", "flavour"), [(120.0, "smplh"), (60.0, "smplx"), (50.0, "smplh")])
def test_resampling_by_time_matches_analytic_motion(tmp_path: Path, fps: float, flavour: str):
    duration = 1.9
    at, (rot, trans) = _analytic(fps, duration)
    T = rot.shape[0]
    if flavour == "smplh":
        poses = np.concatenate([rot.reshape(T, -1), np.zeros((T, 156 - 66))], axis=1)
        path = write_smplh_poses(tmp_path / "a_poses.npz", poses, trans, fps)
    else:
        path = write_smplx_stageii(
            tmp_path / "a_stageii.npz", rot[:, 0], rot[:, 1:].reshape(T, 63), trans, fps
        )
    clip = load_amass_clip(path, fps=30.0)
    assert clip.fps == 30.0 and clip.source_fps == fps
    n_expected = int(np.floor(duration * 30 + 1e-9)) + 1  # 57 frames: t = 0 … 1.8667 s
    assert clip.n_frames == n_expected
    t = np.arange(n_expected) / 30.0
    rot_true, trans_true = at(t)
    assert _angle_between(clip.root_orient, rot_true[:, 0]).max() < 1e-9
    assert _angle_between(clip.joint_aa, rot_true[:, LOWER]).max() < 1e-9
    np.testing.assert_allclose(clip.trans, trans_true, atol=1e-9)


def test_both_flavours_give_the_same_lower_body(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    poses, trans = walking_like_clip(40, 120.0, rng)
    betas = rng.normal(size=16)
    a = read_amass_npz(write_smplh_poses(tmp_path / "x_poses.npz", poses, trans, 120, betas=betas))
    b = read_amass_npz(
        write_smplx_stageii(
            tmp_path / "x_stageii.npz", poses[:, :3], poses[:, 3:66], trans, 120, betas=betas
        )
    )
    for clip in (a, b):
        np.testing.assert_array_equal(clip.root_orient, poses[:, :3])
        for i, k in enumerate(LOWER):
            np.testing.assert_array_equal(clip.joint_aa[:, i], poses[:, 3 * k : 3 * k + 3])
        np.testing.assert_array_equal(clip.trans, trans)
        np.testing.assert_array_equal(clip.betas, betas)
    assert (a.gender, b.gender) == ("female", "male")


def test_heading_normalisation_faces_plus_x_and_keeps_the_motion(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    poses, trans = walking_like_clip(20, 30.0, rng, yaw0=2.5)
    root, aa = poses[:, :3], poses[:, 3:].reshape(20, -1, 3)[:, [k - 1 for k in LOWER]]
    assert abs(heading_angle(root[9])) > 0.5  # really turned before normalising
    root_n, trans_n, yaw = normalise_heading(root, trans, ref=9)
    forward = Rotation.from_rotvec(root_n[9]).apply([0.0, 0.0, 1.0])
    assert forward[0] > 0.9 and abs(forward[1]) < 1e-12
    assert abs(heading_angle(root_n[9])) < 1e-12
    np.testing.assert_allclose(trans_n[9, :2], 0.0, atol=1e-12)
    # Joint positions: rotated about z by −yaw plus one constant offset for all joints/frames.
    skel = builtin_skeleton(1.7)
    p = forward_kinematics(skel, root, trans, aa)
    p_n = forward_kinematics(skel, root_n, trans_n, aa)
    Rz = Rotation.from_rotvec([0, 0, -yaw]).as_matrix()
    diff = p_n - p @ Rz.T
    np.testing.assert_allclose(diff, np.broadcast_to(diff[0, 0], diff.shape), atol=1e-12)


def test_keyword_selection() -> None:
    assert is_walking_clip("KIT/3/walking_medium01_poses.npz")
    assert is_walking_clip("HumanEva/S1/Walking_1_poses.npz")
    assert not is_walking_clip("ACCAD/Female1Walking_c3d/B5 - walk backwards_poses.npz")
    assert not is_walking_clip("KIT/3/walking_upstairs01_poses.npz")
    assert not is_walking_clip("CMU/07/07_01_poses.npz")
    assert not is_walking_clip("ACCAD/Female1Walking_c3d/B1 - stand_poses.npz")  # folder ignored
    assert is_walking_clip("CMU/07/07_01_poses.npz", include=("07_",), exclude=())


def test_default_split_by_sub_dataset() -> None:
    split = DatasetSplit()
    assert split.split_of("BMLrub") == "test"
    assert split.split_of("BioMotionLab_NTroje") == "test"
    for name in ("HumanEva", "MPI_HDM05", "hdm05", "SFU", "MPI_mosh", "MoSh"):
        assert split.split_of(name) == "val"
    for name in ("CMU", "KIT", "ACCAD", "TotalCapture", "EKUT"):
        assert split.split_of(name) == "train"


def _make_root(root: Path) -> None:
    rng = np.random.default_rng(2)

    def smplh(rel: str, T: int, fps: float = 120.0) -> None:
        poses, trans = walking_like_clip(T, fps, rng)
        write_smplh_poses(root / rel, poses, trans, fps, betas=rng.normal(size=16))

    smplh("BMLrub/rub001/0007_normal_walk1_poses.npz", 121)  # test: 31 frames at 30 fps
    smplh("HumanEva/S1/Walking_1_poses.npz", 97)  # val: 25 frames
    smplh("KIT/3/walking_medium01_poses.npz", 241)  # train: 61 frames
    smplh("KIT/3/walking_slow02_poses.npz", 60, fps=59.94)  # train: 30 frames
    smplh("KIT/3/walking_short_poses.npz", 40)  # too short (10 frames at 30 fps)
    smplh("CMU/07/07_01_poses.npz", 121)  # walking, but the name does not say so
    smplh("ACCAD/Female1Walking_c3d/B5 - walk backwards_poses.npz", 121)
    np.savez(root / "KIT/3/shape.npz", betas=np.zeros(16), gender=np.array("male"))
    poses, trans = walking_like_clip(61, 60.0, rng)
    write_smplx_stageii(
        root / "SFU/0005/0005_Walking001_stageii.npz", poses[:, :3], poses[:, 3:66], trans, 60
    )  # val, SMPL-X: 31 frames


def test_prepare_walking_subset_and_windows(tmp_path: Path) -> None:
    root = tmp_path / "amass"
    _make_root(root)
    assert len(find_amass_files(root)) == 8  # shape.npz is not a clip
    seen: list[int] = []

    def progress(files, total):
        seen.append(total)
        return files

    out = tmp_path / "prepared" / "walking.npz"
    report = prepare_walking_subset(root, out, progress=progress)
    assert seen == [6]  # the keyword-selected candidates
    assert report.n_clips == {"train": 2, "val": 2, "test": 1}
    assert report.n_frames == {"train": 61 + 30, "val": 25 + 31, "test": 31}
    assert [name for name, _ in report.skipped] == ["KIT/3/walking_short_poses.npz"]

    data = load_prepared(out)
    assert data.fps == 30.0
    by_name = dict(zip(data.clip_name, data.clip_split, strict=True))
    assert by_name["SFU/0005/0005_Walking001_stageii.npz"] == "val"
    assert by_name["BMLrub/rub001/0007_normal_walk1_poses.npz"] == "test"
    assert set(data.clip_dataset) == {"BMLrub", "HumanEva", "KIT", "SFU"}
    clip = data.clip(int(np.flatnonzero(data.clip_name == "KIT/3/walking_slow02_poses.npz")[0]))
    assert clip.source_fps == 59.94 and clip.n_frames == 30

    train = WalkingWindows(out, "train", n_past=10, n_future=10, stride=5)
    # 61 frames → starts 0, 5, …, 40 (9 windows); 30 frames → 0, 5, 10 (3 windows).
    assert len(train) == 12
    item = train[3]
    assert item["poses"].shape == (20, 21) and item["poses"].dtype == torch.float32
    assert item["trans"].shape == (20, 3) and item["betas"].shape == (16,)
    root_n, _ = split_pose_features(item["poses"].double().numpy())
    assert abs(heading_angle(root_n[9])) < 1e-5  # last observed frame faces +x
    assert len(WalkingWindows(out, "val", stride=5)) == 2 + 3
    assert len(WalkingWindows(out, "test", stride=1)) == 12
    batch = next(iter(torch.utils.data.DataLoader(train, batch_size=4)))
    assert batch["poses"].shape == (4, 20, 21)
    with pytest.raises(AmassError, match="no windows"):
        WalkingWindows(out, "test", n_past=20, n_future=20)

    # A sub-dataset's own stride: KIT at stride 1 gives 61 − 19 + 30 − 19 windows, any case.
    per_set = WalkingWindows(out, "train", stride=5, dataset_stride={"kit": 1})
    assert len(per_set) == (61 - 19) + (30 - 19)
    assert np.array_equal(per_set.index[:3, 1] - per_set.index[0, 1], [0, 1, 2])
    with pytest.raises(InputError, match="sub-dataset 'cmu' in split 'train'"):
        WalkingWindows(out, "train", dataset_stride={"CMU": 1})  # no training clip there
    with pytest.raises(InputError, match="strides >= 1"):
        WalkingWindows(out, "train", dataset_stride={"KIT": 0})


def test_clip_list_selection(tmp_path: Path) -> None:
    root = tmp_path / "amass"
    _make_root(root)
    clip_list = tmp_path / "clips.txt"
    clip_list.write_text("# CMU walks found by description\nCMU/07/07_01_poses.npz\n\n")
    report = prepare_walking_subset(root, tmp_path / "w.npz", clip_list=clip_list)
    assert report.n_clips == {"train": 1, "val": 0, "test": 0}
    assert list(load_prepared(tmp_path / "w.npz").clip_name) == ["CMU/07/07_01_poses.npz"]
    clip_list.write_text("CMU/07/07_02_poses.npz\n")
    with pytest.raises(AmassError, match=r"07_02_poses\.npz"):
        prepare_walking_subset(root, tmp_path / "w2.npz", clip_list=clip_list)


def test_clear_errors_name_file_and_key(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    poses, trans = walking_like_clip(30, 120.0, rng)
    p = write_smplh_poses(
        tmp_path / "nofps_poses.npz", poses, trans, 120, drop=("mocap_framerate",)
    )
    with pytest.raises(AmassError, match=r"nofps_poses\.npz.*'mocap_framerate'"):
        read_amass_npz(p)
    p = write_smplx_stageii(
        tmp_path / "notrans_stageii.npz", poses[:, :3], poses[:, 3:66], trans, 60, drop=("trans",)
    )
    with pytest.raises(AmassError, match=r"notrans_stageii\.npz.*'trans'"):
        read_amass_npz(p)
    bad = poses.copy()
    bad[17, 12] = np.nan
    p = write_smplh_poses(tmp_path / "nan_poses.npz", bad, trans, 120)
    with pytest.raises(AmassError, match=r"nan_poses\.npz.*'poses'.*NaN.*frame 17"):
        read_amass_npz(p)
    p = write_smplh_poses(tmp_path / "shape_poses.npz", poses, trans[:, :2], 120)
    with pytest.raises(AmassError, match=r"'trans' must have shape \(30, 3\)"):
        read_amass_npz(p)
    p = write_smplh_poses(tmp_path / "short_poses.npz", poses[:, :30], trans, 120)
    with pytest.raises(AmassError, match="'poses' must have shape"):
        read_amass_npz(p)
    p = write_smplh_poses(tmp_path / "zero_poses.npz", poses, trans, 0.0)
    with pytest.raises(AmassError, match="'mocap_framerate' must be a positive"):
        read_amass_npz(p)
    (tmp_path / "junk_poses.npz").write_bytes(b"not a zip")
    with pytest.raises(AmassError, match="junk_poses"):
        read_amass_npz(tmp_path / "junk_poses.npz")
    # prepare: a broken file stops the run by default, or is skipped and reported.
    root = tmp_path / "root"
    write_smplh_poses(root / "KIT/1/walk_a_poses.npz", poses, trans, 120)
    write_smplh_poses(root / "KIT/1/walk_b_poses.npz", bad, trans, 120)
    with pytest.raises(AmassError, match="walk_b_poses"):
        prepare_walking_subset(root, tmp_path / "out.npz", min_frames=5)
    report = prepare_walking_subset(root, tmp_path / "out.npz", min_frames=5, on_error="skip")
    assert report.n_clips["train"] == 1 and "walk_b_poses" in report.skipped[0][0]
    with pytest.raises(AmassError, match="no walking clips"):
        prepare_walking_subset(root, tmp_path / "o.npz", include=("run",))


def test_prepared_file_checks(tmp_path: Path) -> None:
    bad = tmp_path / "old.npz"
    np.savez(bad, format_version=np.array(0))
    with pytest.raises(AmassError, match="missing key"):
        load_prepared(bad)


def test_prepare_script_smoke(tmp_path: Path) -> None:
    root = tmp_path / "amass"
    _make_root(root)
    script = Path(__file__).parents[1] / "data" / "prepare_amass.py"
    out = tmp_path / "walking.npz"
    done = subprocess.run(
        [sys.executable, str(script), str(root), str(out)], capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    assert "train" in done.stdout and load_prepared(out).n_clips == 5
    done = subprocess.run(
        [sys.executable, str(script), str(tmp_path / "none"), str(out)],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 1 and done.stderr.startswith("error: ")


def test_a_clip_linked_into_the_amass_folder_keeps_its_sub_dataset(tmp_path: Path) -> None:
    """A symbolic link inside the AMASS folder to a file stored elsewhere belongs to the
    sub-dataset it is linked under (it used to lose it and land in the train split)."""
    rng = np.random.default_rng(4)
    poses, trans = walking_like_clip(60, 60.0, rng)
    store = write_smplh_poses(tmp_path / "store" / "x_poses.npz", poses, trans, 60.0)
    root = tmp_path / "amass"
    linked = root / "BMLrub" / "rub001" / "0001_treadmill_norm_poses.npz"
    linked.parent.mkdir(parents=True)
    linked.symlink_to(store)
    clip = read_amass_npz(linked, amass_root=root)
    assert clip.dataset == "BMLrub" and clip.name == "BMLrub/rub001/0001_treadmill_norm_poses.npz"
    assert DatasetSplit().split_of(clip.dataset) == "test"
    # the root reached through a link of its own names clips the same way
    root_link = tmp_path / "amass_link"
    root_link.symlink_to(root)
    via = read_amass_npz(root_link / "BMLrub" / "rub001" / linked.name, amass_root=root_link)
    assert via.dataset == "BMLrub"
    # a file outside the root has no sub-dataset
    assert read_amass_npz(store, amass_root=root).dataset == ""


def test_rest_joints_travel_from_the_clip_into_the_prepared_file(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    root = tmp_path / "amass"
    poses, trans = walking_like_clip(61, 60.0, rng)
    own = builtin_skeleton(1.62).rest_joints
    with_rest = write_smplh_poses(root / "Synth/s0/a_walk_poses.npz", poses, trans, 60.0)
    np.savez(with_rest, **dict(np.load(with_rest)), **{REST_JOINTS_KEY: own})
    write_smplh_poses(root / "CMU/01/b_walk_poses.npz", poses, trans, 60.0)
    assert np.array_equal(read_amass_npz(with_rest).rest_joints, own)
    out = tmp_path / "p.npz"
    prepare_walking_subset(root, out)
    data = load_prepared(out)
    i_own = int(np.flatnonzero(data.clip_name == "Synth/s0/a_walk_poses.npz")[0])
    np.testing.assert_allclose(data.rest_joints_of(i_own), own, atol=1e-6)
    assert data.rest_joints_of(1 - i_own) is None
    np.testing.assert_allclose(data.clip(i_own).rest_joints, own, atol=1e-6)
    # files of earlier versions (no rest joints) still load; a broken key is named
    arrays = dict(np.load(out))
    legacy = {k: v for k, v in arrays.items() if not k.startswith("clip_rest")}
    legacy.pop("clip_has_rest_joints")
    np.savez(tmp_path / "legacy.npz", **legacy)
    assert load_prepared(tmp_path / "legacy.npz").rest_joints_of(i_own) is None
    np.savez(tmp_path / "half.npz", **{**legacy, "clip_has_rest_joints": np.ones(2, bool)})
    with pytest.raises(AmassError, match="must come together"):
        load_prepared(tmp_path / "half.npz")
    np.savez(tmp_path / "nan.npz", **{**arrays, "clip_rest_joints": np.full((2, 9, 3), np.nan)})
    with pytest.raises(AmassError, match="clip_rest_joints"):
        load_prepared(tmp_path / "nan.npz")
    np.savez(with_rest, **{**dict(np.load(with_rest)), REST_JOINTS_KEY: np.zeros((3, 3))})
    with pytest.raises(AmassError, match=REST_JOINTS_KEY):
        read_amass_npz(with_rest)


def test_standing_and_transition_clips_join_the_walks_by_keyword(tmp_path: Path) -> None:
    rng = np.random.default_rng(4)
    root = tmp_path / "amass"
    poses, trans = walking_like_clip(61, 60.0, rng)
    for rel in ("CMU/01/01_walk_poses.npz", "CMU/01/01_stand_poses.npz",
                "CMU/02/02_turn_around_poses.npz", "HumanEva/S1/idle_poses.npz",
                "CMU/03/03_stairs_walk_poses.npz"):  # fmt: skip
        write_smplh_poses(root / rel, poses, trans, 60.0)
    report = prepare_walking_subset(root, tmp_path / "w.npz")
    assert report.n_clips == {"train": 1, "val": 0, "test": 0}  # walking only (no stairs)
    report = prepare_walking_subset(
        root, tmp_path / "all.npz", include=("walk", "stand", "idle", "turn")
    )
    # split by sub-dataset as the walks: CMU trains, HumanEva validates
    assert report.n_clips == {"train": 3, "val": 1, "test": 0}
