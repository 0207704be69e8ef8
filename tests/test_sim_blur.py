"""Motion blur over the exposure, auto-exposure time, and frame workers (issue 8)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from gaitnet.config import load_config
from gaitnet.errors import ConfigError
from gaitnet.sim.config import SimConfig
from gaitnet.sim.rig import CameraConfig
from gaitnet.sim.scene_setup import build_scene, rng_streams
from gaitnet.sim.session import simulate_session

sys.path.insert(0, str(Path(__file__).parents[1] / "benchmarks"))
from realism_blur import blur_length, synthetic_foot_blur  # noqa: E402

CONFIG = Path(__file__).parents[1] / "configs" / "sim" / "tiny.yaml"
FAST = ["camera.fps=6", "output.preview_frames=2"]


@pytest.mark.parametrize("displacement", [6.0, 15.0, 30.0])
def test_blur_length_is_image_speed_times_exposure(displacement: float) -> None:
    blurred, sharp = synthetic_foot_blur(displacement)
    assert blur_length(sharp) == 0.0
    assert blur_length(blurred) == pytest.approx(displacement, rel=0.1, abs=1.0)
    # the patch's light is spread, not lost
    assert blurred.sum() == pytest.approx(sharp.sum(), rel=0.01)


def test_exposure_time_follows_brightness_and_the_switch_turns_it_off() -> None:
    cam = CameraConfig()
    lo, hi = cam.exposure_time_range_s
    assert cam.exposure_time_s(1.0) == pytest.approx(cam.exposure_time_ref_s)
    assert cam.exposure_time_s(2.0) > cam.exposure_time_s(1.0)  # dimmer scene: longer
    assert cam.exposure_time_s(100.0) == hi and cam.exposure_time_s(1e-3) == lo
    assert CameraConfig(motion_blur=False).exposure_time_s(1.0) == 0.0


def test_default_longest_exposure_is_at_most_the_frame_period() -> None:
    assert CameraConfig().exposure_time_range_s == (0.001, 0.030)  # 30 Hz: as written
    assert CameraConfig(fps=60).exposure_time_range_s == (0.001, 0.0166)  # 16.67 ms, 0.1 ms steps
    assert CameraConfig(fps=120).exposure_time_range_s == (0.001, 0.0083)
    # the config path too (a 60 Hz session was refused because of the default); a range the
    # user gives beyond the frame period is still refused
    cfg = load_config(SimConfig, None, ["camera.fps=60"])
    assert cfg.camera.exposure_time_range_s[1] == pytest.approx(0.0166)
    with pytest.raises(ConfigError, match="exposure_time_range_s"):
        load_config(SimConfig, None, ["camera.fps=60", "camera.exposure_time_range_s=[0.001,0.02]"])


@pytest.mark.parametrize(
    "kw",
    [
        {"exposure_time_range_s": (0.02, 0.01)},
        {"exposure_time_range_s": (0.001, 0.05)},  # longer than the frame period at 30 Hz
        {"exposure_time_range_s": (0.0, 0.01)},
        {"exposure_time_ref_s": 0.1},
        {"exposure_time_ref_s": float("nan")},
    ],
)
def test_bad_exposure_keys_are_refused(kw: dict) -> None:
    with pytest.raises(ValueError):
        CameraConfig(**kw)


def test_blur_changes_colour_only_and_where_things_move() -> None:
    cfg = load_config(SimConfig, CONFIG, FAST)
    scene = build_scene(cfg, rng_streams(2))
    walk = scene.walk
    t = np.linspace(0.0, walk.duration_s, 300)
    speed = np.linalg.norm(np.diff(walk.sole_centres(t), axis=0), axis=2).max(axis=1)
    t_fast = float(t[int(np.argmax(speed))])
    cam = cfg.camera
    T = scene.T_WfromC(np.array([t_fast]))[0]
    sharp = scene.render(cam, t_fast, T)
    blurred = scene.render(cam, t_fast, T, exposure_s=0.03)
    assert np.array_equal(sharp.depth_m, blurred.depth_m)
    assert np.array_equal(sharp.label, blurred.label)
    assert np.array_equal(sharp.instance, blurred.instance)
    diff = np.abs(blurred.rgb_linear - sharp.rgb_linear).max(axis=2)
    body = sharp.label > 0
    assert body.any() and diff[body].mean() > 3 * diff[~body].mean()
    assert np.array_equal(scene.render(cam, t_fast, T, exposure_s=0.0).rgb_linear, sharp.rgb_linear)


def _digest(root: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()
    }


def test_workers_give_the_same_bytes_and_exposure_is_recorded(tmp_path: Path) -> None:
    cfg = load_config(SimConfig, CONFIG, FAST)
    one = simulate_session(cfg, 5, tmp_path / "one", workers=1).path
    two = simulate_session(cfg, 5, tmp_path / "two", workers=2).path
    assert _digest(one) == _digest(two)
    rows = np.loadtxt(one / "groundtruth" / "exposure.csv", delimiter=",", skiprows=1)
    lo, hi = cfg.camera.exposure_time_range_s
    assert len(rows) == len(list((one / "color").iterdir()))
    assert ((rows[:, 2] >= lo) & (rows[:, 2] <= hi)).all()
    assert np.allclose(rows[:, 2], np.clip(rows[:, 1] * cfg.camera.exposure_time_ref_s, lo, hi))
    off = load_config(SimConfig, CONFIG, [*FAST, "camera.motion_blur=false"])
    still = simulate_session(off, 5, tmp_path / "still", workers=2).path
    rows_off = np.loadtxt(still / "groundtruth" / "exposure.csv", delimiter=",", skiprows=1)
    assert (rows_off[:, 2] == 0).all()
    assert np.allclose(rows_off[:, 1], rows[:, 1], rtol=1e-3)  # the smear barely changes AE
    a, b = _digest(one), _digest(still)
    assert any(a[k] != b[k] for k in a if k.startswith("color/"))
    assert all(a[k] == b[k] for k in a if k.startswith(("depth/", "groundtruth/labels")))
