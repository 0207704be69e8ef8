"""Stance-foot candidates (gaitnet.vio.feet, thesis (3.22)–(3.26)) and the stance tracker."""

import logging
from dataclasses import replace

import numpy as np
import pytest

from gaitnet.geometry.floor_plane import FloorPlane
from gaitnet.geometry.rotation import so3_exp
from gaitnet.vio.feet import FootParams, detect_foot_candidates
from gaitnet.vio.stance_tracker import StanceParams, StanceTracker

K = np.array([[386.0, 0.0, 319.5], [0.0, 386.0, 239.5], [0.0, 0.0, 1.0]])
SHAPE = (480, 640)


def _pose(pitch_deg=65.0, height=1.0):
    R0 = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    T = np.eye(4)
    T[:3, :3] = so3_exp(np.array([0.0, np.radians(pitch_deg), 0.0])) @ R0
    T[2, 3] = height
    return T


def _render(T, boxes):
    """Depth image of the floor z = 0 and axis-aligned boxes (x0, x1, y0, y1, z0, z1) [m]
    (ray casting; nearest hit)."""
    H, W = SHAPE
    v, u = np.mgrid[0:H, 0:W]
    d_C = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones((H, W))], -1)
    d_W = d_C @ T[:3, :3].T
    o = T[:3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        s_best = np.where(d_W[..., 2] < 0, -o[2] / d_W[..., 2], np.inf)
        for x0, x1, y0, y1, z0, z1 in boxes:
            lo = (np.array([x0, y0, z0]) - o) / d_W
            hi = (np.array([x1, y1, z1]) - o) / d_W
            t_near = np.nanmax(np.minimum(lo, hi), axis=-1)
            t_far = np.nanmin(np.maximum(lo, hi), axis=-1)
            hit = (t_near <= t_far) & (t_near > 0)
            s_best = np.where(hit & (t_near < s_best), t_near, s_best)
    return np.where(np.isfinite(s_best), s_best, 0.0).astype(np.float32)  # z of d_C is 1


def _plane(T):
    return FloorPlane(n_C=T[:3, :3].T @ np.array([0.0, 0.0, 1.0]), h=float(T[2, 3]))


def _shoe(cx, cy, length=0.26, width=0.10, height=0.07):
    return (cx - length / 2, cx + length / 2, cy - width / 2, cy + width / 2, 0.0, height)


def _to_world(T, p_C):
    return T[:3, :3] @ p_C + T[:3, 3]


def test_two_shoes_give_two_candidates_on_the_floor():
    T = _pose()
    depth = _render(T, [_shoe(0.9, 0.09), _shoe(0.6, -0.09), (1.2, 1.22, 0.3, 0.32, 0.0, 0.05)])
    params = FootParams(shoe_length_m=0.26, toe_margin_m=0.0)
    cands = detect_foot_candidates(depth, K, _plane(T), params)
    assert len(cands) == 2
    pts = sorted((_to_world(T, c.p_FinC) for c in cands), key=lambda p: p[0])
    for p, true in zip(pts, ([0.6, -0.09], [0.9, 0.09]), strict=True):
        assert p[2] == pytest.approx(0.0, abs=1e-9)  # ON the floor plane
        # toe = 98th percentile of the visible top (2 % in from the tip): within 1 cm
        assert np.linalg.norm(p[:2] - true) < 0.01
    for c in cands:
        assert 0.015 < c.area_m2 < 0.04  # the top of a 0.26 × 0.10 box, plus its sides
        assert 0.2 < c.length_m < 0.33 and c.width_m < 0.14
        assert abs(_to_world(T, c.axis_C)[0] - T[0, 3]) > 0.9  # main axis along the walk (+x)
        assert not c.at_border
        (u, v), axes, _ = c.ellipse
        assert 0 <= u < 640 and 0 <= v < 480 and max(axes) > 20


def test_centroid_and_ray_points_are_on_the_floor_too():
    T = _pose()
    depth = _render(T, [_shoe(0.8, 0.0)])
    for method in ("centroid", "ray"):
        (c,) = detect_foot_candidates(depth, K, _plane(T), FootParams(point_method=method))
        p = _to_world(T, c.p_FinC)
        assert p[2] == pytest.approx(0.0, abs=1e-9)
        assert np.linalg.norm(p[:2] - [0.8, 0.0]) < 0.08
    with pytest.raises(ValueError, match="point_method"):
        detect_foot_candidates(depth, K, _plane(T), FootParams(point_method="x"))


def test_size_and_height_filters():
    T = _pose()
    plane = _plane(T)
    assert detect_foot_candidates(_render(T, []), K, plane) == []
    # a 1 m × 0.5 m low platform is too large, a 3 cm cube too small
    big = (0.6, 1.6, -0.25, 0.25, 0.0, 0.05)
    small = (0.8, 0.83, 0.3, 0.33, 0.0, 0.03)
    assert detect_foot_candidates(_render(T, [big, small]), K, plane) == []
    # a shoe floating 15 cm up (a swing foot) is above the band
    floating = (0.75, 1.01, -0.05, 0.05, 0.15, 0.22)
    assert detect_foot_candidates(_render(T, [floating]), K, plane) == []
    # at most two, largest first
    depth = _render(T, [_shoe(0.6, -0.2), _shoe(0.9, 0.0, length=0.3), _shoe(1.1, 0.25)])
    cands = detect_foot_candidates(depth, K, plane)
    assert len(cands) == 2 and cands[0].n_pixels >= cands[1].n_pixels


def test_a_toe_seen_inside_the_image_counts_a_piece_cut_by_its_border_does_not():
    """``min_area_inside_m2`` (a toe under the leg) inside the image, ``min_area_m2`` at its
    border: the same 0.0027 / 0.0033 m² of foot pixels count only inside."""
    T = _pose()
    plane = _plane(T)
    toe = _render(T, [(0.8, 0.84, 0.0, 0.04, 0.0, 0.05)])  # 0.0027 m² as seen
    (c,) = detect_foot_candidates(toe, K, plane)
    assert not c.at_border and 0.002 < c.area_m2 < 0.004
    assert detect_foot_candidates(toe, K, plane, FootParams(min_area_inside_m2=0.004)) == []
    cut = _render(T, [(1.44, 1.64, 0.0, 0.05, 0.0, 0.05)])  # 0.0033 m² left in the image
    assert detect_foot_candidates(cut, K, plane) == []
    (c,) = detect_foot_candidates(cut, K, plane, FootParams(min_area_m2=0.003))
    assert c.at_border and 0.003 < c.area_m2 < 0.004


def test_weak_candidates_make_a_stance_later_and_never_move_a_strong_ones_start():
    p, h, cam = np.array([1.0, 0.1]), np.array([1.0, 0.0]), np.array([0.6, 0.0])

    def run(weak: list[bool], params: StanceParams | None = None):
        trk = StanceTracker(params)
        out = [
            trk.update(k / 30, [p], heading_W=h, p_CinW=cam, weak=[w])[0]
            for k, w in enumerate(weak)
        ]
        return out, trk.finish()

    # a toe alone: a stance once seen for weak_confirm_s (0.1 s: the 4th frame at 30 Hz)
    out, stances = run([True] * 6)
    assert [o is not None for o in out] == [False, False, False, True, True, True]
    assert len(stances) == 1 and stances[0].t_first == 0.0
    assert not stances[0].strong  # weak pieces only: its sightings do not count (run_vio)
    assert run([True, False, True, True, True, True])[1][0].strong
    out, _ = run([True] * 6, StanceParams(weak_confirm_s=0.15))
    assert [o is not None for o in out] == [False] * 5 + [True]
    # a toe first, then the whole foot: confirm_s (0.06 s) counts from the whole foot
    out, _ = run([True, False, False, False, True, True])
    assert [o is not None for o in out] == [False, False, False, True, True, True]
    # the whole foot first, then its toe: confirmed at the 3rd frame as without weak pieces
    out, _ = run([False, True, True, True])
    assert [o is not None for o in out] == [False, False, True, True]


def test_foot_at_the_image_border_is_flagged():
    T = _pose(pitch_deg=65.0)
    # the top image border sees the floor at about x = 1.54 m: a shoe across it
    depth = _render(T, [_shoe(1.5, 0.0)])
    cands = detect_foot_candidates(depth, K, _plane(T))
    assert len(cands) == 1 and cands[0].at_border


def _holes(T, depth, keep):
    """``depth`` with the pixels that see a box (not the floor) set invalid (0) where
    ``keep(x_W, y_W)`` is False: the clustered holes of a black shoe (docs/simulator.md)."""
    H, W = SHAPE
    v, u = np.mgrid[0:H, 0:W]
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones((H, W))], -1)
    p_W = (rays * depth[..., None]) @ T[:3, :3].T + T[:3, 3]
    floor = _render(T, [])
    on_box = (depth > 0) & (depth < floor - 1e-4)
    out = depth.copy()
    out[on_box & ~keep(p_W[..., 0], p_W[..., 1])] = 0.0
    return out


def test_a_shoe_cut_by_a_depth_hole_is_one_candidate_at_its_centre():
    # a black shoe whose depth has a 3 cm band of holes across it, 7 cm behind the toe: the toe
    # piece is a separate component; alone, the larger piece puts the foot point ~7 cm back
    # (a "toe" that is not the toe) and the toe piece becomes a second candidate.
    T = _pose(height=1.1)
    true = np.array([0.9, -0.08])
    toe = true[0] + 0.13
    depth = _holes(T, _render(T, [_shoe(*true)]), lambda x, y: np.abs(x - (toe - 0.055)) > 0.015)
    params = FootParams(shoe_length_m=0.26, toe_margin_m=0.0)
    (cand,) = detect_foot_candidates(depth, K, _plane(T), params)
    assert np.linalg.norm(_to_world(T, cand.p_FinC)[:2] - true) < 0.01
    cut = detect_foot_candidates(depth, K, _plane(T), replace(params, hole_bridge_m=0.0))
    assert len(cut) == 2  # without bridging: the back piece first, ~7 cm short
    assert _to_world(T, cut[0].p_FinC)[0] < true[0] - 0.05


def _assert_right_and_left(cands, T, right, left, tol: float = 0.01) -> None:
    """Two candidates whose world foot points are ``right`` and ``left`` (x, y) within ``tol``."""
    assert len(cands) == 2
    pts = sorted((_to_world(T, c.p_FinC)[:2] for c in cands), key=lambda p: p[1])
    for p, true in zip(pts, (right, left), strict=True):
        assert np.linalg.norm(p - true) < tol


def test_bridging_does_not_join_two_feet():
    # two standing shoes 5 cm apart with the floor between them invalid (a shadow): bridged,
    # the pair is too wide for one foot and each shoe stays a candidate
    T = _pose(height=1.1)
    left, right = np.array([0.8, 0.075]), np.array([0.8, -0.075])
    depth = _render(T, [_shoe(*left), _shoe(*right)])
    floor = _render(T, [])
    H, W = SHAPE
    v, u = np.mgrid[0:H, 0:W]
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones((H, W))], -1)
    p_W = (rays * floor[..., None]) @ T[:3, :3].T + T[:3, 3]
    gap = (np.abs(p_W[..., 1]) < 0.03) & (np.abs(p_W[..., 0] - 0.8) < 0.1) & (depth == floor)
    depth[gap] = 0.0
    params = FootParams(shoe_length_m=0.26, toe_margin_m=0.0)
    _assert_right_and_left(detect_foot_candidates(depth, K, _plane(T), params), T, right, left)
    # without the width limit and the split of a pair the bridged pair is one "foot" between
    # the two
    unlimited = replace(params, max_width_m=1.0, split_width_m=0.0)
    (joined,) = detect_foot_candidates(depth, K, _plane(T), unlimited)
    assert abs(_to_world(T, joined.p_FinC)[1]) < 0.03


@pytest.mark.parametrize("toe_out", [0.0, 0.06])
def test_shoes_touching_side_by_side_are_two_feet(toe_out: float) -> None:
    """Two shoes standing side by side that touch (heels together; ``toe_out`` moves the right
    one back: a V seen in boxes) are one component of foot pixels, too wide for one foot: it
    is split across the walk into two candidates at the shoes; without the split there is
    none."""
    T = _pose(height=1.1)
    left, right = np.array([0.8, 0.05]), np.array([0.8 - toe_out, -0.05])
    depth = _render(T, [_shoe(*left), _shoe(*right)])
    params = FootParams(shoe_length_m=0.26, toe_margin_m=0.0)
    cands = detect_foot_candidates(depth, K, _plane(T), params)
    _assert_right_and_left(cands, T, right, left, tol=0.015)
    assert detect_foot_candidates(depth, K, _plane(T), replace(params, split_width_m=0.0)) == []


def test_a_shoe_across_the_walk_is_not_split() -> None:
    """A shoe turned 90° (a turn on the spot) is as wide across the walk as two feet, but its
    halves lie across the walk: one candidate."""
    T = _pose(height=1.1)
    across = (0.75, 0.85, -0.13, 0.13, 0.0, 0.07)  # 0.26 long along y
    (cand,) = detect_foot_candidates(_render(T, [across]), K, _plane(T), FootParams())
    assert abs(_to_world(T, cand.centroid_C)[1]) < 0.02


def test_otsu_split_separates_two_modes() -> None:
    from gaitnet.geometry.two_groups import otsu_split

    rng = np.random.default_rng(0)
    values = np.concatenate([rng.normal(-0.05, 0.01, 300), rng.normal(0.06, 0.01, 200)])
    upper = otsu_split(values, *np.percentile(values, [5, 95]))
    assert upper.sum() == 200 and upper[300:].all()
    same = otsu_split(values, -1.0, 1.0)  # coarser codes, the same two groups
    np.testing.assert_array_equal(same, upper)


# ------------------------------------------------------------------ stance tracker

FPS = 30.0


def _walk(n_steps=8, step=0.6, width=0.09, period=0.5, flat=0.35, visible=("left", "right")):
    """Scripted candidates of a walk: stance k of alternating feet (right first) is flat from
    k·period for ``flat`` s; a swing foot crosses the band in two frames between. Returns
    per-frame (t, [xy...], heading, camera xy) and the true stances (side, xy, t0, t1)."""
    truth = []
    for k in range(n_steps):
        side = "right" if k % 2 == 0 else "left"
        xy = np.array([0.3 + k * step, -width if side == "right" else width])
        truth.append((side, xy, k * period, k * period + flat))
    rng = np.random.default_rng(7)
    frames = []
    t_end = n_steps * period + 0.3
    for i in range(int(t_end * FPS)):
        t = i / FPS
        cands = [xy + rng.normal(0, 0.002, 2) for side, xy, t0, t1 in truth
                 if t0 <= t <= t1 and side in visible]  # fmt: skip
        phase = (t % period) / period
        if 0.8 < phase < 0.9:  # a swing foot passing low, moving fast
            cands.append(np.array([0.3 + t / period * step + 0.3, 0.0]))
        cam = np.array([0.3 + t / period * step - 0.4, 0.01 * np.sin(2 * np.pi * t)])
        frames.append((t, cands[:2], np.array([1.0, 0.0]), cam))
    return frames, truth


def _run(frames, params=None):
    trk = StanceTracker(params)
    news = 0
    for t, cands, heading, cam in frames:
        out = trk.update(t, cands, heading_W=heading, p_CinW=cam)
        assert len(out) == len(cands)
        news += sum(o is not None and o.is_new for o in out)
    stances = trk.finish()
    assert news == len(stances)
    return stances


def _match(stances, truth):
    ok = 0
    for st in stances:
        d = [np.linalg.norm(st.xy - xy) for _, xy, _, _ in truth]
        side, xy, t0, t1 = truth[int(np.argmin(d))]
        assert min(d) < 0.01
        ok += st.side == side
    return ok


def test_walk_stances_and_sides():
    frames, truth = _walk()
    stances = _run(frames)
    assert len(stances) == len(truth)
    assert _match(stances, truth) == len(truth)
    ids = [s.id for s in stances]
    assert len(set(ids)) == len(ids)
    for st, (_, _, t0, t1) in zip(sorted(stances, key=lambda s: s.t_first), truth, strict=True):
        assert st.t_first == pytest.approx(t0, abs=0.04)
        assert st.t_last == pytest.approx(t1, abs=0.04)  # closed when the foot leaves


def test_one_foot_visible():
    frames, truth = _walk(visible=("left",))
    stances = _run(frames)
    left = [t for t in truth if t[0] == "left"]
    assert len(stances) == len(left)
    assert _match(stances, left) == len(left)


def test_double_support_and_standing():
    # both feet down for 1 s side by side, then a step with overlapping stances
    frames = []
    L, R = np.array([0.0, 0.1]), np.array([0.0, -0.1])
    R2 = np.array([0.6, -0.1])
    for i in range(60):
        t = i / FPS
        cands = [L, R] if t < 1.2 else [L, R2]
        if 1.0 < t < 1.2:
            cands = [L]  # right foot swinging (out of the band)
        frames.append((t, cands, np.array([1.0, 0.0]), np.array([0.3, 0.0])))
    stances = _run(frames)
    sides = {tuple(np.round(s.xy, 2)): s.side for s in stances}
    assert sides == {(0.0, 0.1): "left", (0.0, -0.1): "right", (0.6, -0.1): "right"}


def test_foot_entering_the_image_is_one_stance():
    # the first detections of a foot coming into view are biased by 2 cm, then settle
    frames = []
    true = np.array([1.0, -0.08])
    for i in range(15):
        bias = np.array([0.02, 0.0]) * max(0, 3 - i) / 3
        frames.append((i / FPS, [true + bias], np.array([1.0, 0.0]), np.array([0.6, 0.0])))
    stances = _run(frames)
    assert len(stances) == 1 and stances[0].side == "right"
    assert np.linalg.norm(stances[0].xy - true) < 0.01


def test_closing_and_reopening():
    p = np.array([1.0, 0.08])
    params = StanceParams(max_gap_s=0.1, reopen_s=0.5)
    seen = [i for i in range(10)] + [i for i in range(15, 25)] + [i for i in range(50, 60)]
    frames = [(i / FPS, [p], np.array([1.0, 0.0]), np.array([0.6, 0.0])) for i in seen]
    stances = _run(frames, params)
    # hidden 0.17 s (> max_gap, < reopen): same stance; hidden 0.83 s: a new stance
    assert len(stances) == 2
    assert stances[0].n_obs == 20 and stances[1].n_obs == 10


def test_clutter_far_to_the_side_is_ignored():
    p = np.array([1.0, 0.9])
    frames = [(i / FPS, [p], np.array([1.0, 0.0]), np.array([0.6, 0.0])) for i in range(20)]
    trk = StanceTracker()
    for t, c, h, cam in frames:
        assert trk.update(t, c, heading_W=h, p_CinW=cam) == [None]
    assert trk.finish() == []


def test_sides_from_the_final_landmark_positions_undo_the_pose_drift():
    # the pose that moves the observations to the world drifts sideways with the gait (a
    # lateral error of ±15 cm, period 1 s): stances split where it moves a foot's point by
    # more than assoc_radius_m, and consecutive lateral offsets, which decide the sides,
    # are wrong. Labelled at their true positions (the final landmark estimates, where the
    # drift has been corrected), every stance gets its side.
    frames, truth = _walk(width=0.06)
    trk = StanceTracker()
    for t, cands, heading, cam in frames:
        drift = np.array([0.0, 0.15 * np.sin(2 * np.pi * t)])
        trk.update(t, [p + drift for p in cands], heading_W=heading, p_CinW=cam + drift)
    stances = trk.finish()
    true = [truth[int(np.argmin([abs(s.t_first - t0) for _, _, t0, _ in truth]))] for s in stances]
    assert len(stances) > len(truth)  # split stances
    online = sum(s.side == tr[0] for s, tr in zip(stances, true, strict=True))
    assert online < len(stances) / 2
    sides = trk.sides_at({s.id: tr[1] for s, tr in zip(stances, true, strict=True)})
    assert sides == {s.id: tr[0] for s, tr in zip(stances, true, strict=True)}
    # stances left out take no part
    some = {s.id: tr[1] for s, tr in zip(stances[::2], true[::2], strict=True)}
    assert trk.sides_at(some) == {
        s.id: tr[0] for s, tr in zip(stances[::2], true[::2], strict=True)
    }
    assert trk.sides_at({}) == {}


def test_lateral_foot_point_from_the_shoe_top_is_not_pulled_towards_the_camera():
    """A shoe whose upper is narrower than its sole, 25 cm to the side of the camera: the
    camera sees the near sole edge and the upper hides the far one, so the middle of all its
    points lies towards the camera; the middle of its top (``top_height_fraction``) is on the
    shoe's centre line (known answer: y = 0.25)."""
    T = _pose()
    x, y = 0.8, 0.25
    sole = (x - 0.13, x + 0.13, y - 0.045, y + 0.045, 0.0, 0.03)  # 1 cm wider each side
    upper = (x - 0.11, x + 0.11, y - 0.035, y + 0.035, 0.0, 0.08)  # hides the far 1 cm
    depth = _render(T, [sole, upper])
    lateral = {}
    for fraction in (0.0, 0.75):
        params = FootParams(shoe_length_m=0.26, toe_margin_m=0.0, top_height_fraction=fraction)
        (c,) = detect_foot_candidates(depth, K, _plane(T), params)
        lateral[fraction] = _to_world(T, c.p_FinC)[1]
    assert abs(lateral[0.75] - y) < 0.002
    assert y - lateral[0.0] > 0.003  # pulled towards the camera (y = 0) by the near sole edge
    with pytest.raises(ValueError, match="top_height_fraction"):
        detect_foot_candidates(depth, K, _plane(T), FootParams(top_height_fraction=1.0))


def _split_last_stance(
    params: StanceParams | None = None, twice: bool = False
) -> tuple[StanceTracker, list, dict[int, np.ndarray]]:
    """A walk whose last right stance is reported twice: the pose jumps by 5 cm while the foot
    rests (more than ``assoc_radius_m``), and the camera stands 0.2 m to the right of the
    body's line when the second track is confirmed (the unary term says "left"); with
    ``twice``, instead, the foot is found twice (two candidates 3 mm apart) from then on, so
    the two stances are down at once. Returns the finished tracker, its stances and their true
    floor points."""
    heading = np.array([1.0, 0.0])
    steps = [  # (floor point, first, last time)
        (np.array([0.0, 0.08]), 0.0, 0.3),
        (np.array([0.35, -0.08]), 0.5, 0.8),
        (np.array([0.7, 0.08]), 1.0, 1.3),
        (np.array([1.05, -0.08]), 1.5, 2.5),
    ]
    trk = StanceTracker(params)
    for i in range(int(2.5 * FPS) + 1):
        t = i / FPS
        jump = np.array([0.05, 0.0]) if t >= 1.9 and not twice else np.zeros(2)
        cands = [p + jump for p, t0, t1 in steps if t0 <= t <= t1]
        if twice and t >= 1.9:
            cands.append(steps[-1][0] + [0.003, 0.0])
        cam = np.array([t * 0.5, -0.2 if t >= 1.9 else 0.0])
        trk.update(t, cands, heading_W=heading, p_CinW=cam)
    stances = trk.finish()
    truth = {
        s.id: min((p for p, _, _ in steps), key=lambda p: np.linalg.norm(s.xy - p)) for s in stances
    }
    return trk, stances, truth


@pytest.mark.parametrize("twice", [False, True])
def test_a_stance_reported_again_at_the_same_place_keeps_its_side(twice: bool) -> None:
    trk, stances, truth = _split_last_stance(twice=twice)
    assert len(stances) == 5  # the last one split in two
    last_two = sorted(stances, key=lambda s: s.t_first)[-2:]
    assert np.allclose(truth[last_two[0].id], truth[last_two[1].id])
    sides = trk.sides_at(truth)
    assert [sides[s.id] for s in sorted(stances, key=lambda s: s.t_first)] == [
        "left", "right", "left", "right", "right"
    ]  # fmt: skip
    # without the rule the camera's offset labels the second report "left"
    off, stances_off, truth_off = _split_last_stance(StanceParams(same_foot_m=0.0), twice)
    assert off.sides_at(truth_off)[max(stances_off, key=lambda s: s.t_first).id] == "left"


def test_a_stance_beside_a_resting_foot_is_not_that_foot() -> None:
    """The same-foot rule needs the earlier stance to have ended: a short stance found between
    the feet while the right foot rests (6.7 cm from it), then the left foot resting 5.4 cm
    from that one 0.1 s after it: the short one is the left foot (it overlaps the right one's
    rest), and so is the last."""
    heading = np.array([1.0, 0.0])
    R, S, L = np.array([1.0, -0.06]), np.array([1.03, 0.0]), np.array([1.05, 0.05])
    steps = [(R, 0.6, 3.0), (S, 1.0, 1.1), (L, 1.2, 3.0)]
    trk = StanceTracker()
    for i in range(int(3.0 * FPS) + 1):
        t = i / FPS
        cands = [p for p, t0, t1 in steps if t0 <= t <= t1]
        trk.update(t, cands, heading_W=heading, p_CinW=np.array([1.0, 0.0]))
    stances = sorted(trk.finish(), key=lambda s: s.t_first)
    assert len(stances) == 3
    sides = trk.sides_at({s.id: p for s, (p, _, _) in zip(stances, steps, strict=True)})
    assert [sides[s.id] for s in stances] == ["right", "left", "left"]


def _drifting_walk(
    drift_per_m: float = 0.0,
    camera_left_m: float = 0.0,
    sway_m: float = 0.0,
    missed: tuple[int, ...] = (),
    lateral: dict[int, float] | None = None,
) -> tuple[list, list]:
    """Scripted frames of a walk along a line drifting ``drift_per_m`` sideways per metre
    while the heading (the camera's optical axis) stays +x, as CMU walking_01 does (12 cm over
    3 m). Stance k (right first) lies 0.09 m either side of the line (``lateral`` overrides
    the offset of some, in metres to the left); the camera is ``camera_left_m`` to the left of
    the line (a mount off the belly's middle) and sways ``sway_m`` towards the stance foot;
    the stances in ``missed`` are never seen. Returns the frames and (side, xy) per stance."""
    step, period, flat = 0.6, 0.55, 0.3
    lateral = lateral or {}
    truth = []
    for k in range(8):
        side = "right" if k % 2 == 0 else "left"
        x = 0.3 + k * step
        y = drift_per_m * x + lateral.get(k, -0.09 if side == "right" else 0.09)
        truth.append((side, np.array([x, y]), k * period, k * period + flat))
    frames = []
    for i in range(int((8 * period + 0.3) * FPS)):
        t = i / FPS
        k = int(t / period)
        towards = (1.0 if k % 2 else -1.0) * np.sin(np.pi * (t % period) / period)
        x_cam = 0.3 + t / period * step - 0.4
        cam = np.array([x_cam, drift_per_m * x_cam + camera_left_m + sway_m * towards])
        cands = [xy for j, (_, xy, t0, t1) in enumerate(truth) if t0 <= t <= t1 and j not in missed]
        frames.append((t, cands, np.array([1.0, 0.0]), cam))
    return frames, [(side, xy) for side, xy, _, _ in truth]


def _sides(frames: list, truth: list, params: StanceParams | None = None) -> list[str]:
    """The final sides of the stances of ``frames``, in the order of ``truth`` ("-": not
    found)."""
    trk = StanceTracker(params)
    for t, cands, heading, cam in frames:
        trk.update(t, cands, heading_W=heading, p_CinW=cam)
    stances = trk.finish()
    sides = trk.sides_at({s.id: s.xy for s in stances})
    found = {int(np.argmin([np.linalg.norm(s.xy - xy) for _, xy in truth])): s for s in stances}
    return [sides[found[k].id] if k in found else "-" for k in range(len(truth))]


def test_a_missed_stance_on_a_drifting_walk_keeps_the_sides() -> None:
    """Stance 3, or 4, missed on a walk drifting 4 cm per metre either way: the stances either
    side of the gap are a stride apart, 2.5 cm apart sideways along the heading, and keep
    their sides."""
    frames, truth = _drifting_walk(drift_per_m=0.04, missed=(3,))
    expected = [side for side, _ in truth]
    expected[3] = "-"
    assert _sides(frames, truth) == expected
    frames, truth = _drifting_walk(drift_per_m=-0.04, missed=(4,))
    expected = [side for side, _ in truth]
    expected[4] = "-"
    assert _sides(frames, truth) == expected


def test_a_camera_off_the_body_middle_and_its_sway_keep_the_sides() -> None:
    """The camera 12 cm to the left of the line between the feet (more than the feet's 9 cm):
    its offset ``b`` is estimated from both sides' stances. Its sway of 6 cm towards the
    stance foot averages out over ``line_window_s`` (known answer: each stance 9 cm from the
    line, within 1.5 cm); with a window of 0 the line at each stance is the camera's mean
    position over the stance alone, 4 cm towards that foot (the sway's mean over the first
    0.3 s of its 0.55 s half-period: 6 cm × 0.67)."""
    frames, truth = _drifting_walk(camera_left_m=0.12)
    assert _sides(frames, truth) == [side for side, _ in truth]
    frames, truth = _drifting_walk(sway_m=0.06, missed=(3,))
    expected = [side for side, _ in truth]
    expected[3] = "-"
    assert _sides(frames, truth) == expected
    for window, offset in ((0.6, 0.09), (0.0, 0.09 - 0.06 * 0.67)):
        trk = StanceTracker(StanceParams(line_window_s=window))
        for t, cands, heading, cam in frames:
            trk.update(t, cands, heading_W=heading, p_CinW=cam)
        stances = trk.finish()
        path = trk._recorded_path()
        d = trk._line_offsets(stances, path[:, 0], path[:, 1:])
        inner = [s for s in stances if 0.5 < s.t_first < 3.5]  # a window either side
        assert len(inner) >= 4
        for st in inner:
            sign = 1.0 if st.xy[1] < 0 else -1.0  # right of the line: positive
            assert sign * d[st.id] == pytest.approx(offset, abs=0.015 if window else 0.003)


def test_line_sigma_weighs_the_walking_line_against_the_alternation() -> None:
    """A crossover step: left stance 3 lands 1 cm to the right of the walking line. The
    alternation of sides, the step timing and the 8 cm step to the left from stance 2 label
    it left; with a walking-line scale of 0.5 mm, its line offset outweighs them and it is
    labelled right."""
    frames, truth = _drifting_walk(lateral={3: -0.01})
    assert _sides(frames, truth) == [side for side, _ in truth]
    tight = _sides(frames, truth, StanceParams(line_sigma_m=0.0005))
    assert tight[3] == "right"


def test_the_feet_standing_side_by_side_place_the_camera_for_a_lone_stance() -> None:
    """The layout of a mirrored CMU walk whose walking stances were all missed but one: the
    feet stand 8 cm either side of their middle at the start and the end, the camera 2.5 cm
    to the right of that middle, and the one right stance found between them lies 5.5 cm right
    of it, only 3 cm right of the camera's line. The standing pairs give the camera's offset
    (``standing_overlap_s``), and the lone stance is right; without them (a standing overlap
    longer than the walk) the alternation labels it left."""
    cam_y = -0.025
    stances = [  # (xy, first, last), right standing first
        (np.array([0.0, -0.08]), 0.0, 1.8),
        (np.array([0.0, 0.08]), 0.0, 1.57),
        (np.array([1.33, -0.055]), 2.97, 3.1),
        (np.array([2.69, -0.094]), 4.17, 6.0),
        (np.array([2.69, 0.066]), 4.43, 6.0),
    ]
    truth = [("right", xy) for xy, _, _ in stances]
    truth[1], truth[4] = ("left", stances[1][0]), ("left", stances[4][0])
    frames = []
    for i in range(int(6.0 * FPS) + 1):
        t = i / FPS
        x = float(np.clip((t - 1.6) / 2.7, 0.0, 1.0)) * 2.69 - 0.2
        cands = [xy for xy, t0, t1 in stances if t0 <= t <= t1]
        frames.append((t, cands, np.array([1.0, 0.0]), np.array([x, cam_y])))
    assert _sides(frames, truth) == ["right", "left", "right", "right", "left"]
    unplaced = _sides(frames, truth, StanceParams(standing_overlap_s=60.0))
    assert unplaced[2] == "left"


def test_step_timing_tells_alternation_and_a_missed_stance_apart() -> None:
    """Feet on one line (a narrow walk, no lateral cue) after a first step 9 cm to the right,
    stance 3 missed: one step time between two starts means two feet, two step times one
    foot (``step_timing_cost``); without it every stance after the first two takes the side
    of the one before (the weak alternation prior loses to the same-side fit on one line)."""
    frames, truth = _drifting_walk(lateral={k: 0.0 for k in range(1, 8)}, missed=(3,))
    expected = [side for side, _ in truth]
    expected[3] = "-"
    assert _sides(frames, truth) == expected
    off = _sides(frames, truth, StanceParams(step_timing_cost=0.0))
    assert off != expected


def test_segmented_candidates_find_only_feet_the_depth_does_not() -> None:
    """Candidates from the segmenter's foot pixels (``segmented``) never join a stance seen in
    depth, nor start one where such a stance rests: a foot seen in depth for 0.2 s and then
    only in its pixels for 0.3 s keeps its start, end and point; a foot seen only in its
    pixels is a stance (after ``weak_confirm_s``), and a depth sighting joins it."""
    heading, cam = np.array([1.0, 0.0]), np.array([0.5, 0.0])
    A, B = np.array([1.0, -0.08]), np.array([1.6, 0.08])
    trk = StanceTracker()
    for i in range(16):
        t = i / FPS
        cands, seg = [A + [0.01, 0.0]] if i >= 6 else [A], [i >= 6]
        if i >= 4:
            cands.append(B)
            seg.append(i < 12)  # B: only its pixels, then depth
        trk.update(t, cands, heading_W=heading, p_CinW=cam, weak=seg, segmented=seg)
    stances = sorted(trk.finish(), key=lambda s: s.t_first)
    assert len(stances) == 2
    a, b = stances
    assert a.t_last == pytest.approx(5 / FPS) and np.allclose(a.xy, A)
    assert a.n_obs == 6
    assert b.t_first == pytest.approx(4 / FPS) and b.t_last == pytest.approx(15 / FPS)
    assert np.allclose(b.xy, B)


@pytest.mark.parametrize("offset", [0.05, 0.07])
def test_a_foot_seen_in_depth_and_in_its_pixels_by_turns_is_one_stance(offset: float) -> None:
    """Depth finds a resting foot in every other frame, its pixels (in the stereo shadow) in
    the others, their point ``offset`` ahead (the toe cap's height along the ray): one stance,
    on its side, not a second one that the double-support cost would give the other side
    (``segmented_radius_m``; with a radius of 0 the phantom appears)."""
    heading, cam = np.array([1.0, 0.0]), np.array([0.5, 0.0])
    R = np.array([1.0, -0.08])

    def run(params: StanceParams | None = None) -> list:
        trk = StanceTracker(params)
        for i in range(15):
            seg = i % 2 == 1 and i > 3
            p = R + [offset, 0.0] if seg else R
            trk.update(i / FPS, [p], heading_W=heading, p_CinW=cam, weak=[seg], segmented=[seg])
        stances = trk.finish()
        return sorted(trk.sides_at({s.id: s.xy for s in stances}).values())

    assert run() == ["right"]
    assert run(StanceParams(segmented_radius_m=0.0)) == ["left", "right"]


def test_the_walking_line_labels_the_stances_of_a_real_drifting_walk() -> None:
    """The stances the filter found on CMU walking_01 (simulated, seed 1) and the camera's
    path, which drifts 2 cm a metre to the right: standing, the left foot's one stance found
    between two missed right ones, the left foot's last stance found twice (the pose moved
    6 cm while it rested, so its track split; the final positions put the two 1.4 cm apart)
    and the right foot joining it. Offsets along the heading labelled the left foot's
    second sighting right (the tracker before the walking line: left, right, left, right,
    left, right); against the walking line every stance has its side."""
    heading = np.array([1.0, 0.0])
    stances = [  # (x, y as the filter saw them, first, last, final x)
        (-0.002, 0.083, 0.0, 1.63, -0.002),
        (0.007, -0.076, 0.0, 1.57, 0.007),
        (1.472, 0.072, 2.77, 2.87, 1.472),
        (2.968, 0.016, 3.87, 4.03, 2.968),
        (3.024, 0.029, 4.47, 6.07, 2.954),
        (3.026, -0.129, 4.53, 6.07, 2.956),
    ]
    trk = StanceTracker()
    for i in range(int(6.07 * FPS) + 1):
        t = i / FPS
        x = float(np.clip((t - 1.8) / 3.0, 0.0, 1.0)) * 2.8 + 0.17  # 0.93 m/s, then standing
        cam = np.array([x, -0.02 * x])
        cands = [np.array([x_, y_]) for x_, y_, t0, t1, _ in stances if t0 <= t <= t1]
        trk.update(t, cands, heading_W=heading, p_CinW=cam)
    found = sorted(trk.finish(), key=lambda s: (s.t_first, s.xy[1] < 0))
    assert len(found) == len(stances)
    final = {s.id: np.array([r[4], r[1]]) for s, r in zip(found, stances, strict=True)}
    sides = trk.sides_at(final)
    assert [sides[s.id] for s in found] == ["left", "right", "left", "left", "left", "right"]


def test_a_camera_path_on_another_clock_is_said(caplog) -> None:
    frames, truth = _walk()
    trk = StanceTracker()
    for t, cands, heading, cam in frames:
        trk.update(t, cands, heading_W=heading, p_CinW=cam)
    stances = trk.finish()
    path_t = np.array([f[0] for f in frames]) + 1.7e9  # seconds since 1970
    path_xy = np.array([f[3] for f in frames])
    with caplog.at_level(logging.WARNING, logger="gaitnet.vio.stance_tracker"):
        trk.sides_at({s.id: s.xy for s in stances}, (path_t, path_xy))
    assert "misses the time of every stance" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="gaitnet.vio.stance_tracker"):
        trk.sides_at({s.id: s.xy for s in stances}, (path_t - 1.7e9, path_xy))
    assert caplog.text == ""


@pytest.mark.parametrize("fps", [15.0, 30.0, 60.0])
def test_a_stance_is_confirmed_after_the_same_time_at_any_frame_rate(fps: float) -> None:
    """``confirm_s``: a foot resting from t = 0 becomes a stance at the first frame at least
    0.06 s later (the 2nd at 15 Hz, the 3rd at 30 Hz, the 5th at 60 Hz), and a swing foot
    passing through the band at 1.5 m/s, 2.5 cm per frame at 60 Hz, never does."""
    p = np.array([1.0, -0.08])
    trk = StanceTracker()
    confirmed_at = None
    for i in range(10):
        t = i / fps
        (out,) = trk.update(t, [p], heading_W=np.array([1.0, 0.0]))
        if out is not None and out.is_new:
            confirmed_at = t
    assert confirmed_at == pytest.approx(np.ceil(0.06 * fps - 1e-9) / fps)
    assert StanceTracker(StanceParams(confirm_s=0.0)).update(0.0, [p])[0].is_new
    passing = StanceTracker()
    for i in range(int(0.05 * fps) + 1):  # 0.05 s within the radius, then gone
        assert passing.update(i / fps, [p + [1.5 * i / fps, 0.0]]) == [None]
    assert passing.finish() == []


def test_stance_params_are_checked() -> None:
    for bad in (
        {"assoc_radius_m": -1.0},
        {"confirm_s": -0.1},
        {"max_gap_s": float("nan")},
        {"double_support_cost": -1.0},
    ):
        with pytest.raises(ValueError, match=next(iter(bad))):
            StanceParams(**bad)


def test_foot_params_are_checked() -> None:
    for bad in (
        {"h_min_m": -0.1},
        {"h_max_m": 0.001},  # below h_min_m
        {"stride": 0},
        {"min_area_m2": 0.0},
        {"max_width_m": float("nan")},
        {"split_width_m": -0.1},
        {"max_candidates": 0},
    ):
        with pytest.raises(ValueError, match=next(iter(bad))):
            FootParams(**bad)


def test_a_stance_reopened_behind_another_closed_one() -> None:
    """Two stances seen at the same times, both closed, the second seen again: it is re-opened
    (closed tracks are found by identity; comparing their fields, arrays, raised)."""
    a, b = np.array([0.0, 0.1]), np.array([0.0, -0.1])
    trk = StanceTracker(StanceParams(max_gap_s=0.15, reopen_s=1.0))
    for i in range(3):
        trk.update(0.1 * i, [a, b], heading_W=np.array([1.0, 0.0]))
    trk.update(0.5, [], heading_W=np.array([1.0, 0.0]))  # both closed
    (out,) = trk.update(0.6, [b], heading_W=np.array([1.0, 0.0]))
    assert out is not None and not out.is_new
    assert len(trk.finish()) == 2


def test_camera_forward_holds_at_every_pitch() -> None:
    """The heading the stance tracker sides feet with: the optical axis alone has no horizontal
    part at 90° and flips past it (sway at 89°); z − y points along the walk at every pitch from
    horizontal to beyond straight down, with a length of at least 0.7."""
    from gaitnet.geometry import so3_exp
    from gaitnet.vio.run import camera_forward_W

    level = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])  # z_C along +x
    for pitch in (0.0, 45.0, 70.0, 86.0, 89.0, 90.0, 92.0, 100.0):
        for yaw in (0.0, 2.0):
            R = so3_exp([0.0, 0.0, np.radians(yaw)]) @ so3_exp([0.0, np.radians(pitch), 0.0])
            T = np.eye(4)
            T[:3, :3] = R @ level
            f = camera_forward_W(T)
            assert f[0] > 0.7 and abs(np.arctan2(f[1], f[0]) - np.radians(yaw)) < 1e-9, pitch
    past = np.eye(4)
    past[:3, :3] = so3_exp([0.0, np.radians(92.0), 0.0]) @ level
    assert past[0, 2] < 0  # the optical axis alone would point backwards
