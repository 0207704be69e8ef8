"""gait.c3d (gaitnet.pipeline.c3d_export): a round trip through ezc3d's reader."""

from __future__ import annotations

from pathlib import Path

import ezc3d
import numpy as np
import pytest

from gaitnet.pipeline.c3d_export import FOOT_LABELS, JOINT_LABELS, write_gait_c3d
from gaitnet.pipeline.gait_events import FootContact


def _contact(side: str, ic: float | None, to: float | None) -> FootContact:
    return FootContact(side, ic, to, 0.0, 0.1, np.zeros(3))


def test_points_events_and_height_read_back(tmp_path: Path) -> None:
    """Known answers: 2 s at 30 frames/s with frame 10 dropped. The points read back in mm
    (float32) on a uniform 60-frame grid whose dropped frame is invalid (residual −1); Foot
    Strike / Foot Off events with Left / Right contexts at frame / rate seconds (frame 1 the
    first), the undetected ones left out; the height in PROCESSING:Height [mm]."""
    rng = np.random.default_rng(0)
    t = np.delete(np.arange(60) / 30.0, 10) + 12.5  # session clock: not from 0
    joints = rng.normal(size=(59, 9, 3))
    feet = rng.normal(size=(59, 2, 3))
    contacts = [
        _contact("left", 12.5 + 0.5, 12.5 + 1.2),
        _contact("right", None, 12.5 + 0.8),  # began before the first frame
    ]
    path = tmp_path / "gait.c3d"
    write_gait_c3d(path, t, joints, feet, contacts, 1.75, subject="S01")
    c3d = ezc3d.c3d(str(path))
    point = c3d["parameters"]["POINT"]
    assert point["RATE"]["value"][0] == pytest.approx(30.0)
    assert list(point["LABELS"]["value"]) == [n for n, _ in JOINT_LABELS + FOOT_LABELS]
    assert list(point["UNITS"]["value"]) == ["mm"]
    xyz = c3d["data"]["points"][:3]  # (3, 9, 60)
    assert xyz.shape == (3, 9, 60)
    kept = np.delete(np.arange(60), 10)
    expected = np.concatenate([joints[:, :7], feet], axis=1) * 1000.0  # (59, 9, 3)
    np.testing.assert_allclose(np.transpose(xyz[:, :, kept], (2, 1, 0)), expected, atol=1e-3)
    residuals = c3d["data"]["meta_points"]["residuals"][0]
    assert np.all(residuals[:, 10] < 0) and np.all(residuals[:, kept] >= 0)
    event = c3d["parameters"]["EVENT"]
    got = sorted(
        zip(
            event["CONTEXTS"]["value"],
            event["LABELS"]["value"],
            60 * event["TIMES"]["value"][0] + event["TIMES"]["value"][1],
            event["ICON_IDS"]["value"],
            strict=True,
        )
    )
    want = [
        ("Left", "Foot Off", 1.2 + 1 / 30, 2),
        ("Left", "Foot Strike", 0.5 + 1 / 30, 1),
        ("Right", "Foot Off", 0.8 + 1 / 30, 2),
    ]
    assert [g[:2] for g in got] == [w[:2] for w in want]
    np.testing.assert_allclose([g[2] for g in got], [w[2] for w in want], atol=1e-5)
    assert [int(g[3]) for g in got] == [w[3] for w in want]
    assert c3d["parameters"]["PROCESSING"]["Height"]["value"][0] == pytest.approx(1750.0)
    assert list(c3d["parameters"]["SUBJECTS"]["NAMES"]["value"]) == ["S01"]
