"""Edge refinement of label maps (gaitnet/segmentation/edge_refine.py): the guided filter
against an independent computation of He et al.'s formulas, a boundary moved onto a colour
edge, what the ``feet`` region may change, and the parameters' checks."""

from __future__ import annotations

import numpy as np
import pytest

from gaitnet.segmentation.edge_refine import EdgeRefineParams, argmax_classes, refine_labels


def _box_mean(x: np.ndarray, r: int) -> np.ndarray:
    """Mean over the (2r+1)² window around each pixel, the frame mirrored at its border
    (the edge pixel repeated), by summed-area tables."""
    k = 2 * r + 1
    pad = [(r, r), (r, r)] + [(0, 0)] * (x.ndim - 2)
    c = np.pad(np.pad(x, pad, mode="symmetric"), [(1, 0), (1, 0)] + [(0, 0)] * (x.ndim - 2))
    c = c.cumsum(0).cumsum(1)
    return (c[k:, k:] - c[:-k, k:] - c[k:, :-k] + c[:-k, :-k]) / k**2


def _guided_filter(rgb: np.ndarray, p: np.ndarray, r: int, eps: float) -> np.ndarray:
    """He, Sun and Tang's colour guided filter (TPAMI 2013, eq. 19–21) of ``p`` (H, W, C)
    with the guide ``rgb`` / 255, written out in float64."""
    g, p = rgb.astype(np.float64) / 255.0, p.astype(np.float64)
    mean_g, mean_p = _box_mean(g, r), _box_mean(p, r)
    sigma = _box_mean(g[..., :, None] * g[..., None, :], r)
    sigma -= mean_g[..., :, None] * mean_g[..., None, :]
    cov = (
        _box_mean(g[..., :, None] * p[..., None, :], r)
        - mean_g[..., :, None] * mean_p[..., None, :]
    )
    a = np.linalg.solve(sigma + eps * np.eye(3), cov)  # (H, W, 3, C)
    b = mean_p - np.einsum("hwc,hwck->hwk", mean_g, a)
    return np.einsum("hwc,hwck->hwk", g, _box_mean(a, r)) + _box_mean(b, r)


def _softmax(logits: np.ndarray) -> np.ndarray:
    e = np.exp(logits - logits.max(axis=0))
    return np.moveaxis(e / e.sum(axis=0), 0, -1)


def test_frame_region_is_the_argmax_of_the_guided_filtered_probabilities() -> None:
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, (30, 40, 3), dtype=np.uint8)
    logits = rng.normal(0.0, 1.5, (3, 30, 40)).astype(np.float32)
    params = EdgeRefineParams(radius_px=3, eps=1e-3, region="frame")
    got = refine_labels(logits, rgb, argmax_classes(logits[None])[0], params)
    q = _guided_filter(rgb, _softmax(logits)[..., 1:], 3, 1e-3)
    expected = np.argmax(np.concatenate([1 - q.sum(-1, keepdims=True), q], -1), -1)
    np.testing.assert_array_equal(got, expected)


def _shoe_on_floor(edge_col: int, drawn_col: int) -> tuple[np.ndarray, np.ndarray]:
    """A dark shoe (columns < ``edge_col``) on a bright floor, and smooth logits (as from a
    coarse score grid) that put the foot/background boundary at ``drawn_col`` instead."""
    h, w = 32, 48
    rng = np.random.default_rng(1)
    rgb = np.where(np.arange(w)[None, :, None] < edge_col, 40, 200).astype(np.float64)
    rgb = np.clip(rgb + rng.normal(0, 2, (h, w, 3)), 0, 255).astype(np.uint8)
    ramp = (drawn_col - 0.5 - np.arange(w, dtype=np.float32)) / 4.0  # > 0 left of drawn_col
    logits = np.zeros((3, h, w), np.float32)
    logits[1] = np.broadcast_to(ramp, (h, w))
    logits[2] = -5.0
    return rgb, logits


@pytest.mark.parametrize("region", ["feet", "frame"])
@pytest.mark.parametrize("drawn_col", [21, 23, 26, 27])
def test_a_boundary_drawn_off_the_colour_edge_moves_onto_it(region: str, drawn_col: int) -> None:
    """Up to half the default radius (3 px) either side of the edge."""
    rgb, logits = _shoe_on_floor(24, drawn_col)
    labels = argmax_classes(logits[None])[0]
    assert (labels[:, :drawn_col] == 1).all() and (labels[:, drawn_col:] == 0).all()
    refined = refine_labels(logits, rgb, labels, EdgeRefineParams(region=region))
    assert (refined[:, :24] == 1).all() and (refined[:, 24:] == 0).all()
    assert (labels == np.array(labels)).all()  # the input is not changed
    np.testing.assert_array_equal(
        refine_labels(logits, rgb, labels, EdgeRefineParams(0, 3e-4, region)), labels
    )


def test_feet_region_changes_only_foot_labels_near_a_foot() -> None:
    """``feet``: labels change only within three radii of a foot blob, and a pixel changes only
    to or from foot; ``frame`` also moves a leg boundary far from any foot."""
    rgb, logits = _shoe_on_floor(24, 27)
    h = logits.shape[1]
    # below the foot, a leg drawn 3 columns off its colour edge
    rgb = np.concatenate([rgb, rgb[::-1]], axis=0)
    logits = np.concatenate([logits, logits], axis=1)
    logits[1, h:] = -5.0
    logits[2, h:] = logits[1, :h]
    labels = argmax_classes(logits[None])[0]
    r = EdgeRefineParams().radius_px
    feet = refine_labels(logits, rgb, labels, EdgeRefineParams(region="feet"))
    frame = refine_labels(logits, rgb, labels, EdgeRefineParams(region="frame"))
    changed = feet != labels
    assert changed.any()
    assert ((labels[changed] == 1) | (feet[changed] == 1)).all()
    rows = np.nonzero(changed.any(axis=1))[0]
    assert rows.max() < h + 3 * r  # the foot blob ends at row h - 1
    assert (frame[h + 3 * r :] != labels[h + 3 * r :]).any()  # the leg edge, moved by "frame"
    np.testing.assert_array_equal(feet[:h], frame[:h])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"radius_px": -1}, "radius_px must be an integer within [0, 64]"),
        ({"radius_px": 2.5}, "radius_px must be an integer"),
        ({"eps": 0.0}, "eps must be"),
        ({"region": "legs"}, "region must be feet or frame"),
    ],
)
def test_bad_parameters_are_refused(kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
        EdgeRefineParams(**kwargs)
