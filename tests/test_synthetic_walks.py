"""Synthetic walking clips: AMASS keys and shapes, the real loader, FK reproduces the simulator."""

from __future__ import annotations

import json
import subprocess
import sys
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
    walk_to_amass,
    write_amass_poses,
)
from gaitnet.sim.gait import GaitConfig, generate_walk
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
