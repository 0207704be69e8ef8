"""Footstep-driven walking: contact constraints, kinematic consistency, realism, determinism."""

from __future__ import annotations

import numpy as np
import pytest

from gaitnet.geometry import so3_exp, so3_log
from gaitnet.motion import forward_kinematics
from gaitnet.sim.gait import REACH_FRACTION, GaitConfig, Walk, generate_walk
from gaitnet.sim.scene import SIDES, BodyState
from gaitnet.sim.subject import HEIGHT_RANGE_M, sample_subject

DT = 1e-3


def _walk(seed: int, height: float | None = 1.75, **cfg) -> Walk:
    rng = np.random.default_rng(seed)
    subject = sample_subject(rng, height_m=height)
    return generate_walk(subject, GaitConfig(**cfg), rng)


@pytest.fixture(scope="module")
def walk() -> Walk:
    """A 1.75 m subject walking 10 m at 1.3 m/s."""
    return _walk(7, speed_mps=1.3, walk_length_m=10.0)


@pytest.fixture(scope="module")
def turning() -> Walk:
    """A random subject walking 5 m while turning left by 90°."""
    return _walk(11, height=None, speed_mps=1.0, turn_deg=90.0)


@pytest.fixture(scope="module")
def t(walk: Walk) -> np.ndarray:
    return np.arange(0.0, walk.duration_s, DT)


def _sole_corners(w: Walk) -> np.ndarray:
    L, W = w.subject.shoe_length_m, w.subject.shoe_width_m
    return np.array([[sx * L / 2, sy * W / 2, 0.0] for sx in (-1, 1) for sy in (-1, 1)])


def _inside(t: np.ndarray, a: float, b: float) -> np.ndarray:
    return (t >= a) & (t <= b)


def _steady(w: Walk, t: np.ndarray) -> np.ndarray:
    hs = w.steps.hs_s
    return (t > hs[2]) & (t < hs[-3])


# --- contact ---------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["walk", "turning"])
def test_feet_do_not_slip(name, request):
    w: Walk = request.getfixturevalue(name)
    t = np.arange(0.0, w.duration_s, DT)
    L = w.subject.shoe_length_m
    sole = w.sole_centres(t)
    heel = w.shoe_points(t, [-L / 2, 0.0, 0.0])[:, :, 0]
    toe = w.shoe_points(t, [L / 2, 0.0, 0.0])[:, :, 0]
    n_checked = 0
    for i, side in enumerate(SIDES):
        ev = w.events[side]
        for k in range(len(ev.flat_start_s)):
            m = _inside(t, ev.flat_start_s[k], ev.flat_end_s[k])
            assert np.abs(sole[m, i] - ev.sole_centre_W[k]).max() < 1e-4  # flat: still
            if np.isfinite(ev.hs_s[k]):
                m = _inside(t, ev.hs_s[k], ev.ff_s[k])
                assert np.ptp(heel[m, i], axis=0).max() < 1e-3  # heel rocker
                assert heel[m, i, 2].max() < 1e-6
            if np.isfinite(ev.ho_s[k]):
                m = _inside(t, ev.ho_s[k], ev.to_s[k])
                assert np.ptp(toe[m, i], axis=0).max() < 1e-3  # toe rocker
                assert toe[m, i, 2].max() < 1e-6
            n_checked += 1
    assert n_checked >= 8


@pytest.mark.parametrize("name", ["walk", "turning"])
def test_sole_above_floor_and_swing_clearance(name, request):
    w: Walk = request.getfixturevalue(name)
    t = np.arange(0.0, w.duration_s, DT)
    lowest = w.shoe_points(t, _sole_corners(w))[..., 2].min(axis=-1)  # (n, 2)
    assert lowest.min() >= -1e-3
    for i, side in enumerate(SIDES):
        ev = w.events[side]
        for k in range(len(ev.to_s) - 1):
            a, b = ev.to_s[k], ev.hs_s[k + 1]
            mid = _inside(t, a + 0.3 * (b - a), a + 0.7 * (b - a))
            assert lowest[mid, i].min() >= 0.01
            assert lowest[mid, i].min() <= 0.03  # a realistic (small) clearance


def test_heel_rises_before_toe_off(walk):
    L = walk.subject.shoe_length_m
    for i, side in enumerate(SIDES):
        ev = walk.events[side]
        for k in np.flatnonzero(np.isfinite(ev.to_s)):
            heel = walk.shoe_points([ev.to_s[k]], [-L / 2, 0.0, 0.0])[0, i, 0]
            assert heel[2] > 0.05
            assert ev.ho_s[k] < ev.to_s[k]


# --- kinematics ------------------------------------------------------------------------------
def test_forward_kinematics_reproduces_joints(walk, t):
    joints = walk.joints(t)
    fk = forward_kinematics(walk.skeleton, *walk.smpl_pose(t))
    assert np.abs(fk - joints).max() < 1e-6
    np.testing.assert_allclose(joints[:, 5:7], walk.ankles(t), atol=1e-9)
    for i in (0, 1):
        foot = walk.shoe_points(t, walk.foot_joints_in_shoe[i])[:, i, 0]
        np.testing.assert_allclose(joints[:, 7 + i], foot, atol=1e-9)


def test_bone_lengths_constant_and_legs_reachable(walk, t):
    J = walk.joints(t)
    parents = [0, 0, 1, 2, 3, 4, 5, 6]
    lengths = np.linalg.norm(J[:, 1:] - J[:, parents], axis=-1)
    assert np.ptp(lengths, axis=0).max() < 1e-9
    hip_ankle = np.linalg.norm(J[:, 5:7] - J[:, 1:3], axis=-1)
    assert hip_ankle.max() <= REACH_FRACTION * walk.subject.leg_length_m + 1e-9


def _knee_flexion(w: Walk, t: np.ndarray) -> np.ndarray:
    """Knee flexion [deg] (n, 2): the angle between thigh and shank."""
    J = w.joints(t)
    thigh, shank = J[:, 3:5] - J[:, 1:3], J[:, 5:7] - J[:, 3:5]
    cos = (
        np.sum(thigh * shank, -1) / np.linalg.norm(thigh, axis=-1) / np.linalg.norm(shank, axis=-1)
    )
    return np.degrees(np.arccos(np.clip(cos, -1, 1)))


def test_knee_flexion_range_and_direction(walk, t):
    J = walk.joints(t)
    R_WP, _ = walk.pelvis_pose(t)
    flexion = _knee_flexion(walk, t)
    assert flexion.min() >= 0.0 and flexion.max() <= 85.0
    assert flexion.max() >= 50.0  # the swing knee really bends
    # The knee lies in front of the hip–ankle line (along the pelvis forward axis).
    e = (J[:, 5:7] - J[:, 1:3]) / np.linalg.norm(J[:, 5:7] - J[:, 1:3], axis=-1, keepdims=True)
    rel = J[:, 3:5] - J[:, 1:3]
    off = rel - np.sum(rel * e, -1, keepdims=True) * e
    forward = np.sum(off * R_WP[:, None, :, 0], -1)
    assert np.all(forward > 0.0)


def test_standing_root_orientation_convention(walk):
    root, trans, aa = walk.smpl_pose([0.0])
    R_root = so3_exp(root[0])
    expected = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    np.testing.assert_allclose(R_root, expected, atol=1e-9)
    np.testing.assert_allclose(trans[0], walk.joints([0.0])[0, 0] - walk.skeleton.rest_joints[0])
    assert np.abs(aa[0, 6:]).max() == 0.0  # the foot joints carry no rotation


def test_body_state(walk):
    state = walk.body_state(walk.duration_s / 2)
    assert isinstance(state, BodyState)
    J = walk.joints([walk.duration_s / 2])[0]
    names = [(leg.side, leg.name) for leg in state.legs]
    assert names == [("left", "thigh"), ("left", "shank"), ("right", "thigh"), ("right", "shank")]
    np.testing.assert_allclose(state.legs[0].p_top_W, J[1])
    np.testing.assert_allclose(state.legs[3].p_bottom_W, J[6])
    assert [s.side for s in state.shoes] == ["left", "right"]
    assert state.shoes[0].length_m == walk.subject.shoe_length_m
    np.testing.assert_allclose(
        state.shoes[1].R_WfromShoe @ state.shoes[1].R_WfromShoe.T, np.eye(3), atol=1e-12
    )
    marker = walk.marker_points([walk.duration_s / 2])[0]
    sole = walk.sole_centres([walk.duration_s / 2])[0]
    up = np.stack([s.R_WfromShoe[:, 2] for s in state.shoes])
    height = np.sum((marker - sole) * up, axis=-1)
    np.testing.assert_allclose(height, walk.subject.shoe_height_m)  # on top of the shoe


# --- pelvis ----------------------------------------------------------------------------------
def test_pelvis_derivatives_match_finite_differences(turning):
    w = turning
    t = np.linspace(0.2, w.duration_s - 0.2, 300)
    h = 1e-4
    R, p, v, a, om = w.pelvis_kinematics(t)
    Rp, pp, vp, _, omp = w.pelvis_kinematics(t + h)
    Rm, pm, vm, _, omm = w.pelvis_kinematics(t - h)
    np.testing.assert_allclose((pp - pm) / (2 * h), v, atol=1e-6 * np.abs(v).max())
    np.testing.assert_allclose((vp - vm) / (2 * h), a, atol=1e-5 * np.abs(a).max())
    om_fd = so3_log(np.swapaxes(Rm, -1, -2) @ Rp) / (2 * h)  # body-frame rate
    np.testing.assert_allclose(om_fd, om, atol=1e-6 * np.abs(om).max())
    alpha = w.pelvis_angular_acceleration(t)
    np.testing.assert_allclose((omp - omm) / (2 * h), alpha, atol=1e-5 * np.abs(alpha).max())
    np.testing.assert_allclose(
        R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12
    )


def test_pelvis_is_smooth(walk, t):
    """C² pelvis: accelerations without jumps and of a realistic size (< 1 g)."""
    _, _, _, a, _ = walk.pelvis_kinematics(t)
    assert np.abs(a).max() < 9.81
    jerk = np.diff(a, axis=0) / DT
    assert np.abs(jerk).max() < 150.0


def test_stands_at_start_and_end_feet_still_pelvis_sways(walk, t):
    """Standing: the feet do not move at all; the pelvis sways by millimetres (postural sway)."""
    _, p, v, _, _ = walk.pelvis_kinematics(t)
    cfg = walk.config
    for m in (t <= cfg.stand_start_s, t >= walk.duration_s - cfg.stand_end_s):
        assert m.sum() * DT >= 1.0
        assert np.ptp(walk.joints(t[m])[:, 5:], axis=0).max() < 1e-9  # ankles and feet
        assert 0.5e-3 < np.ptp(p[m, :2], axis=0).max() < 0.03
        assert np.abs(v[m]).max() < 0.05
    first_move = min(np.nanmin(walk.events[s].ho_s) for s in SIDES)
    assert first_move > cfg.stand_start_s
    assert np.abs(walk.sole_centres([0.0])[0, :, 0]).max() < 0.01  # side by side at x ≈ 0
    end = walk.sole_centres([walk.duration_s])[0]
    assert abs(end[0, 0] - end[1, 0]) < 0.05  # together again at the end


def test_without_sway_standing_is_still():
    w = _walk(7, speed_mps=1.3, sway_ap_rms_m=0.0, sway_ml_rms_m=0.0)
    t = np.arange(0.0, w.config.stand_start_s, DT)
    _, _, v, _, om = w.pelvis_kinematics(t)
    assert np.abs(v).max() < 1e-6 and np.abs(om).max() < 1e-6


# --- realism (references.md, "Normal adult walking") -----------------------------------------
def test_temporal_spatial_parameters(walk):
    hs = walk.steps.hs_s
    cadence = 60.0 / np.mean(np.diff(hs)[2:-2])
    assert 100.0 <= cadence <= 125.0
    strides = np.concatenate([walk.events[s].stride_lengths_m[2:-2] for s in SIDES])
    assert 1.2 <= strides.mean() <= 1.6
    for side in SIDES:
        ev = walk.events[side]
        cycle = np.diff(ev.hs_s)[1:]
        stance = (ev.to_s[1:-1] - ev.hs_s[1:-1]) / cycle
        assert np.all((stance > 0.55) & (stance < 0.65))
        heel_off = (ev.ho_s[1:-1] - ev.hs_s[1:-1]) / cycle
        assert np.all((heel_off >= 0.29) & (heel_off <= 0.41))
    assert np.all(np.abs(walk.steps.width_m[:-1] - 0.10) < 0.05)


def test_pelvis_excursions_and_speed(walk, t):
    R, p, _, _, _ = walk.pelvis_kinematics(t)
    m = _steady(walk, t)
    hs = walk.steps.hs_s
    per_step = [np.ptp(p[(t >= hs[k]) & (t < hs[k + 1]), 2]) for k in range(2, len(hs) - 3)]
    assert min(per_step) >= 0.025 and max(per_step) <= 0.06  # textbook 4–5 cm
    assert 0.02 <= np.ptp(p[m, 1]) <= 0.06  # lateral sway (straight walk along x)
    yaw = np.degrees(np.arctan2(R[m, 1, 0], R[m, 0, 0]))
    assert 2.0 <= yaw.max() <= 6.0 and -6.0 <= yaw.min() <= -2.0
    speed = (p[m, 0][-1] - p[m, 0][0]) / (t[m][-1] - t[m][0])
    assert abs(speed - walk.config.speed_mps) < 0.1 * walk.config.speed_mps


def _knee_cycles(w: Walk, t: np.ndarray) -> dict[str, np.ndarray]:
    """Knee flexion [deg] at gait events of the steady strides of both legs.

    Per stride (heel strike to the next one of the same foot): at heel strike, the
    loading-response peak (first 25 % of the cycle), the mid/terminal-stance minimum (15–50 %),
    at toe off and the swing peak.
    """
    knee = _knee_flexion(w, t)
    out: dict[str, list[float]] = {k: [] for k in ("hs", "loading", "mid", "to", "swing")}
    for i, side in enumerate(SIDES):
        ev = w.events[side]
        for k in range(2, len(ev.hs_s) - 2):
            phase = (t - ev.hs_s[k]) / (ev.hs_s[k + 1] - ev.hs_s[k])
            cycle = (phase >= 0.0) & (phase < 1.0)
            out["hs"].append(knee[np.argmin(np.abs(phase)), i])
            out["loading"].append(knee[cycle & (phase < 0.25), i].max())
            out["mid"].append(knee[cycle & (phase > 0.15) & (phase < 0.5), i].min())
            out["to"].append(knee[np.argmin(np.abs(t - ev.to_s[k])), i])
            out["swing"].append(knee[cycle, i].max())
    assert len(out["hs"]) >= 6
    return {k: np.array(v) for k, v in out.items()}


def test_stance_knee_follows_textbook(walk, t):
    """Knee ≈ 0–5° at heel strike, 15–20° in loading response, ≈ 0–5° in mid/terminal stance,
    35–40° at toe off, 60–65° in swing (references.md), with some tolerance (toe off: below)."""
    c = _knee_cycles(walk, t)
    assert c["hs"].max() <= 8.0
    assert c["loading"].min() >= 10.0 and c["loading"].max() <= 25.0
    assert c["mid"].max() <= 8.0
    # textbook 35–40° at toe off: the rigid shoe pivots about its toe tip, not the ball of the
    # foot, so the heel-up pitch giving a textbook ankle lifts the ankle more (docs/simulator.md)
    assert c["to"].min() >= 30.0 and c["to"].max() <= 60.0
    assert c["swing"].min() >= 50.0 and c["swing"].max() <= 80.0
    # loading response is a real flexion wave, not a knee that stays bent
    assert np.all(c["loading"] - np.maximum(c["hs"], c["mid"]) >= 5.0)


def test_standing_knees_nearly_straight(walk):
    stand = _knee_flexion(walk, np.array([0.0, walk.duration_s]))
    assert stand.max() <= 6.0  # textbook: standing straight-legged


def test_turn_changes_heading(turning):
    R, _ = turning.pelvis_pose([0.0, turning.duration_s])
    yaw = np.degrees(np.arctan2(R[:, 1, 0], R[:, 0, 0]))
    assert abs(yaw[0]) < 1e-6 and abs(yaw[1] - 90.0) < 1.0


# --- determinism and config --------------------------------------------------------------------
def test_same_seed_same_walk_different_seed_different_walk():
    a, b, c = _walk(3), _walk(3), _walk(4)
    ts = np.linspace(0.0, min(a.duration_s, c.duration_s), 97)
    np.testing.assert_array_equal(a.joints(ts), b.joints(ts))
    np.testing.assert_array_equal(a.pelvis_kinematics(ts)[3], b.pelvis_kinematics(ts)[3])
    assert a.duration_s == b.duration_s
    assert not np.allclose(a.joints(ts), c.joints(ts))


def test_config_validation():
    with pytest.raises(ValueError, match="speed_mps"):
        GaitConfig(speed_mps=3.0)
    with pytest.raises(ValueError, match="stand_start_s"):
        GaitConfig(stand_start_s=0.5)
    with pytest.raises(ValueError, match="first_foot"):
        GaitConfig(first_foot="both")


def test_subject_sampling():
    rng = np.random.default_rng(0)
    for _ in range(20):
        s = sample_subject(rng)
        assert HEIGHT_RANGE_M[0] <= s.height_m <= HEIGHT_RANGE_M[1]
        assert 0.02 <= s.shoe_length_m - s.foot_length_m <= 0.03
        assert abs(s.thigh_m / s.height_m - 0.245) < 0.02
        skel = s.skeleton()
        assert skel.thigh_lengths[0] == pytest.approx(s.thigh_m)
        assert skel.shank_lengths[1] == pytest.approx(s.shank_m)
        assert all(0.0 <= c <= 1.0 for c in (*s.trouser_rgb, *s.shoe_rgb, *s.sole_rgb))
    assert sample_subject(rng, height_m=1.62).height_m == 1.62


# --- speed laws, per-subject style, standing (benchmarks/realism_gait.py) ----------------------
def _gait_values(speed: float, seeds=(0, 1, 2), **cfg) -> list[dict[str, float]]:
    from realism_gait import measure_walk

    out = []
    for seed in seeds:
        rng = np.random.default_rng([seed, 99])
        subject = sample_subject(rng)
        gait = GaitConfig(speed_mps=speed, walk_length_m=8.0, stand_start_s=3.0, **cfg)
        out.append(measure_walk(generate_walk(subject, gait, rng)))
    return out


@pytest.fixture(scope="module")
def by_speed() -> dict[float, list[dict[str, float]]]:
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parents[1] / "benchmarks"))
    return {v: _gait_values(v) for v in (0.9, 1.2, 1.6)}


def _mean(rows: list[dict[str, float]], key: str) -> float:
    return float(np.mean([r[key] for r in rows]))


def test_gait_follows_speed_within_textbook_bands(by_speed):
    """Stance and double support fall with speed (≈ 62 → 58 %), cadence and stride grow,
    pelvic rotation / obliquity / vertical excursion grow (Hebenstreit 2015, Orendurff 2004)."""
    slow, normal, fast = (by_speed[v] for v in (0.9, 1.2, 1.6))
    assert 61.5 <= _mean(slow, "stance") <= 64.5 and 57.5 <= _mean(fast, "stance") <= 60.5
    assert _mean(slow, "double") > _mean(normal, "double") > _mean(fast, "double")
    assert 95.0 <= _mean(normal, "cadence") <= 125.0
    assert _mean(slow, "cadence") < _mean(normal, "cadence") < _mean(fast, "cadence")
    assert 3.5 <= _mean(normal, "vert") <= 5.5  # textbook 4–5 cm at 1.2 m/s
    assert _mean(slow, "vert") < _mean(normal, "vert") < _mean(fast, "vert")
    for key in ("rot", "obl"):
        assert _mean(slow, key) < _mean(normal, key) < _mean(fast, key)
    assert 3.0 <= _mean(normal, "rot") <= 6.0 and 2.5 <= _mean(normal, "obl") <= 5.0
    assert _mean(slow, "lat") > _mean(fast, "lat")  # side-to-side excursion shrinks


def test_ankle_plantarflexes_after_toe_off_and_is_neutral_in_late_swing(by_speed):
    """Textbook: −15…−20° just after toe off, ≈ 0° in late swing (was +14° and +31…36°)."""
    for v in (1.2, 1.6):
        rows = by_speed[v]
        assert -22.0 <= _mean(rows, "ankle_pf") <= -11.0
        assert -5.0 <= _mean(rows, "ankle_to") <= 5.0
        assert abs(_mean(rows, "ankle_ls")) <= 6.0


def test_subjects_walk_differently_and_variability_acts(by_speed):
    rows = by_speed[1.2]
    for key in ("stance", "cadence", "rot", "obl"):
        assert np.std([r[key] for r in rows]) > 0.0
    same = _gait_values(1.2, variability=0.0, step_length_cv=0.0, step_time_cv=0.0)
    for key in ("stance", "rot"):
        assert np.std([r[key] for r in same]) < 0.05 * np.std([r[key] for r in rows])


def test_standing_sway_amplitude_and_frequency(by_speed):
    """Pelvis sway: RMS a few mm, AP > ML, mean frequency 0.1–1 Hz (Prieto 1996)."""
    rows = [r for v in by_speed.values() for r in v]
    ap, ml = _mean(rows, "sway_ap"), _mean(rows, "sway_ml")
    assert 1.5 <= ap <= 5.0 and 0.8 <= ml <= 3.5 and ap > ml
    assert 0.1 <= _mean(rows, "sway_f") <= 1.0
    still = _gait_values(1.2, seeds=(0,), sway_ap_rms_m=0.0, sway_ml_rms_m=0.0)[0]
    assert still["sway_ap"] < 1e-6 and still["sway_ml"] < 1e-6


@pytest.mark.parametrize("seed", range(6))
def test_standing_shoes_do_not_overlap(seed):
    w = _walk(seed, height=None, sway_ap_rms_m=0.0)
    for t0 in (0.0, w.duration_s):
        sole = w.sole_centres([t0])[0]
        gap = abs(sole[0, 1] - sole[1, 1]) - w.subject.shoe_width_m
        assert gap >= 0.029
    wide = _walk(seed, height=None, stand_width_m=0.3)
    assert abs(np.diff(wide.sole_centres([0.0])[0, :, 1])[0]) == pytest.approx(0.3, abs=1e-6)


def test_new_keys_validated():
    for key, bad in (
        ("variability", 3.0),
        ("stand_width_m", 0.01),
        ("sway_ap_rms_m", -0.001),
        ("sway_ml_rms_m", 0.5),
        ("toe_off_ankle_deg", 40.0),
        ("push_off_ankle_deg", 5.0),
        ("swing_ankle_deg", -40.0),
    ):
        with pytest.raises(ValueError, match=key):
            GaitConfig(**{key: bad})
