"""Stance-foot candidates from the segmenter's foot pixels where depth has none
(gaitnet.vio.feet_segmented)."""

import numpy as np
import pytest
from test_vio_feet import K, _plane, _pose, _render, _shoe, _to_world

from gaitnet.vio.feet import FootParams, detect_foot_candidates
from gaitnet.vio.feet_segmented import FootMask, segmented_foot_candidates

PARAMS = FootParams(shoe_length_m=0.26, toe_margin_m=0.0)


def _shadowed(T: np.ndarray, boxes: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The depth of the floor and ``boxes``, the boxes' pixels (their "foot" label), and the
    depth with those pixels' depth removed (a stereo shadow over the shoes)."""
    depth = _render(T, boxes)
    floor = _render(T, [])
    shoe = np.abs(depth - floor) > 1e-6
    return depth, shoe, np.where(shoe, 0.0, depth).astype(np.float32)


def _toe_on_floor(T: np.ndarray, x_toe: float, y: float, top: float) -> float:
    """Where the ray through the shoe's top front edge (``x_toe``, ``y``, ``top``) meets the
    floor, along x: beyond the toe by the top's height over the ray's slope."""
    o = T[:3, 3]
    d = np.array([x_toe, y, top]) - o
    return float(o[0] + d[0] * (-o[2] / d[2]))


def test_a_shoe_without_depth_is_found_from_its_pixels_with_the_known_bias() -> None:
    """A 26 cm shoe 5 cm high, 0.8 m ahead and 9 cm to the side, all of its depth missing:
    the depth finds nothing, its pixels give one weak candidate on the floor whose point lies
    as far beyond the sole's centre as the ray through the shoe's top front edge meets the
    floor beyond the toe (known answer within 5 mm: the 98th percentile of the points)."""
    T = _pose()
    plane = _plane(T)
    _, shoe, depth = _shadowed(T, [_shoe(0.8, 0.09, height=0.05)])
    assert detect_foot_candidates(depth, K, plane, PARAMS) == []
    (c,) = segmented_foot_candidates(FootMask.from_labels(shoe.astype(np.uint8)), depth, K,
                                     plane, PARAMS, [])  # fmt: skip
    p = _to_world(T, c.p_FinC)
    assert p[2] == pytest.approx(0.0, abs=1e-9)
    expected_x = _toe_on_floor(T, 0.8 + 0.13, 0.09, 0.05) - 0.13
    assert expected_x - 0.8 > 0.02  # the bias is there to see
    assert p[0] == pytest.approx(expected_x, abs=0.005)
    assert p[1] == pytest.approx(0.09, abs=0.01)
    assert c.weak and not c.at_border


def test_the_depth_keeps_the_feet_it_shows() -> None:
    """A shoe the depth shows is the depth's to judge (``segmented_max_depth_fraction``), and
    a candidate near one from depth is that foot again (``segmented_apart_m``)."""
    T = _pose()
    plane = _plane(T)
    depth, shoe, shadowed = _shadowed(T, [_shoe(0.8, 0.09, height=0.05)])
    mask = FootMask.from_labels(shoe.astype(np.uint8))
    assert segmented_foot_candidates(mask, depth, K, plane, PARAMS, []) == []
    anyway = FootParams(shoe_length_m=0.26, toe_margin_m=0.0, segmented_max_depth_fraction=1.0)
    assert len(segmented_foot_candidates(mask, depth, K, plane, anyway, [])) == 1
    found = detect_foot_candidates(depth, K, plane, PARAMS)
    assert len(found) == 1
    assert segmented_foot_candidates(mask, shadowed, K, plane, PARAMS, found) == []
    apart = FootParams(shoe_length_m=0.26, toe_margin_m=0.0, segmented_apart_m=0.0)
    assert len(segmented_foot_candidates(mask, shadowed, K, plane, apart, found)) == 1
    full = FootParams(shoe_length_m=0.26, toe_margin_m=0.0, max_candidates=1)
    assert segmented_foot_candidates(mask, shadowed, K, plane, full, found) == []


def test_a_shoe_in_the_air_and_specks_are_not_feet() -> None:
    """A shoe 15 cm up whose pixels with depth (a quarter) say so: a swing foot; a 3 cm speck
    labelled foot: too small on the floor. Neither is a candidate."""
    T = _pose()
    plane = _plane(T)
    floating = (0.75, 1.01, -0.05, 0.05, 0.15, 0.22)
    depth, shoe, shadowed = _shadowed(T, [floating])
    some = shadowed.copy()
    rows, cols = np.nonzero(shoe)
    keep = slice(None, None, 4)  # a quarter of its pixels keep their depth
    some[rows[keep], cols[keep]] = depth[rows[keep], cols[keep]]
    mask = FootMask.from_labels(shoe.astype(np.uint8))
    assert segmented_foot_candidates(mask, some, K, plane, PARAMS, []) == []
    on_floor = _shadowed(T, [_shoe(0.88, 0.0, height=0.05)])  # the same share with depth
    low = on_floor[2].copy()
    rows, cols = np.nonzero(on_floor[1])
    low[rows[keep], cols[keep]] = on_floor[0][rows[keep], cols[keep]]
    low_mask = FootMask.from_labels(on_floor[1].astype(np.uint8))
    assert len(segmented_foot_candidates(low_mask, low, K, plane, PARAMS, [])) == 1
    _, speck, speck_depth = _shadowed(T, [(0.8, 0.83, 0.3, 0.33, 0.0, 0.03)])
    speck_mask = FootMask.from_labels(speck.astype(np.uint8))
    assert segmented_foot_candidates(speck_mask, speck_depth, K, plane, PARAMS, []) == []


def test_foot_mask_keeps_the_foot_label_in_its_box() -> None:
    labels = np.zeros((6, 8), np.uint8)
    labels[2:4, 3:6] = 1
    labels[5, 0] = 2  # leg
    mask = FootMask.from_labels(labels)
    assert mask.origin == (2, 3)
    assert mask.pixels.shape == (2, 3) and mask.pixels.all()
    assert FootMask.from_labels(np.full((6, 8), 2, np.uint8)) is None


def test_a_shoe_showing_its_inner_part_lies_half_a_width_out_from_it() -> None:
    """A 10 cm wide shoe 12 cm to the side whose outer 6 cm the thigh hides: its inner 4 cm
    alone are labelled. The foot point lies half ``shoe_width_m`` out from their inner edge,
    on the shoe's centre line (known answer within 1 cm); the middle of the visible part
    would be 3 cm in. A 20 cm ``shoe_width_m`` moves it 5 cm further out."""
    T = _pose()
    plane = _plane(T)
    _, _, depth = _shadowed(T, [_shoe(0.8, 0.12, height=0.05)])
    inner = (0.8 - 0.13, 0.8 + 0.13, 0.07, 0.11, 0.0, 0.05)
    _, shown, _ = _shadowed(T, [inner])
    mask = FootMask.from_labels(shown.astype(np.uint8))
    (c,) = segmented_foot_candidates(mask, depth, K, plane, PARAMS, [])
    assert _to_world(T, c.p_FinC)[1] == pytest.approx(0.12, abs=0.01)
    wide = FootParams(shoe_length_m=0.26, toe_margin_m=0.0, shoe_width_m=0.2)
    (w,) = segmented_foot_candidates(mask, depth, K, plane, wide, [])
    assert _to_world(T, w.p_FinC)[1] - _to_world(T, c.p_FinC)[1] == pytest.approx(0.05, abs=0.002)
