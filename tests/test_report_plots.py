"""Report figures (gaitnet/pipeline/plots.py): valid PNGs of the expected size with the side
colours, and one-line errors on bad input."""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image
from test_gait_events import synthetic_foot

from gaitnet.errors import InputError
from gaitnet.pipeline.gait_events import FootContact, detect_events, stances_from_contacts
from gaitnet.pipeline.plots import (
    PNG_SIGNATURE,
    foot_trajectories_png,
    gait_cycles,
    gait_phases_png,
    joint_angles_png,
    stance_spans,
    top_view_png,
    write_png,
)

RED = (214, 39, 40)  # left, "#d62728"
GREEN = (44, 160, 44)  # right, "#2ca02c"


@pytest.fixture(scope="module")
def walk():
    t = np.arange(0.0, 6.0, 1 / 30)
    toe_offs = [1.0 + 1.1 * k for k in range(4)]
    contacts = [x + 0.4 for x in toe_offs]
    feet = {
        "left": synthetic_foot(t, toe_offs, contacts, 0.1),
        "right": synthetic_foot(
            t, [x + 0.55 for x in toe_offs], [x + 0.55 for x in contacts], -0.1
        ),
    }
    found = detect_events(t, feet)
    angles = np.stack([30 * np.sin(2 * np.pi * t / 1.1 + k) for k in range(6)], axis=1)
    return t, feet, found, angles


def _image(png: bytes, size: tuple[int, int]) -> np.ndarray:
    assert png.startswith(PNG_SIGNATURE)
    with Image.open(io.BytesIO(png)) as im:
        im.load()
        assert im.format == "PNG" and im.size == size
        return np.asarray(im.convert("RGB"))


def _has(pixels: np.ndarray, colour: tuple[int, int, int]) -> bool:
    return bool(np.any(np.all(np.abs(pixels.astype(int) - colour) <= 3, axis=-1)))


def test_foot_trajectories(walk) -> None:
    t, feet, _, _ = walk
    measured = {side: (np.arange(t.size) % 10) < 6 for side in feet}
    png = foot_trajectories_png(t, feet, measured, truth=feet)
    pixels = _image(png, (1000, 650))
    assert 20_000 < len(png) < 1_000_000
    assert _has(pixels, RED) and _has(pixels, GREEN)
    only_left = _image(foot_trajectories_png(t, {"left": feet["left"]}), (1000, 650))
    assert _has(only_left, RED) and not _has(only_left, GREEN)


def test_top_view_phases_and_angles(walk, tmp_path) -> None:
    t, feet, found, angles = walk
    top = top_view_png(feet, stances_from_contacts(found), found, camera_xy=feet["left"][:, :2])
    assert _has(_image(top, (1000, 380)), GREEN)
    phases = _image(gait_phases_png(found, float(t[0]), float(t[-1])), (1000, 240))
    assert _has(phases, RED) and _has(phases, GREEN)
    png = joint_angles_png(t, angles, found)
    assert _has(_image(png, (1000, 360)), RED)
    write_png(tmp_path / "a.png", png)
    assert (tmp_path / "a.png").read_bytes() == png


def _contact(side, ic, to, still_start, still_end) -> FootContact:
    return FootContact(side, ic, to, still_start, still_end, np.zeros(3))


def test_stance_spans_come_from_detected_events_only() -> None:
    """Known answer: a missed toe off mid-walk ends the stance bar where the foot was last
    still and leaves the time to the next stance unknown, never stance (the README demo's
    right foot once showed stance for the whole walk); standing at the start and the end
    (no IC / TO at the range's edges) is stance."""
    contacts = [
        _contact("right", None, None, 0.0, 1.5),  # stood, then its toe off was missed
        _contact("right", 2.4, 3.3, 2.5, 3.0),
        _contact("right", 3.6, None, 3.7, 6.0),  # stood to the end
        _contact("left", None, 1.9, 0.0, 1.6),
        _contact("left", 2.9, 3.8, 3.0, 3.5),
        _contact("left", None, None, 4.6, 5.0),  # neither event detected mid-walk
    ]
    known, unknown = stance_spans(contacts, "right", 0.0, 6.0)
    assert known == [(0.0, 1.5), (2.4, 3.3), (3.6, 6.0)]
    assert unknown == [(1.5, 2.4)]
    known, unknown = stance_spans(contacts, "left", 0.0, 6.0)
    assert known == [(0.0, 1.9), (2.9, 3.8), (4.6, 5.0)]
    assert unknown == [(3.8, 4.6), (5.0, 6.0)]
    png = _image(gait_phases_png(contacts, 0.0, 6.0), (1000, 240))
    assert _has(png, RED) and _has(png, GREEN)


def test_gait_cycles_known_answer(walk) -> None:
    """Three complete left cycles: IC 1.4, 2.5, 3.6 → the next IC; toe offs 2.1, 3.2, 4.3."""
    _, _, found, _ = walk
    cycles = gait_cycles(found, "left")
    np.testing.assert_allclose(
        cycles, [[1.4, 2.1, 2.5], [2.5, 3.2, 3.6], [3.6, 4.3, 4.7]], atol=3e-3
    )


def test_angles_without_cycles_still_draw(walk) -> None:
    t, _, _, angles = walk
    assert joint_angles_png(t, angles, []).startswith(PNG_SIGNATURE)


def test_given_cycles_replace_the_contacts_own(walk) -> None:
    """The cycles given per side (the report's table's) are drawn, not the contacts':
    the left's alone draws red and no green; none given draws neither."""
    t, _, found, angles = walk
    left = {"left": gait_cycles(found, "left"), "right": []}
    only_left = _image(joint_angles_png(t, angles, found, left), (1000, 360))
    assert _has(only_left, RED) and not _has(only_left, GREEN)
    none = _image(joint_angles_png(t, angles, found, {}), (1000, 360))
    assert not _has(none, RED) and not _has(none, GREEN)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda t, f, c, a: foot_trajectories_png(t, {"left": f["left"][:-2]}), "'left'"),
        (lambda t, f, c, a: foot_trajectories_png(t, {"middle": f["left"]}), "keys"),
        (lambda t, f, c, a: foot_trajectories_png(t, f, {"left": np.ones(t.size)}), "bool"),
        (
            lambda t, f, c, a: foot_trajectories_png(t, f, truth={"left": f["left"] * np.nan}),
            "truth 'left': not all finite",
        ),
        (lambda t, f, c, a: top_view_png(f, camera_xy=np.zeros((3, 3))), "camera_xy"),
        (lambda t, f, c, a: joint_angles_png(t, a[:, :5], c), "angles_deg"),
        (
            lambda t, f, c, a: joint_angles_png(t, np.where(a > 0, np.inf, a), c),
            "angles_deg: not all finite",
        ),
        (lambda t, f, c, a: gait_phases_png(c, 3.0, 1.0), "time range"),
        (lambda t, f, c, a: write_png("x.png", b"GIF89a"), "not a PNG"),
    ],
)
def test_bad_input_is_one_line(walk, call, match) -> None:
    t, feet, found, angles = walk
    with pytest.raises(InputError, match=match) as info:
        call(t, feet, found, angles)
    assert "\n" not in str(info.value)
