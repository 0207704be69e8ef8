"""Synthetic walking clips in AMASS's SMPL+H G ``*_poses.npz`` format (thesis sec. 4.2.2).

A product of the simulator (it lives in :mod:`gaitnet.sim`, which builds on
:mod:`gaitnet.motion`; nothing in :mod:`gaitnet.motion` imports the simulator).

The thesis trains its motion predictor (sec. 4.2) on AMASS walking clips. AMASS is licensed and
not downloadable at run time, so this module writes clips of the same format from the
simulator's gait generator (:func:`gaitnet.sim.gait.generate_walk`): the files go through the
real AMASS loader (:func:`gaitnet.motion.prepared.prepare_walking_subset`, resampling by time
included) exactly as downloaded AMASS clips would.

One clip = one whole simulated walk (standing start, gait initiation, steady walking, optional
turn, stopping, standing end), sampled at a mocap-like rate drawn from
:attr:`SyntheticWalksConfig.mocap_rates_hz` (60 / 100 / 120 Hz by default, so the 30 fps
resampling is exercised with non-integer and integer ratios alike).

Keys written (AMASS SMPL+H G, see :data:`gaitnet.motion.prepared.PREPARED_KEYS` for what is read):

* ``poses`` (T, 156) float64: root orientation in ``[0:3]``, SMPL joint ``k``'s local
  axis-angle in ``[3k : 3k+3]``; only the lower-body joints 1, 2, 4, 5, 7, 8, 10, 11 are
  non-zero (the simulator moves nothing else; the foot joints 10, 11 are zero too);
* ``trans`` (T, 3) float64 [m]: SMPL translation, ``p_pelvis = J_rest[0] + trans``;
* ``betas`` (16,) zeros, ``dmpls`` (T, 8) zeros, ``gender`` ``'neutral'``,
  ``mocap_framerate`` () [Hz];
* ``gaitnet_rest_joints`` (9, 3) float64 [m]: the subject's own rest joints (SMPL canonical
  frame, order :data:`gaitnet.motion.skeleton.SMPL_JOINT_INDICES`). Synthetic clips use the
  simulator's built-in skeleton of the subject's height, not an SMPL body shape, so ``betas``
  carry no information; forward kinematics with these rest joints
  (:func:`gaitnet.motion.skeleton.forward_kinematics`) reproduces the simulator's joints.
  AMASS readers ignore unknown keys.

Split (held-out subjects AND a held-out speed band). Sub-datasets, as AMASS's first folder level:

* ``SynthWalkTrain``: training subjects, speeds in :attr:`SyntheticWalksConfig.train_speed_bands`
  (default 0.6–1.0 and 1.2–1.7 m/s);
* ``SynthWalkVal``: other subjects, speeds in the same training bands (model selection sees
  unseen people, never the held-out speeds);
* ``SynthWalkTest``: yet other subjects, speeds in :attr:`SyntheticWalksConfig.test_speed_bands`
  (default 1.0–1.2 m/s, a band no training or validation clip uses).

The folder → split mapping is :data:`SYNTH_DATASET_SPLIT`, a
:class:`gaitnet.motion.amass.DatasetSplit` passed to the loader (``prepare_amass.py --val
SynthWalkVal --test SynthWalkTest``, or the training config's ``data.val_datasets`` /
``data.test_datasets``); nothing is hard-coded in the loader.

Layout: ``<root>/<SubDataset>/<subject>/<clip>_walk_poses.npz`` plus ``<root>/manifest.json``
(one entry per clip: split, subject, height, speed, turn, rate, duration).
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from gaitnet.checks import check_each, check_int_range, check_range
from gaitnet.io.atomic import atomic_open, atomic_write_text, staged_folder
from gaitnet.motion.amass import REST_JOINTS_KEY, DatasetSplit
from gaitnet.motion.skeleton import ROTATED_SMPL_INDICES
from gaitnet.sim.amass_mix import (
    CLIP_KINDS,
    ClipMotion,
    choose_kind,
    clip_motion,
    sample_gait_config,
)
from gaitnet.sim.config import HEIGHT_LIMITS_M
from gaitnet.sim.gait import Walk
from gaitnet.sim.scene_setup import SEED_LIMIT
from gaitnet.sim.subject import HEIGHT_RANGE_M, Subject, sample_subject

__all__ = [
    "N_SMPLH_JOINTS",
    "REST_JOINTS_KEY",
    "SPLIT_DATASETS",
    "SYNTH_DATASET_SPLIT",
    "SyntheticClip",
    "SyntheticWalksConfig",
    "SyntheticWalksReport",
    "make_synthetic_walks",
    "pose_to_amass",
    "sample_gait_config",
    "walk_to_amass",
    "write_amass_poses",
]

#: SMPL+H G has 52 joints (22 body + 2 × 15 hand): ``poses`` has 156 columns.
N_SMPLH_JOINTS = 52
#: Split → sub-dataset folder.
SPLIT_DATASETS: dict[str, str] = {
    "train": "SynthWalkTrain",
    "val": "SynthWalkVal",
    "test": "SynthWalkTest",
}
#: The loader's split mapping for these folders.
SYNTH_DATASET_SPLIT = DatasetSplit(val=(SPLIT_DATASETS["val"],), test=(SPLIT_DATASETS["test"],))

Band = tuple[float, float]
logger = logging.getLogger(__name__)
_MAX_ATTEMPTS = 20


@dataclass(frozen=True)
class SyntheticWalksConfig:
    """What :func:`make_synthetic_walks` generates (lengths m, speeds m/s, angles deg).

    Subjects per split and walks per subject; heights uniform in ``height_range_m``; each
    walk's speed uniform over the union of its split's speed bands; walk length uniform in
    ``walk_length_range_m``; with probability ``turn_probability`` the path turns by an angle
    uniform in ``turn_range_deg`` (random sign); step-to-step variability (step length / time
    coefficients of variation, step-width spread) uniform in the ``*_range`` values; pelvis
    amplitudes, toe-out and heel-off timing are varied around the simulator's defaults (the
    stance share follows the speed and the subject's gait style); the
    sampling rate is drawn from ``mocap_rates_hz``.
    """

    seed: int = 0
    train_subjects: int = 40
    val_subjects: int = 8
    test_subjects: int = 10
    walks_per_subject: int = 3
    height_range_m: Band = HEIGHT_RANGE_M
    train_speed_bands: tuple[Band, ...] = ((0.6, 1.0), (1.2, 1.7))
    test_speed_bands: tuple[Band, ...] = ((1.0, 1.2),)
    walk_length_range_m: Band = (6.0, 16.0)
    turn_probability: float = 0.35
    turn_range_deg: Band = (30.0, 180.0)
    step_cv_range: Band = (0.01, 0.05)
    step_width_std_range_m: Band = (0.005, 0.02)
    mocap_rates_hz: tuple[float, ...] = (60.0, 100.0, 120.0)
    #: Weights of the clip kinds (:mod:`gaitnet.sim.amass_mix`); the default: whole walks only.
    mix_walk: float = 1.0
    mix_sharp_turn: float = 0.0
    mix_speed_change: float = 0.0
    mix_pause: float = 0.0
    mix_standing: float = 0.0
    stand_range_s: Band = (1.0, 1.5)
    standing_range_s: Band = (6.0, 20.0)
    sharp_turn_range_deg: Band = (45.0, 180.0)
    turn_arc_range_m: Band = (1.0, 3.0)
    min_speed_change_mps: float = 0.3
    pause_range_s: Band = (1.0, 4.0)
    asymmetry_range: Band = (0.0, 0.0)

    @property
    def mix(self) -> dict[str, float]:
        """Clip kind → weight (the ``mix_*`` keys)."""
        return {k: float(getattr(self, f"mix_{k}")) for k in CLIP_KINDS}

    def __post_init__(self) -> None:
        for name in ("train_subjects", "val_subjects", "test_subjects", "walks_per_subject"):
            value = getattr(self, name)
            if not isinstance(value, int) or value < 0:
                raise ValueError(f"{name} must be a non-negative integer, got {value!r}")
        for name in ("train_speed_bands", "test_speed_bands"):
            bands = getattr(self, name)
            if not bands or any(not 0.6 <= lo < hi <= 1.7 for lo, hi in bands):
                raise ValueError(f"{name} must be non-empty bands within 0.6–1.7 m/s: {bands}")
        for lo, hi in self.train_speed_bands:
            for tlo, thi in self.test_speed_bands:
                if lo < thi and tlo < hi:
                    raise ValueError(
                        f"test speed band {(tlo, thi)} overlaps training band {(lo, hi)}"
                    )
        if not self.mocap_rates_hz or min(self.mocap_rates_hz) < 30.0:
            raise ValueError(f"mocap_rates_hz must be rates >= 30 Hz, got {self.mocap_rates_hz}")
        check_range("turn_probability", self.turn_probability, 0.0, 1.0)
        check_int_range("seed", self.seed, 0, SEED_LIMIT - 1)
        for name, lo, hi in (
            ("height_range_m", *HEIGHT_LIMITS_M),
            ("walk_length_range_m", 3.0, 100.0),
            ("turn_range_deg", 0.0, 360.0),
            ("step_cv_range", 0.0, 0.1),
            ("step_width_std_range_m", 0.0, 0.1),
        ):
            band = getattr(self, name)
            check_each(name, band, lo, hi)
            if band[0] > band[1]:
                raise ValueError(f"{name} must be [low, high], got {band}")
        check_each("mocap_rates_hz", self.mocap_rates_hz, 30.0, 1000.0)
        for kind in CLIP_KINDS:
            check_range(f"mix_{kind}", getattr(self, f"mix_{kind}"), 0.0, 1e6)
        if sum(self.mix.values()) <= 0:
            raise ValueError("the mix_* weights must not all be zero")
        check_range("min_speed_change_mps", self.min_speed_change_mps, 0.05, 0.5)
        for name, lo, hi in (
            ("stand_range_s", 1.0, 60.0),
            ("standing_range_s", 2.0, 60.0),
            ("sharp_turn_range_deg", 0.0, 360.0),
            ("turn_arc_range_m", 0.5, 20.0),
            ("pause_range_s", 0.5, 60.0),
            ("asymmetry_range", 0.0, 0.3),
        ):
            band = getattr(self, name)
            check_each(name, band, lo, hi)
            if band[0] > band[1]:
                raise ValueError(f"{name} must be [low, high], got {band}")


@dataclass(frozen=True)
class SyntheticClip:
    """One written clip (a row of ``manifest.json``)."""

    path: str  # relative to the root
    split: str
    kind: str
    dataset: str
    subject: str
    height_m: float
    speed_mps: float
    turn_deg: float
    walk_length_m: float
    mocap_framerate: float
    n_frames: int
    duration_s: float
    speed_change: float = 0.0
    pause_s: float = 0.0
    step_length_asymmetry: float = 0.0
    step_time_asymmetry: float = 0.0
    turn_arc_m: float | None = None


@dataclass(frozen=True)
class SyntheticWalksReport:
    """What :func:`make_synthetic_walks` wrote."""

    root: Path
    clips: tuple[SyntheticClip, ...]

    def count(self, split: str) -> tuple[int, float]:
        """Clips and minutes of motion in ``split``."""
        rows = [c for c in self.clips if c.split == split]
        return len(rows), sum(c.duration_s for c in rows) / 60.0


def walk_to_amass(walk: Walk, fps: float) -> dict[str, np.ndarray]:
    """The AMASS SMPL+H G arrays of a whole walk sampled at ``fps`` (module docstring keys).

    Frame ``n`` is the simulator's pose at ``t = n / fps`` for ``n = 0 .. floor(duration·fps)``.
    """
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    t = np.arange(int(math.floor(walk.duration_s * fps + 1e-9)) + 1) / fps
    return pose_to_amass(walk.smpl_pose(t), walk.skeleton.rest_joints, fps)


def pose_to_amass(
    pose: tuple[np.ndarray, np.ndarray, np.ndarray], rest_joints: np.ndarray, fps: float
) -> dict[str, np.ndarray]:
    """The AMASS SMPL+H G arrays of ``(root_orient, trans, joint_aa)`` sampled at ``fps``."""
    root_orient, trans, joint_aa = pose
    T = root_orient.shape[0]
    poses = np.zeros((T, N_SMPLH_JOINTS, 3))
    poses[:, 0] = root_orient
    poses[:, list(ROTATED_SMPL_INDICES)] = joint_aa
    return {
        "poses": poses.reshape(T, 3 * N_SMPLH_JOINTS),
        "trans": np.asarray(trans, dtype=np.float64),
        "betas": np.zeros(16),
        "dmpls": np.zeros((T, 8)),
        "gender": np.array("neutral"),
        "mocap_framerate": np.array(float(fps)),
        REST_JOINTS_KEY: np.array(rest_joints, dtype=np.float64),
    }


def write_amass_poses(path: str | Path, arrays: dict[str, np.ndarray]) -> Path:
    """Write ``arrays`` as an (uncompressed, pickle-free) ``.npz``, atomically."""
    path = Path(path)
    with atomic_open(path, "wb") as handle:
        np.savez(handle, **arrays)
    return path


def _generate(
    rng: np.random.Generator,
    subject: Subject,
    cfg: SyntheticWalksConfig,
    bands: tuple[Band, ...],
    what: str,
) -> tuple[str, ClipMotion]:
    """One clip; a draw the generator cannot realise is replaced by a fresh draw (same kind)."""
    kind = choose_kind(rng, cfg.mix)
    for attempt in range(1, _MAX_ATTEMPTS + 1):
        try:
            return kind, clip_motion(
                rng, subject, cfg, kind, lambda: sample_gait_config(rng, cfg, bands)
            )
        except (RuntimeError, ValueError) as exc:
            logger.warning("%s: gait draw %d rejected by the generator (%s)", what, attempt, exc)
    raise RuntimeError(f"{what}: the gait generator failed {_MAX_ATTEMPTS} draws in a row")


def make_synthetic_walks(
    out_root: str | Path,
    cfg: SyntheticWalksConfig | None = None,
    *,
    overwrite: bool = False,
    progress: Callable[[Iterable[tuple[str, int]], int], Iterable[tuple[str, int]]] | None = None,
) -> SyntheticWalksReport:
    """Generate the three sub-datasets under ``out_root`` and a ``manifest.json``.

    Deterministic given ``cfg.seed``: every subject has its own child generator of
    ``SeedSequence(seed)``, so a subject's clips do not depend on how many subjects come
    before it in other splits. ``progress(iterable, total)`` may wrap the subject loop.
    ``out_root`` must not exist or be empty (else ``overwrite`` replaces it); it appears only
    when complete (:func:`gaitnet.io.atomic.staged_folder`).
    """
    cfg = SyntheticWalksConfig() if cfg is None else cfg
    with staged_folder(out_root, overwrite) as staging:
        clips = _write_clips(staging, cfg, progress)
    return SyntheticWalksReport(root=Path(out_root), clips=clips)


def _write_clips(
    root: Path,
    cfg: SyntheticWalksConfig,
    progress: Callable[[Iterable[tuple[str, int]], int], Iterable[tuple[str, int]]] | None,
) -> tuple[SyntheticClip, ...]:
    jobs = [
        (split, i)
        for split, n in (
            ("train", cfg.train_subjects),
            ("val", cfg.val_subjects),
            ("test", cfg.test_subjects),
        )
        for i in range(n)
    ]
    split_code = {"train": 0, "val": 1, "test": 2}
    iterator: Iterable[tuple[str, int]] = jobs if progress is None else progress(jobs, len(jobs))
    clips: list[SyntheticClip] = []
    for split, i in iterator:
        rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, split_code[split], i]))
        dataset = SPLIT_DATASETS[split]
        subject_id = f"{split}_s{i:03d}"
        subject = sample_subject(rng, cfg.height_range_m)
        bands = cfg.test_speed_bands if split == "test" else cfg.train_speed_bands
        for w in range(cfg.walks_per_subject):
            kind, motion = _generate(rng, subject, cfg, bands, f"{subject_id} clip {w}")
            fps = float(rng.choice(np.asarray(cfg.mocap_rates_hz, dtype=np.float64)))
            arrays = pose_to_amass(motion.sample(fps), motion.skeleton_rest_joints, fps)
            tag = "" if kind == "walk" else f"_{kind}"
            rel = f"{dataset}/{subject_id}/{subject_id}_{w:02d}{tag}_walk_poses.npz"
            write_amass_poses(root / rel, arrays)
            n_frames = int(arrays["poses"].shape[0])
            clips.append(
                SyntheticClip(
                    path=rel,
                    split=split,
                    kind=kind,
                    dataset=dataset,
                    subject=subject_id,
                    height_m=round(subject.height_m, 4),
                    speed_mps=round(motion.speed_mps, 4),
                    turn_deg=round(motion.turn_deg, 2),
                    walk_length_m=round(motion.walk_length_m, 3),
                    mocap_framerate=fps,
                    n_frames=n_frames,
                    duration_s=round((n_frames - 1) / fps, 4),
                    speed_change=round(motion.speed_change, 4),
                    pause_s=round(motion.pause_s, 3),
                    **_variation_fields(motion),
                )
            )
    manifest = {
        "config": _jsonable(asdict(cfg)),
        "datasets": SPLIT_DATASETS,
        "clips": [asdict(c) for c in clips],
    }
    atomic_write_text(root / "manifest.json", json.dumps(manifest, indent=1) + "\n")
    return tuple(clips)


def _variation_fields(motion: ClipMotion) -> dict[str, float | None]:
    """The manifest's record of a clip's within-walk variation (asymmetry, turn arc)."""
    v = motion.variation
    if v is None:
        return {}
    return {
        "step_length_asymmetry": round(v.step_length_asymmetry, 4),
        "step_time_asymmetry": round(v.step_time_asymmetry, 4),
        "turn_arc_m": None if v.turn_arc_m is None else round(v.turn_arc_m, 3),
    }


def _jsonable(value: object) -> object:
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    return value
