"""AprilTag sheets render as a camera sees them (issue 8): decodable at the default 640×480.

The threshold: on 15 standing frames (5 floor families × pitch 55/70/80°) the default 640×480
session decodes 8–16 of the 35 tags (mean 11.8) with ``cv2.aruco`` defaults, and exactly as
many as the same view rendered at the D455's native 1280×800 and area-downsampled to the
640×480 mode — which is what a real D455's 640×480 stream is. The tags are 12.5–15 px wide
there (1.6–1.9 px per bit), at the sampling limit of the detector, so a clear majority is not
what a real camera at this distance delivers either; the test asks for at least 7 of 35 (the
measured minimum 8 less a margin), every id right and corners within 1.5 px of the truth, and
≥ 33 of 35 at 1280×800 (measured 34–35). Before the fix: 0 of 35 at 640×480.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parents[1] / "benchmarks"))
from realism_tags import (  # noqa: E402
    area_check,
    decode_stats,
    native_camera,
    render_colour,
    standing_world,
)


@pytest.fixture(scope="module")
def standing():
    return standing_world(0, "tiles", 70.0, None)


def test_default_resolution_standing_frame_decodes(standing) -> None:
    cam = standing.cfg.camera
    rgb, _ = render_colour(standing, cam, 0)
    board = standing.scene.boards[0]
    in_view, decoded, wrong, err = decode_stats(rgb, board, cam.intrinsics().K, standing.T_WfromC)
    assert in_view == 35
    assert decoded >= 7 and wrong == 0
    assert err < 1.5


def test_native_resolution_decodes_nearly_all(standing) -> None:
    cam = native_camera(standing.cfg.camera)
    rgb, _ = render_colour(standing, cam, 0)
    in_view, decoded, wrong, err = decode_stats(
        rgb, standing.scene.boards[0], cam.intrinsics().K, standing.T_WfromC
    )
    assert in_view == 35 and decoded >= 33 and wrong == 0 and err < 2.5


def test_sheet_is_area_sampled_like_a_downsampled_native_frame() -> None:
    a = area_check(0, "tiles", 70.0)
    assert a["pixels"] > 3000
    assert a["mad"] < 6.0  # grey levels (measured 4.0; 15.4 before)
    assert a["contrast_direct"] == pytest.approx(a["contrast_down"], rel=0.08)
    assert a["contrast_direct"] > 120  # black toner on white paper (99 before)


def test_sheet_reflectance_is_paper_and_toner(standing) -> None:
    from gaitnet.sim.tag_sheet import INK_REFLECTANCE, PAPER_REFLECTANCE

    level0 = standing.scene.floor.sheets[0].levels[0]
    assert np.percentile(level0, 99) == pytest.approx(PAPER_REFLECTANCE, rel=0.08)
    assert np.percentile(level0, 1) == pytest.approx(INK_REFLECTANCE, abs=0.01)
