"""The measured feet's sides checked against the filter's stance landmarks
(gaitnet/pipeline/side_check.py): known answers for each rule, points the landmarks do not
cover left alone, and the config keys reaching ``gaitnet infer``'s reconstruction."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gaitnet.pipeline.side_check import check_sides
from gaitnet.vio.result import StanceFoot

NEAR, FAR = 0.08, 0.2
LEFT_XY, RIGHT_XY = np.array([1.0, 0.1]), np.array([1.3, -0.1])


def _landmark(side: str, xy: np.ndarray, t0: float = 0.0, t1: float = 1.0) -> StanceFoot:
    return StanceFoot(0, side, t0, t1, np.asarray(xy, float), np.full(2, 0.01), 10)


def _frame(left, right) -> np.ndarray:
    """One frame's points (1, 2, 3): a point at floor ``xy`` (z 0.05), or None (not seen)."""
    out = np.full((1, 2, 3), np.nan)
    for i, xy in enumerate((left, right)):
        if xy is not None:
            out[0, i] = (*xy, 0.05)
    return out


BOTH = [_landmark("left", LEFT_XY), _landmark("right", RIGHT_XY)]
NEAR_LEFT, NEAR_RIGHT = LEFT_XY + [0.03, 0.02], RIGHT_XY + [-0.02, 0.03]


@pytest.mark.parametrize(
    ("landmarks", "measured", "expected", "counts"),
    [
        # sided right: unchanged
        (BOTH, (NEAR_LEFT, NEAR_RIGHT), (NEAR_LEFT, NEAR_RIGHT), (0, 0, 0)),
        # the right foot measured as the left one, the right side empty: moved
        (BOTH, (NEAR_RIGHT, None), (None, NEAR_RIGHT), (1, 0, 0)),
        # ... and the right side has its own point: the duplicate is dropped
        (BOTH, (NEAR_RIGHT + [0.01, 0], NEAR_RIGHT), (None, NEAR_RIGHT), (0, 0, 1)),
        # both the other's: swapped
        (BOTH, (NEAR_RIGHT, NEAR_LEFT), (NEAR_LEFT, NEAR_RIGHT), (0, 1, 0)),
        # far from its own resting foot and near no other: dropped
        (BOTH, (LEFT_XY + [0.5, 0.3], NEAR_RIGHT), (None, NEAR_RIGHT), (0, 0, 1)),
        # only the right foot rests: a left point elsewhere (swinging) is left alone
        (BOTH[1:], (LEFT_XY + [0.5, 0.3], None), (LEFT_XY + [0.5, 0.3], None), (0, 0, 0)),
        # nothing rests at this time: nothing to check against
        (
            [_landmark("right", RIGHT_XY, 2.0, 3.0)],
            (NEAR_RIGHT, None),
            (NEAR_RIGHT, None),
            (0, 0, 0),
        ),
    ],
)
def test_rules_known_answers(landmarks, measured, expected, counts) -> None:
    out, changed = check_sides(np.array([0.5]), _frame(*measured), landmarks, NEAR, FAR)
    np.testing.assert_array_equal(out, _frame(*expected))
    assert (changed["moved"], changed["swapped"], changed["dropped"]) == counts


def test_each_frame_is_checked_against_the_landmarks_resting_then() -> None:
    landmarks = [_landmark("left", LEFT_XY, 0.0, 0.5), _landmark("right", RIGHT_XY, 0.4, 1.0)]
    t = np.array([0.2, 0.45, 0.8])
    feet = np.concatenate([_frame(NEAR_RIGHT, None)] * 3)  # a left point at the right's place
    out, changed = check_sides(t, feet, landmarks, NEAR, FAR)
    # 0.2: only the left rests, 0.28 m away: dropped; 0.45 and 0.8: the right rests there
    np.testing.assert_array_equal(out[0], _frame(None, None)[0])
    np.testing.assert_array_equal(out[1:], np.concatenate([_frame(None, NEAR_RIGHT)] * 2))
    assert changed == {"moved": 2, "swapped": 0, "dropped": 1}
    # the thresholds act: with a shorter reach the point is no longer the right foot's
    out, _ = check_sides(t, feet, landmarks, 0.02, FAR)
    assert np.isnan(out[1:, 1]).all()


def test_side_check_keys_reach_the_reconstruction(tiny_sim_session: Path, monkeypatch) -> None:
    """``pipeline.side_check`` runs the check on the observed points before the correction,
    with ``vio.stance.same_foot_m`` and ``pipeline.side_check_far_m`` as its distances; what it
    returns is what the correction and the outputs see. Off, the observed points go on."""
    import gaitnet.pipeline.infer as infer
    from gaitnet.config import load_config
    from gaitnet.io import open_session
    from gaitnet.motion.onnx_runtime import OnnxPredictor
    from gaitnet.pipeline.config import InferConfig
    from gaitnet.pipeline.foot_points import FrameFeet

    p_C = np.array([[0.1, 0.5, 1.0], [-0.1, 0.45, 0.9]])

    def fixed_feet(frame, K, T_WfromC, *args, **kwargs) -> FrameFeet:
        foot_W = p_C @ T_WfromC[:3, :3].T + T_WfromC[:3, 3]
        return FrameFeet(foot_W, np.zeros(frame.depth_m.shape, np.uint8), 2)

    class NoSegmenter:
        """Never called: ``measure_feet`` is replaced."""

        arch = "rgb"
        input_scale = 0.5
        path = Path("none")

    monkeypatch.setattr(infer, "measure_feet", fixed_feet)
    base = ["vio.smoother.enabled=false", "pipeline.gap_fill=none"]
    cfg = load_config(InferConfig, None, base)
    obs = infer.observe(open_session(tiny_sim_session), cfg, segmenter=NoSegmenter())  # type: ignore[arg-type]
    seen: list[tuple[float, float]] = []

    def drop_right(t_s, foot_W, stance_feet, near_m, far_m):
        seen.append((near_m, far_m))
        out = np.array(foot_W, copy=True)
        out[:, 1] = np.nan
        return out, {"moved": 0, "swapped": 0, "dropped": len(out)}

    monkeypatch.setattr(infer, "check_sides", drop_right)
    predictor = OnnxPredictor(infer.default_predictor_path())
    keys = [*base, "vio.stance.same_foot_m=0.05", "pipeline.side_check_far_m=0.3"]
    on = infer.reconstruct(obs, load_config(InferConfig, None, keys), predictor)
    assert seen == [(0.05, 0.3)]
    assert on.foot_measured[:, 0].all() and not on.foot_measured[:, 1].any()
    off = infer.reconstruct(
        obs, load_config(InferConfig, None, [*base, "pipeline.side_check=false"]), predictor
    )
    assert len(seen) == 1 and off.foot_measured.all()
