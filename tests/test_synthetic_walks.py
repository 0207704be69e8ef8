"""Synthetic walking clips: AMASS keys and shapes, the real loader, FK reproduces the simulator."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gaitnet.motion.amass import DatasetSplit, load_amass_clip, read_amass_npz
from gaitnet.motion.prepared import load_prepared, prepare_walking_subset
from gaitnet.motion.skeleton import ROTATED_SMPL_INDICES, LowerBodySkeleton, forward_kinematics
from gaitnet.sim.amass_clips import (
    REST_JOINTS_KEY,
    SYNTH_DATASET_SPLIT,
    SyntheticWalksConfig,
    make_synthetic_walks,
    sample_gait_config,
    walk_to_amass,
    write_amass_poses,
)
from gaitnet.sim.amass_mix import CLIP_KINDS, clip_motion
from gaitnet.sim.gait import GaitConfig, generate_walk
from gaitnet.sim.gait_plan import WalkVariation
from gaitnet.sim.subject import sample_subject

ROOT = Path(__file__).parents[1]


def _walk(seed: int = 3, speed: float = 1.4, turn: float = 60.0):
    rng = np.random.default_rng(seed)
    subject = sample_subject(rng)
    for _ in range(20):  # the generator may reject a draw; the module retries the same way
        try:
            cfg = GaitConfig(
                speed_mps=speed,
                walk_length_m=3.0,
                turn_deg=turn,
                stand_start_s=1.0,
                stand_end_s=1.0,
            )
            return generate_walk(subject, cfg, rng)
        except RuntimeError:
            continue
    pytest.fail("gait generator failed 20 times")


@pytest.fixture(scope="module")
def walk():
    return _walk()


def test_written_clip_has_amass_keys_and_shapes(tmp_path: Path, walk) -> None:
    arrays = walk_to_amass(walk, 120.0)
    path = write_amass_poses(tmp_path / "S" / "s0" / "s0_00_walk_poses.npz", arrays)
    with np.load(path, allow_pickle=False) as data:
        T = data["poses"].shape[0]
        assert data["poses"].shape == (T, 156) and data["trans"].shape == (T, 3)
        assert data["betas"].shape == (16,) and not data["betas"].any()
        assert data["dmpls"].shape == (T, 8) and not data["dmpls"].any()
        assert str(data["gender"]) == "neutral"
        assert float(data["mocap_framerate"]) == 120.0
        assert data[REST_JOINTS_KEY].shape == (9, 3)
        poses = data["poses"].reshape(T, 52, 3)
        nonzero = {k for k in range(52) if np.abs(poses[:, k]).max() > 0}
        assert nonzero <= {0, *ROTATED_SMPL_INDICES} and {0, 1, 2, 4, 5, 7, 8} <= nonzero
    assert int(np.floor(walk.duration_s * 120.0 + 1e-9)) + 1 == T
    clip = read_amass_npz(path, amass_root=tmp_path)
    assert clip.dataset == "S" and clip.fps == 120.0


@pytest.mark.parametrize("fps", [120.0, 250.0])
def test_fk_of_resampled_clip_reproduces_the_simulator(tmp_path: Path, walk, fps: float) -> None:
    path = write_amass_poses(tmp_path / "x_walk_poses.npz", walk_to_amass(walk, fps))
    clip = load_amass_clip(path)  # resampled by time to 30 fps
    assert clip.fps == 30.0 and clip.source_fps == fps
    skeleton = LowerBodySkeleton(np.load(path)[REST_JOINTS_KEY])
    joints = forward_kinematics(skeleton, clip.root_orient, clip.trans, clip.joint_aa)
    truth = walk.joints(np.arange(clip.n_frames) / 30.0)
    err = np.linalg.norm(joints - truth, axis=-1)
    # 120 Hz: the 30 fps times are source samples (exact); 250 Hz: slerp between samples.
    assert err.max() < (1e-9 if fps == 120.0 else 1e-3), err.max()


def test_dataset_layout_split_and_loader(tmp_path: Path) -> None:
    cfg = SyntheticWalksConfig(
        seed=1,
        train_subjects=2,
        val_subjects=1,
        test_subjects=1,
        walks_per_subject=1,
        walk_length_range_m=(3.0, 3.5),
        turn_probability=0.5,
        mocap_rates_hz=(60.0, 100.0),
    )
    report = make_synthetic_walks(tmp_path / "synth", cfg)
    manifest = json.loads((tmp_path / "synth" / "manifest.json").read_text())
    assert len(manifest["clips"]) == len(report.clips) == 4
    for c in report.clips:
        assert (tmp_path / "synth" / c.path).is_file()
        assert c.path.startswith(f"{c.dataset}/{c.subject}/") and c.path.endswith("_walk_poses.npz")
        assert 1.55 <= c.height_m <= 1.90
        if c.split == "test":
            assert 1.0 <= c.speed_mps <= 1.2
        else:
            assert 0.6 <= c.speed_mps <= 1.0 or 1.2 <= c.speed_mps <= 1.7
    subjects = {s: {c.subject for c in report.clips if c.split == s} for s in ("train", "test")}
    assert not subjects["train"] & subjects["test"]

    out = prepare_walking_subset(tmp_path / "synth", tmp_path / "p.npz", split=SYNTH_DATASET_SPLIT)
    assert out.n_clips == {"train": 2, "val": 1, "test": 1}
    prepared = load_prepared(tmp_path / "p.npz")
    assert prepared.fps == 30.0 and set(prepared.clip_source_fps) <= {60.0, 100.0}
    # The default (AMASS) mapping would put every synthetic clip in training.
    assert DatasetSplit().split_of("SynthWalkTest") == "train"
    assert SYNTH_DATASET_SPLIT.split_of("SynthWalkTest") == "test"


def test_config_rejects_overlapping_speed_bands() -> None:
    with pytest.raises(ValueError, match="overlaps"):
        SyntheticWalksConfig(train_speed_bands=((0.6, 1.1),), test_speed_bands=((1.0, 1.2),))


def test_script_smoke(tmp_path: Path) -> None:
    done = subprocess.run(
        [
            sys.executable,
            str(ROOT / "data" / "make_synthetic_walks.py"),
            "--out",
            str(tmp_path / "s"),
            "--n-subjects",
            "1",
            "0",
            "0",
            "--walks-per-subject",
            "1",
        ],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    assert "wrote 1 clips" in done.stdout
    bad = subprocess.run(
        [sys.executable, str(ROOT / "data" / "make_synthetic_walks.py"), "--out", "x",
         "--test-speeds", "0.7-0.9"],
        capture_output=True,
        text=True,
    )  # fmt: skip
    assert bad.returncode == 1 and bad.stderr.startswith("error: ") and bad.stderr.count("\n") == 1


# --------------------------------------------------------------------------- the clip mix


def _subject():
    return sample_subject(np.random.default_rng(7))


def _pelvis_speed(pose, fps: float) -> np.ndarray:
    return np.linalg.norm(np.diff(pose[1][:, :2], axis=0), axis=1) * fps


def test_default_variation_changes_nothing() -> None:
    cfg = GaitConfig(walk_length_m=4.0, turn_deg=40.0)
    a = generate_walk(_subject(), cfg, np.random.default_rng(1))
    b = generate_walk(_subject(), cfg, np.random.default_rng(1), variation=WalkVariation())
    t = np.linspace(0.0, a.duration_s, 200)
    assert a.duration_s == pytest.approx(b.duration_s, abs=1e-9)
    np.testing.assert_allclose(a.joints(t), b.joints(t), atol=1e-9)


def test_walk_variation_speed_change_asymmetry_and_sharp_turn() -> None:
    cfg = GaitConfig(speed_mps=0.8, walk_length_m=10.0, step_length_cv=0.0, step_time_cv=0.0)
    faster = generate_walk(
        _subject(), cfg, np.random.default_rng(2), variation=WalkVariation(speed_change=0.8)
    )
    hs = faster.steps.hs_s
    steady = slice(3, len(hs) - 3)
    speeds = faster.steps.length_m[steady][1:] / np.diff(hs[steady])
    assert speeds[-1] > 1.5 * speeds[0]  # 0.8 → 1.44 m/s over the walk
    limp = generate_walk(
        _subject(), cfg, np.random.default_rng(2),
        variation=WalkVariation(step_length_asymmetry=0.1),
    )  # fmt: skip
    lengths = limp.steps.length_m[steady]
    sides = np.array(limp.steps.side)[steady]
    ratio = lengths[sides == "left"].mean() / lengths[sides == "right"].mean()
    assert ratio == pytest.approx(1.1 / 0.9, rel=0.05)
    sharp = generate_walk(
        _subject(), replace(cfg, turn_deg=90.0), np.random.default_rng(2),
        variation=WalkVariation(turn_arc_m=2.0, turn_at=0.5),
    )  # fmt: skip
    s = np.array([0.0, 3.9, 6.1, 10.0])
    np.testing.assert_allclose(np.degrees(sharp.path.heading(s)), [0, 0, 90, 90], atol=1e-9)


def test_each_clip_kind(tmp_path: Path) -> None:
    cfg = SyntheticWalksConfig(
        walk_length_range_m=(3.0, 4.0), standing_range_s=(3.0, 3.5), pause_range_s=(2.0, 2.5),
        asymmetry_range=(0.02, 0.05),
    )  # fmt: skip
    subject = _subject()
    fps = 60.0
    for kind in CLIP_KINDS:
        rng = np.random.default_rng(5)
        motion = clip_motion(
            rng, subject, cfg, kind, lambda r=rng: sample_gait_config(r, cfg, ((1.0, 1.4),))
        )
        pose = motion.sample(fps)
        speed = _pelvis_speed(pose, fps)
        np.testing.assert_allclose(motion.skeleton_rest_joints, subject.skeleton().rest_joints)
        assert abs(pose[0].shape[0] - (motion.duration_s * fps + 1)) <= 2  # (pause: the blend)
        if kind == "standing":
            assert 3.0 <= motion.duration_s <= 3.5 and speed.max() < 0.05
            continue
        assert speed.max() > 0.8
        # every frame-to-frame change is smooth: no jump anywhere (the pause's junction too)
        joints = forward_kinematics(subject.skeleton(), *pose[:1], pose[1], pose[2])
        assert np.linalg.norm(np.diff(joints, axis=0), axis=-1).max() * fps < 8.0
        assert np.abs(np.diff(pose[1], axis=0)).max() * fps < 2.5
        if kind == "pause":  # walk, stand still (at least 1.5 s below 0.05 m/s), walk on
            moving = speed > 0.3
            first, last = np.argmax(moving), len(moving) - np.argmax(moving[::-1])
            still = (speed[first:last] < 0.05).sum() / fps
            assert still >= motion.pause_s >= 2.0  # plus both walks' settling
        if kind == "sharp_turn":
            assert 45.0 <= abs(motion.turn_deg) <= 180.0
        if kind == "speed_change":
            assert abs(motion.speed_change) > 0.2


def test_mix_config_file_and_default_clip_names(tmp_path: Path) -> None:
    (tmp_path / "mix.yaml").write_text(
        "train_subjects: 2\nval_subjects: 0\ntest_subjects: 0\nwalks_per_subject: 2\n"
        "walk_length_range_m: [3.0, 3.5]\nmix_walk: 0\nmix_standing: 1\n"
        "standing_range_s: [2.0, 2.5]\nheight_range_m: [1.3, 2.1]\n"
    )
    script = ROOT / "data" / "make_synthetic_walks.py"
    done = subprocess.run(
        [sys.executable, str(script), "--out", str(tmp_path / "s"), "--config",
         str(tmp_path / "mix.yaml"), "--n-subjects", "1", "0", "0"],
        capture_output=True, text=True,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    clips = json.loads((tmp_path / "s" / "manifest.json").read_text())["clips"]
    assert len(clips) == 2 and {c["kind"] for c in clips} == {"standing"}  # the CLI overrides
    assert all(c["path"].endswith("_standing_walk_poses.npz") for c in clips)
    assert all(2.0 <= c["duration_s"] <= 2.5 for c in clips)
    default = make_synthetic_walks(
        tmp_path / "d",
        SyntheticWalksConfig(train_subjects=1, val_subjects=0, test_subjects=0,
                             walks_per_subject=1, walk_length_range_m=(3.0, 3.5)),
    )  # fmt: skip
    assert [c.kind for c in default.clips] == ["walk"]
    assert default.clips[0].path.endswith("_00_walk_poses.npz")
    bad = subprocess.run(
        [sys.executable, str(script), "--out", "x", "--config", str(tmp_path / "no.yaml")],
        capture_output=True, text=True,
    )  # fmt: skip
    assert bad.returncode == 1 and bad.stderr.startswith("error: ") and bad.stderr.count("\n") == 1
    with pytest.raises(ValueError, match="mix_"):
        SyntheticWalksConfig(mix_walk=0.0)


def test_committed_mix_config_loads() -> None:
    from gaitnet.config import load_config

    cfg = load_config(
        SyntheticWalksConfig, ROOT / "configs" / "predictor" / "data" / "synthwalk_mix.yaml"
    )
    assert sum(v > 0 for v in cfg.mix.values()) == 5 and cfg.asymmetry_range[1] > 0


def test_mix_ranges_act(tmp_path: Path) -> None:
    """stand_range_s, asymmetry_range, turn_arc_range_m and min_speed_change_mps reach the clips."""
    cfg = SyntheticWalksConfig(
        train_subjects=1, val_subjects=0, test_subjects=0, walks_per_subject=4,
        walk_length_range_m=(4.0, 5.0), mix_walk=0.0, mix_sharp_turn=1.0, mix_speed_change=1.0,
        stand_range_s=(3.0, 3.2), asymmetry_range=(0.05, 0.06), turn_arc_range_m=(1.5, 1.6),
        min_speed_change_mps=0.45, mocap_rates_hz=(60.0,),
    )  # fmt: skip
    report = make_synthetic_walks(tmp_path / "s", cfg)
    assert {c.kind for c in report.clips} == {"sharp_turn", "speed_change"}
    for c in report.clips:
        assert 0.05 <= abs(c.step_length_asymmetry) <= 0.06
        assert 0.05 <= abs(c.step_time_asymmetry) <= 0.06
        if c.kind == "sharp_turn":
            assert 1.5 <= c.turn_arc_m <= 1.6
        else:
            assert abs(c.speed_change * c.speed_mps) >= 0.45 - 1e-6
        clip = read_amass_npz(tmp_path / "s" / c.path)
        speed = np.linalg.norm(np.diff(clip.trans[:, :2], axis=0), axis=1) * clip.fps
        assert np.argmax(speed > 0.05) / clip.fps >= 3.0  # standing start of 3.0–3.2 s


def test_every_mix_key_is_documented() -> None:
    from dataclasses import fields

    text = (ROOT / "docs" / "predictor.md").read_text()
    missing = [f.name for f in fields(SyntheticWalksConfig) if f"`{f.name}`" not in text]
    assert not missing, f"SyntheticWalksConfig keys missing in docs/predictor.md: {missing}"
