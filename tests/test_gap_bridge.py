"""Bridging swing gaps (gaitnet.pipeline.gap_bridge): known answers, and ``pipeline.gap_fill``
acting in ``reconstruct``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gaitnet.pipeline.gap_bridge import bridge_gaps, frames_to_bridge, gaps


def test_gaps_are_the_runs_bounded_on_both_sides() -> None:
    m = np.array([1, 1, 0, 0, 1, 1, 0, 1, 1, 0, 0], bool)
    assert gaps(m) == [(2, 4), (6, 7)]
    assert gaps(np.ones(4, bool)) == [] and gaps(np.zeros(4, bool)) == []


def test_a_single_frames_detection_does_not_end_a_gap() -> None:
    """Seen in frame 4 only, between misses: one gap 2 … 6, bridged over frame 4 to frame 7."""
    m = np.array([1, 1, 0, 0, 1, 0, 0, 1, 1, 0, 1], bool)
    assert gaps(m) == [(2, 7)]  # the lone frame 10 at the end bounds nothing either
    points = np.zeros((11, 1, 3))
    points[:, 0, 0] = 0.1 * np.arange(11)
    points[4, 0, 0] += 0.3  # where the false detection pulled the first pass
    out = bridge_gaps(points, m[:, None])
    assert np.isfinite(out[2:7, 0]).all() and np.isnan(out[[0, 1, 7, 8, 9, 10], 0]).all()


def test_constant_speed_spreads_the_discrepancy_evenly() -> None:
    """A path at constant speed along x, seen again 9 cm further on: the k-th of the gap's
    frames (of 4, the re-sighting the 5th step) moves by k/5 of it."""
    n = 10
    points = np.zeros((n, 1, 3))
    points[:, 0, 0] = 0.1 * np.arange(n)
    measured = np.ones((n, 1), bool)
    measured[3:7] = False
    points[7, 0] += [0.09, 0.0, -0.02]  # where the foot is seen: ahead and lower
    out = bridge_gaps(points, measured)
    assert np.isnan(out[measured[:, 0]]).all()
    for j, k in enumerate(range(3, 7), start=1):
        np.testing.assert_allclose(
            out[k, 0], points[k, 0] + j / 5 * np.array([0.09, 0.0, -0.02]), atol=1e-12
        )


def test_the_discrepancy_goes_where_the_predicted_foot_moves() -> None:
    """Still for the first half of the gap, then moving: the still frames keep their point."""
    x = np.array([0, 0, 0, 0, 0, 0, 0, 0.1, 0.3, 0.5, 0.6, 0.7, 0.8])
    points = np.zeros((len(x), 1, 3))
    points[:, 0, 0] = x
    measured = np.ones((len(x), 1), bool)
    measured[2:10] = False  # f_9 = 0.5, f_8 = 0.3: expected at 10 is 0.7; seen at 0.6
    out = bridge_gaps(points, measured)
    np.testing.assert_allclose(out[2:7, 0], points[2:7, 0], atol=1e-12)  # no motion, no change
    length = np.cumsum(np.abs(np.diff(np.r_[x[1:10], 0.7])))
    w = length / length[-1]
    np.testing.assert_allclose(out[2:10, 0, 0], x[2:10] + w[:-1] * (0.6 - 0.7), atol=1e-12)


def test_unbounded_gaps_are_left_alone_and_bad_shapes_refused() -> None:
    points = np.random.default_rng(0).normal(size=(6, 2, 3))
    measured = np.array([[0, 1], [1, 1], [1, 0], [1, 0], [1, 1], [0, 1]], bool)
    out = bridge_gaps(points, measured)
    assert np.isnan(out[:, 0]).all()  # left: gaps only at the ends
    assert np.isfinite(out[2:4, 1]).all() and np.isnan(out[[0, 1, 4, 5], 1]).all()
    with pytest.raises(ValueError, match="bridge_gaps"):
        bridge_gaps(points[:, :, :2], measured)


def test_gap_fill_key_acts(tiny_sim_session: Path, monkeypatch) -> None:
    """With ``pipeline.gap_fill: bridge`` the correction runs twice, the second time with the
    gap frames measured at the bridged points and the seen frames as they were; the result
    still flags the gap frames as filled. The first pass stops where the bridges need it no
    more (:func:`frames_to_bridge`). With ``none``, once. With ``swing``, the second pass
    takes the swing fill where it gives a point and the bridge elsewhere; a swing fill that
    covers every gap leaves only the second pass."""
    import gaitnet.pipeline.infer as infer
    from gaitnet.config import load_config
    from gaitnet.io import open_session
    from gaitnet.motion.onnx_runtime import OnnxPredictor
    from gaitnet.pipeline.config import InferConfig
    from gaitnet.pipeline.foot_points import FrameFeet

    p_C = np.array([[0.1, 0.5, 1.0], [-0.1, 0.45, 0.9]])

    def fixed_feet(frame, K, T_WfromC, *args, **kwargs) -> FrameFeet:
        foot_W = p_C @ T_WfromC[:3, :3].T + T_WfromC[:3, 3]
        if 20 <= frame.index < 30:
            foot_W[1] = np.nan  # a swing gap of the right foot
        return FrameFeet(foot_W, np.zeros(frame.depth_m.shape, np.uint8), 2)

    monkeypatch.setattr(infer, "measure_feet", fixed_feet)
    cfg = load_config(InferConfig, None, ["vio.smoother.enabled=false"])
    obs = infer.observe(open_session(tiny_sim_session), cfg, segmenter=_NoSegmenter())
    calls: list[list] = []
    real = infer.track_poses

    def spy(predict, start, measurements, *args, **kwargs):
        measurements = list(measurements)
        calls.append(measurements)
        return real(predict, start, measurements, *args, **kwargs)

    monkeypatch.setattr(infer, "track_poses", spy)
    bridged: list[tuple[np.ndarray, np.ndarray]] = []
    real_bridge = infer.bridge_gaps

    def spy_bridge(points, measured):
        out = real_bridge(points, measured)
        bridged.append((np.array(points), out))
        return out

    monkeypatch.setattr(infer, "bridge_gaps", spy_bridge)
    predictor = OnnxPredictor(infer.default_predictor_path())
    off = infer.reconstruct(
        obs, load_config(InferConfig, None, ["pipeline.gap_fill=none"]), predictor
    )
    assert len(calls) == 1
    calls.clear()
    on = infer.reconstruct(
        obs, load_config(InferConfig, None, ["pipeline.gap_fill=bridge"]), predictor
    )
    assert len(calls) == 2
    first = np.array([m.foot_W for m in calls[0]])
    second = np.array([m.foot_W for m in calls[1]])
    assert len(first) == 32 and len(second) == len(obs.foot_W)  # the gap ends at frame 30
    np.testing.assert_array_equal(first, obs.foot_W[:32])
    first = obs.foot_W
    gap = np.isnan(first[:, 1, 0])
    assert gap.sum() == 10
    assert np.isfinite(second).all()
    np.testing.assert_array_equal(second[~gap], first[~gap])
    # the second pass measures the gap at the bridge of the first pass's points, and those
    # are the correction's measured points (near the measurements where the foot is seen; the
    # reported shoe marker lies 4 cm behind them on this body)
    ((points, out),) = bridged
    np.testing.assert_array_equal(second[gap, 1], out[gap[:32], 1])
    near = np.linalg.norm(points[~gap[:32], 1] - first[:32][~gap[:32], 1], axis=1)
    assert np.median(near) < 0.02
    np.testing.assert_array_equal(on.foot_measured, off.foot_measured)
    assert not on.foot_measured[gap, 1].any()
    k = np.flatnonzero(gap)
    assert not np.allclose(on.feet_W[k, 1], off.feet_W[k, 1], atol=1e-4)
    np.testing.assert_allclose(on.feet_W[: k[0]], off.feet_W[: k[0]], atol=1e-9)

    # swing: a fill of the first half of the gap (a stand-in for the template's) replaces the
    # bridge there; the rest of the gap keeps the bridge
    half = k[: len(k) // 2]
    marker = np.array([0.3, -0.2, 0.1])

    given: list[tuple[float, ...]] = []

    def fake_swing(
        t_s, measured, stance_feet, height, *, span_offset_s, span_per_cycle,
        span_contralateral_offset_s, span_per_contralateral, retime_weight, retime_max_shift_s,
        start_delay_s, rest_end_lead_s,
    ):  # fmt: skip
        given.append(
            (height, span_offset_s, span_per_cycle, span_contralateral_offset_s,
             span_per_contralateral, retime_weight, retime_max_shift_s, start_delay_s,
             rest_end_lead_s)
        )  # fmt: skip
        out = np.full(np.shape(measured), np.nan)
        out[half, 1] = marker
        return out

    monkeypatch.setattr(infer, "swing_fill", fake_swing)
    calls.clear()
    bridged.clear()
    keys = [
        "pipeline.swing_span_offset_s=0.2",
        "pipeline.swing_span_per_cycle=0.6",
        "pipeline.subject_height_m=1.8",
        "pipeline.swing_span_contralateral_offset_s=0.1",
        "pipeline.swing_span_per_contralateral=1.3",
        "pipeline.swing_retime_weight=0.25",
        "pipeline.swing_retime_max_shift_s=0.05",
        "pipeline.swing_start_delay_s=0.03",
        "pipeline.swing_rest_end_lead_s=0.07",
    ]
    infer.reconstruct(obs, load_config(InferConfig, None, keys), predictor)
    assert given == [(1.8, 0.2, 0.6, 0.1, 1.3, 0.25, 0.05, 0.03, 0.07)]  # the keys reach the fill
    assert len(calls) == 2
    second = np.array([m.foot_W for m in calls[1]])
    np.testing.assert_array_equal(second[half, 1], np.broadcast_to(marker, (len(half), 3)))
    ((_, out),) = bridged
    rest = k[len(k) // 2 :]
    np.testing.assert_array_equal(second[rest, 1], out[rest, 1])
    np.testing.assert_array_equal(second[~gap], first[~gap])

    # the first pass cut short gives the poses of a whole first pass, to the bit
    cut_short = infer.frames_to_bridge
    for config in (["pipeline.gap_fill=bridge"], keys):
        short = infer.reconstruct(obs, load_config(InferConfig, None, config), predictor)
        monkeypatch.setattr(infer, "frames_to_bridge", lambda seen, covered: len(seen))
        whole = infer.reconstruct(obs, load_config(InferConfig, None, config), predictor)
        monkeypatch.setattr(infer, "frames_to_bridge", cut_short)
        np.testing.assert_array_equal(short.poses, whole.poses)
        np.testing.assert_array_equal(short.trans, whole.trans)

    # a swing fill of the whole gap: nothing to bridge, so no first pass
    half = k
    calls.clear()
    bridged.clear()
    whole = infer.reconstruct(obs, load_config(InferConfig, None, keys), predictor)
    assert len(calls) == 1 and not bridged
    only = np.array([m.foot_W for m in calls[0]])
    np.testing.assert_array_equal(only[k, 1], np.broadcast_to(marker, (len(k), 3)))
    np.testing.assert_array_equal(only[~gap], first[~gap])
    assert np.isfinite(whole.poses).all() and len(whole.poses) == len(first)


def test_frames_to_bridge_is_where_the_first_pass_may_stop() -> None:
    """Known answers, and on random masks the bridges over the frames it gives equal the
    bridges over the whole session at every frame of a gap that ``covered`` leaves open."""
    m = np.array([1, 1, 0, 0, 1, 1, 0, 0, 0, 1, 1, 1], bool)[:, None]  # gaps (2, 4), (6, 9)
    assert frames_to_bridge(m) == 11
    covered = np.zeros_like(m)
    covered[6:9] = True
    assert frames_to_bridge(m, covered) == 6  # through frame 5, after the first gap's end 4
    covered[2:4] = True
    assert frames_to_bridge(m, covered) == 0
    assert frames_to_bridge(np.ones((5, 2), bool)) == 0
    assert frames_to_bridge(np.array([1, 1, 0, 1, 1], bool)[:, None]) == 5  # all frames
    with pytest.raises(ValueError, match="frames_to_bridge"):
        frames_to_bridge(m, covered[:5])
    rng = np.random.default_rng(11)
    for _ in range(200):
        n = int(rng.integers(3, 40))
        measured = rng.random((n, 2)) < 0.6
        covered = (rng.random((n, 2)) < 0.5) & ~measured
        points = rng.normal(size=(n, 2, 3)).cumsum(axis=0)
        k = frames_to_bridge(measured, covered)
        full = bridge_gaps(points, measured)
        part = bridge_gaps(points[:k], measured[:k])
        for s in range(2):
            for a, b in gaps(measured[:, s]):
                if not covered[a:b, s].all():
                    assert b < k
                    np.testing.assert_array_equal(part[a:b, s], full[a:b, s])


class _NoSegmenter:
    """Never called: ``measure_feet`` is replaced."""

    arch = "rgb"
    input_scale = 0.5
    path = Path("none")
