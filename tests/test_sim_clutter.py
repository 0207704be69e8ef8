"""Scene clutter (gaitnet.sim.clutter): the distance to the walking path, and boxes kept off
the path of a turning walk while a straight walk's clutter stays as it was."""

from __future__ import annotations

import numpy as np
import pytest

from gaitnet.config import load_config
from gaitnet.sim.clutter import ClutterBox, distance_to_path, make_clutter
from gaitnet.sim.config import SimConfig
from gaitnet.sim.scene_setup import build_scene, rng_streams

EXTENT = ((-1.0, 9.0), (-2.0, 6.0))
KEEP_OUT = 0.7


def _size(item) -> float:
    """The size the keep-out distance adds: a box's first side, a cylinder's diameter."""
    return item.size_m[0] if isinstance(item, ClutterBox) else 2 * item.radius_m


def _arc(turn_deg: float, length_m: float = 8.0, n: int = 200) -> np.ndarray:
    """A path starting at the origin along +x and turning left by ``turn_deg`` over its length."""
    s = np.linspace(0.0, length_m, n)
    if turn_deg == 0:
        return np.stack([s, np.zeros(n)], axis=1)
    radius = length_m / np.radians(turn_deg)
    a = s / radius
    return np.stack([radius * np.sin(a), radius * (1 - np.cos(a))], axis=1)


def test_distance_to_path_known_answers() -> None:
    path = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 3.0]])
    assert distance_to_path(np.array([1.0, 0.5]), path) == pytest.approx(0.5)  # inside a segment
    assert distance_to_path(np.array([-3.0, 4.0]), path) == pytest.approx(5.0)  # past an end
    assert distance_to_path(np.array([2.5, 1.0]), path) == pytest.approx(0.5)  # second segment
    assert distance_to_path(np.array([3.0, -1.0]), path) == pytest.approx(np.sqrt(2))  # corner
    assert distance_to_path(np.array([1.0, 1.0]), path[:1]) == pytest.approx(np.sqrt(2))
    # against a dense sampling of the polyline
    rng = np.random.default_rng(0)
    pairs = zip(path[:-1], path[1:], strict=True)
    dense = np.concatenate([np.linspace(a, b, 2001) for a, b in pairs])
    for p in rng.uniform(-3, 5, (50, 2)):
        brute = np.min(np.linalg.norm(dense - p, axis=1))
        assert distance_to_path(p, path) == pytest.approx(brute, abs=2e-3)


def test_a_straight_path_leaves_the_clutter_as_the_line_alone_places_it() -> None:
    for seed in range(10):
        line_only = make_clutter(np.random.default_rng(seed), EXTENT, 8, path_y_m=0.0)
        with_path = make_clutter(
            np.random.default_rng(seed), EXTENT, 8, path_y_m=0.0, path_xy=_arc(0.0)
        )
        assert with_path == line_only


def test_clutter_stays_off_a_turning_path() -> None:
    path = _arc(120.0)
    too_close_before = 0
    for seed in range(20):
        before = make_clutter(np.random.default_rng(seed), EXTENT, 8, path_y_m=0.0)
        too_close_before += sum(
            distance_to_path(np.array(c.centre_xy), path) < KEEP_OUT + _size(c) for c in before
        )
        after = make_clutter(np.random.default_rng(seed), EXTENT, 8, path_y_m=0.0, path_xy=path)
        assert len(after) == 8
        for c in after:
            assert distance_to_path(np.array(c.centre_xy), path) >= KEEP_OUT + _size(c)
    assert too_close_before > 0  # the line alone put boxes on the turned path


def test_a_turning_session_walks_around_its_clutter() -> None:
    # the simulated fast turn of docs/pipeline.md (seed 9207): a box stood where the right foot
    # landed, and the filter took its edge for a stance foot
    cfg = load_config(
        SimConfig,
        None,
        ["gait.speed_mps=1.7", "gait.turn_deg=120", "gait.walk_length_m=8", "scene.texel_m=0.02"],
    )
    scene = build_scene(cfg, rng_streams(9207))
    t = np.linspace(0.0, scene.walk.duration_s, 400)
    soles = scene.walk.sole_centres(t)[:, :, :2]
    assert len(scene.clutter) > 0
    for c in scene.clutter:
        for side in range(2):
            assert distance_to_path(np.array(c.centre_xy), soles[:, side]) > _size(c) / 2 + 0.3
