"""simulate-dataset: files, labelme polygons, and every config key it accepts acting on the frames.

The command writes what :func:`simulate_frame` renders (first test), so the per-key tests render
single frames with the key set and check its effect there.
"""

from __future__ import annotations

import csv
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from gaitnet.config import load_config, parse_config
from gaitnet.errors import ConfigError, GaitnetError, InputError
from gaitnet.geometry import project
from gaitnet.io.labelme_io import read_labelme, read_labels_txt
from gaitnet.io.types import tag_corners_in_board
from gaitnet.sim import dataset as dataset_module
from gaitnet.sim.config import SimConfig
from gaitnet.sim.dataset import SINGLE_FRAME_UNUSED, simulate_dataset, simulate_frame
from gaitnet.sim.floor import FLOOR_FAMILIES
from gaitnet.sim.render_types import Lighting

ROOT = Path(__file__).parents[1]
TINY = ROOT / "configs" / "sim" / "tiny.yaml"
DEFAULT = ROOT / "configs" / "sim" / "default.yaml"
LUMA = np.array([0.2126, 0.7152, 0.0722])


def tiny(*overrides: str) -> SimConfig:
    return load_config(SimConfig, TINY, list(overrides))


def read_rows(root: Path) -> list[dict[str, str]]:
    return list(csv.DictReader((root / "frames.csv").read_text().splitlines()))


def frame_pixels(root: Path, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rgb = cv2.cvtColor(cv2.imread(str(root / "images" / f"{name}.png")), cv2.COLOR_BGR2RGB)
    depth = cv2.imread(str(root / "depth" / f"{name}.png"), cv2.IMREAD_UNCHANGED)
    labels = cv2.imread(str(root / "labels" / f"{name}.png"), cv2.IMREAD_UNCHANGED)
    return rgb, depth, labels


def points_W(frame, mask: np.ndarray) -> np.ndarray:
    """World points of the noise-free depth at ``mask`` pixels."""
    K = np.linalg.inv(frame.K)
    v, u = np.nonzero(mask)
    z = frame.render.depth_m[v, u].astype(np.float64)
    p_C = (K @ np.stack([u, v, np.ones_like(u)]).astype(np.float64)).T * z[:, None]
    return p_C @ frame.T_WfromC[:3, :3].T + frame.T_WfromC[:3, 3]


def render(cfg: SimConfig, seed: int = 5, index: int = 0, t_s: float | None = None):
    return simulate_frame(cfg, seed, index, t_s)


# ----------------------------------------------------------------------------- the command


def test_dataset_files_match_simulate_frame_and_labelme(tmp_path: Path) -> None:
    cfg = tiny("mount.pitch_deg=[62, 72]", "output.preview_frames=2")
    result = simulate_dataset(cfg, 3, seed=7, out_dir=tmp_path / "ds", labelme=True)
    root = result.path
    assert read_labels_txt(root / "labels.txt")["foot"] == 1
    rows = read_rows(root)
    assert [r["id"] for r in rows] == ["000000", "000001", "000002"]
    assert (root / "preview.png").is_file()
    for i, row in enumerate(rows):
        name = row["id"]
        rgb, depth, labels = frame_pixels(root, name)
        frame = simulate_frame(cfg, 7, i)
        assert np.array_equal(rgb, frame.rgb) and np.array_equal(labels, frame.render.label)
        expected_mm = np.round(frame.depth_m * 1000).astype(np.uint16)
        assert depth.dtype == np.uint16 and np.abs(depth.astype(int) - expected_mm).max() <= 1
        g = np.array([float(row[k]) for k in ("gravity_cx", "gravity_cy", "gravity_cz")])
        assert np.allclose(g, frame.gravity_C(), atol=1e-8)
        assert 62.0 <= float(row["pitch_deg"]) <= 72.0
        assert row["floor_family"] == frame.scene.floor_family
        cls, _, image = read_labelme(root / "images" / f"{name}.json")
        assert image == (root / "images" / f"{name}.png").resolve()
        for value in (1, 2):
            truth = labels == value
            if truth.sum() > 200:
                inter = (truth & (cls == value)).sum()
                assert inter / (truth | (cls == value)).sum() > 0.85
    assert 0.0 < result.label_fractions["leg"] < 0.5
    # The resolved config reproduces the keys that acted; the unused ones are left out.
    text = (root / "dataset_config.yaml").read_text()
    data = yaml.safe_load(text)
    assert "imu" not in data and "fps" not in data["camera"] and "labels" not in data["output"]
    assert parse_config(SimConfig, data, "dataset_config.yaml") == cfg
    assert "--seed 7 --n 3 --labelme" in text.splitlines()[0]


def test_output_compress_frames_deflates_images_and_depth_only(tmp_path: Path) -> None:
    """Same pixels either way; compressed colour and depth files are smaller, labels equal."""
    roots = {
        flag: simulate_dataset(tiny(f"output.compress_frames={flag}"), 1, 2, tmp_path / flag).path
        for flag in ("true", "false")
    }
    for got, want in zip(
        frame_pixels(roots["true"], "000000"), frame_pixels(roots["false"], "000000"), strict=True
    ):
        np.testing.assert_array_equal(got, want)
    for sub in ("images", "depth"):
        small, large = ((roots[f] / sub / "000000.png").stat().st_size for f in ("true", "false"))
        assert small < 0.8 * large, sub
    for sub in ("labels", "instances"):
        assert (roots["true"] / sub / "000000.png").read_bytes() == (
            roots["false"] / sub / "000000.png"
        ).read_bytes()


def test_pitch_range_argument_replaces_mount_pitch_and_is_recorded(tmp_path: Path) -> None:
    cfg = tiny("mount.pitch_deg=80", "output.preview_frames=0")
    root = simulate_dataset(cfg, 4, 1, tmp_path / "ds", pitch_range_deg=(40.0, 45.0)).path
    pitches = [float(r["pitch_deg"]) for r in read_rows(root)]
    assert all(40.0 <= p <= 45.0 for p in pitches) and len(set(pitches)) == 4
    assert yaml.safe_load((root / "dataset_config.yaml").read_text())["mount"]["pitch_deg"] == [
        40.0,
        45.0,
    ]
    assert not (root / "preview.png").exists()  # output.preview_frames=0
    fixed = simulate_dataset(tiny("mount.pitch_deg=33"), 2, 1, tmp_path / "fixed").path
    pitches = [float(r["pitch_deg"]) for r in read_rows(fixed)]
    assert pitches == [33.0, 33.0]


@pytest.mark.parametrize(
    "override",
    ["camera.fps=15", "imu.rate_hz=400", "imu.noise_free=true", "mount.imu_rpy_deg=[0, 0, 90]",
     "mount.imu_in_camera_m=[0, 0, 0]", "scene.exposure_drift=0.1", "output.labels=false"],
)  # fmt: skip
def test_keys_meaningless_for_single_frames_are_refused(tmp_path: Path, override: str) -> None:
    key = override.split("=")[0]
    assert any(key.startswith(k) for k in SINGLE_FRAME_UNUSED)
    with pytest.raises(ConfigError, match=f"'{key}'"):
        simulate_dataset(tiny(override), 1, 0, tmp_path / "ds")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("n", "seed", "pitch", "message"),
    [(0, 0, None, "--n"), (-3, 0, None, "--n"), (1, -1, None, "--seed"),
     (1, 2**32, None, "--seed"), (1, True, None, "--seed"), (1, 0, (50.0, 40.0), "--pitch"),
     (1, 0, (5.0, 40.0), "--pitch"), (1, 0, (float("nan"), 40.0), "--pitch")],
)  # fmt: skip
def test_bad_arguments_are_input_errors_before_anything_is_written(
    tmp_path: Path, n: int, seed: int, pitch, message: str
) -> None:
    with pytest.raises(InputError, match=message):
        simulate_dataset(tiny(), n, seed, tmp_path / "ds", pitch_range_deg=pitch)
    assert list(tmp_path.iterdir()) == []


def test_output_path_that_is_a_file_is_refused(tmp_path: Path) -> None:
    target = tmp_path / "file"
    target.write_text("keep")
    with pytest.raises(GaitnetError, match="not a folder"):
        simulate_dataset(tiny(), 1, 0, target)
    assert target.read_text() == "keep" and sorted(p.name for p in tmp_path.iterdir()) == ["file"]


def test_exception_mid_run_leaves_nothing(tmp_path: Path, monkeypatch) -> None:
    real = dataset_module.simulate_frame

    def failing(cfg, seed, index, t_s=None):
        if index == 1:
            raise RuntimeError("boom")
        return real(cfg, seed, index, t_s)

    monkeypatch.setattr(dataset_module, "simulate_frame", failing)
    with pytest.raises(RuntimeError, match="boom"):
        simulate_dataset(tiny(), 3, 0, tmp_path / "ds")
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------- keys that act


@pytest.mark.parametrize("family", FLOOR_FAMILIES)
def test_scene_floor_family_sets_the_floor(family: str) -> None:
    frame = render(tiny(f"scene.floor_family={family}"))
    assert frame.scene.floor_family == family == frame.scene.floor.family


def _floor_contrast(frame) -> float:
    """Fine detail on the floor: std of high-passed luminance over the mean, on floor pixels
    away from edges."""
    lum = (frame.render.rgb_linear @ LUMA).astype(np.float32)
    detail = lum - cv2.GaussianBlur(lum, (0, 0), 3)
    floor = (frame.render.label == 0) & np.isfinite(frame.render.depth_m)
    floor = cv2.erode(floor.astype(np.uint8), np.ones((7, 7), np.uint8)).astype(bool)
    return float(np.std(detail[floor]) / np.mean(lum[floor]))


def test_floor_family_changes_the_floor_appearance_and_random_varies_it() -> None:
    keys = ("gait.walk_length_m=3", "scene.clutter_count=0", "scene.apriltag_boards=false",
            "scene.texel_m=0.004")  # fmt: skip
    contrast = {
        family: _floor_contrast(
            render(load_config(SimConfig, DEFAULT, [*keys, f"scene.floor_family={family}"]))
        )
        for family in FLOOR_FAMILIES
    }
    plain = contrast.pop("textureless")
    assert all(c > 3 * plain for c in contrast.values()), (plain, contrast)
    families = {render(tiny("scene.floor_family=random"), index=i).scene.floor_family
                for i in range(12)}  # fmt: skip
    assert len(families) >= 2


def test_scene_room_off_leaves_no_wall_pixels() -> None:
    # Pitched up to 15°: the top of the image looks above the horizon, at walls or at nothing.
    keys = ("mount.pitch_deg=15", "scene.clutter_count=0", "scene.apriltag_boards=false")
    with_room = render(tiny(*keys, "scene.room=true"))
    without = render(tiny(*keys, "scene.room=false"))
    for frame, room in ((with_room, True), (without, False)):
        background = frame.render.label == 0
        hit = background & np.isfinite(frame.render.depth_m)
        z = points_W(frame, hit)[:, 2]
        walls = np.count_nonzero(z > 0.05)
        sky = np.count_nonzero(background & ~np.isfinite(frame.render.depth_m))
        if room:
            assert walls > 0.05 * background.sum() and sky == 0
        else:
            assert walls == 0 and sky > 0.05 * background.sum()


def test_scene_lighting_variation_off_gives_the_default_lighting() -> None:
    fixed = [render(tiny("scene.lighting_variation=false"), index=i).scene.light for i in range(3)]
    assert all(light == Lighting() for light in fixed)
    varied = [render(tiny("scene.lighting_variation=true"), index=i).scene.light for i in range(3)]
    assert all(light != Lighting() for light in varied) and varied[0] != varied[1]


def _board_region_contrast(frame, board) -> float:
    corners = np.concatenate([tag_corners_in_board(board, i) for i in range(35)])
    T = board.T_WfromBoard
    p_W = corners @ T[:3, :3].T + T[:3, 3]
    T_CfromW = np.linalg.inv(frame.T_WfromC)
    uv, ok = project(frame.K, p_W @ T_CfromW[:3, :3].T + T_CfromW[:3, 3])
    assert ok.all()
    (u0, v0), (u1, v1) = np.floor(uv.min(0)).astype(int), np.ceil(uv.max(0)).astype(int)
    lum = frame.render.rgb_linear[v0:v1, u0:u1] @ LUMA
    return float(np.percentile(lum, 95) / np.percentile(lum, 5))


def test_scene_apriltag_boards_put_tags_in_view_or_not() -> None:
    # Full-size camera at the start (standing behind the first sheet), plain floor.
    keys = ("gait.walk_length_m=3", "scene.floor_family=textureless", "scene.clutter_count=0")
    on = load_config(SimConfig, DEFAULT, [*keys, "scene.apriltag_boards=true"])
    off = load_config(SimConfig, DEFAULT, [*keys, "scene.apriltag_boards=false"])
    with_tags, without = render(on, t_s=0.0), render(off, t_s=0.0)
    assert len(with_tags.scene.boards) == 2 and len(with_tags.scene.floor.sheets) == 2
    assert without.scene.boards == () and without.scene.floor.sheets == ()
    board = with_tags.scene.boards[0]  # the walk (and so the board's place) is the same
    assert _board_region_contrast(with_tags, board) > 4.0  # black ink on white paper
    assert _board_region_contrast(without, board) < 2.0  # plain floor
    size = load_config(SimConfig, DEFAULT, [*keys, "scene.tag_size_m=0.03", "scene.tag_gap_m=0.02"])
    small = render(size, t_s=0.0).scene.boards[0]
    assert (small.tag_size_m, small.gap_m) == (0.03, 0.02)


def test_scene_clutter_shoe_colour_exposure_and_texel_keys() -> None:
    assert len(render(tiny("scene.clutter_count=0")).scene.clutter) == 0
    assert len(render(tiny("scene.clutter_count=5")).scene.clutter) == 5
    assert render(tiny("scene.texel_m=0.01")).scene.floor.texel_m == 0.01
    like = render(tiny("scene.shoe_like_floor_prob=1")).scene
    floor_lin = like.floor.levels[-1][..., :3].reshape(-1, 3).mean(0) / 255.0
    shoe = np.asarray(like.appearance.shoe_rgb)
    assert np.all(shoe <= (floor_lin**2.2) * 1.4 + 0.02) and np.all(shoe >= (floor_lin**2.2) * 0.6)
    dark = render(tiny("scene.exposure_range=[0.5, 0.5]"))
    bright = render(tiny("scene.exposure_range=[2.0, 2.0]"))
    assert dark.scene.exposure_gain == 0.5 and bright.scene.exposure_gain == 2.0
    assert bright.rgb.mean() > 1.3 * dark.rgb.mean()


def test_subject_height_scales_the_legs() -> None:
    short = render(tiny("subject.height_m=1.5"), t_s=0.0)
    tall = render(tiny("subject.height_m=2.0"), t_s=0.0)
    assert short.scene.subject.height_m == 1.5 and tall.scene.subject.height_m == 2.0
    # Same seed: same proportions, so standing hip, knee and ankle heights scale with height.
    j_short = short.scene.walk.joints(np.array([0.0]))[0]  # (9, 3), SMPL 0, 1, 2, 4, 5, ...
    j_tall = tall.scene.walk.joints(np.array([0.0]))[0]
    for k in (1, 2, 3, 4):  # hips and knees (SMPL 1, 2, 4, 5)
        assert j_tall[k, 2] / j_short[k, 2] == pytest.approx(2.0 / 1.5, rel=0.02)
    # The camera (0.05 m above the pelvis joint) rises with the pelvis.
    up = 0.05
    ratio = (tall.T_WfromC[2, 3] - up) / (short.T_WfromC[2, 3] - up)
    assert ratio == pytest.approx(4 / 3, rel=0.02)
    heights = {render(tiny("subject.height_range_m=[1.6, 1.65]"), index=i).scene.subject.height_m
               for i in range(5)}  # fmt: skip
    assert all(1.6 <= h <= 1.65 for h in heights) and len(heights) == 5


@pytest.mark.parametrize("pitch", [20.0, 45.0, 80.0])
def test_mount_pitch_sets_the_gravity_direction(pitch: float) -> None:
    # Standing upright at the start: gravity in the camera is (0, cos p, sin p).
    g = render(tiny(f"mount.pitch_deg={pitch}"), t_s=0.0).gravity_C()
    p = np.radians(pitch)
    assert np.allclose(g, [0.0, np.cos(p), np.sin(p)], atol=0.02)


def test_mount_yaw_roll_offset_and_camera_intrinsics_in_the_pixels() -> None:
    """Where the floor meets the horizon in the image follows the pose and K exactly: a
    background pixel has finite depth iff its ray points below the horizon (no room)."""
    keys = ("scene.room=false", "scene.clutter_count=0", "scene.apriltag_boards=false")
    variants = [
        ("mount.pitch_deg=15",),
        ("mount.pitch_deg=20", "mount.roll_deg=12", "mount.yaw_deg=-25"),
        ("mount.pitch_deg=18", "camera.fx=80", "camera.fy=120", "camera.cx=70", "camera.cy=40"),
        ("mount.pitch_deg=18", "camera.width=96", "camera.height=64", "camera.cx=47.5",
         "camera.cy=31.5", "mount.offset_m=[0.3, 0.1, 0.2]"),
    ]  # fmt: skip
    for extra in variants:
        cfg = tiny(*keys, *extra)
        frame = render(cfg, t_s=0.0)
        h, w = cfg.camera.height, cfg.camera.width
        assert frame.rgb.shape == (h, w, 3) and frame.depth_m.shape == (h, w)
        u, v = np.meshgrid(np.arange(w), np.arange(h))
        rays_C = (
            np.stack([u, v, np.ones_like(u)], -1).reshape(-1, 3)
            @ np.linalg.inv(cfg.camera.intrinsics().K).T
        )
        down = (rays_C @ frame.T_WfromC[:3, :3].T)[:, 2].reshape(h, w) < 0
        background = frame.render.label == 0
        finite = np.isfinite(frame.render.depth_m)
        assert np.mean((down != finite)[background]) < 0.01, extra
        assert down[background].any() and (~down[background]).any(), extra
    # offset: the camera sits at the given point of the standing pelvis (upright, facing +x)
    cfg = tiny("mount.offset_m=[0.3, 0.1, 0.2]")
    frame = render(cfg, t_s=0.0)
    R_WP, p_P = frame.scene.walk.pelvis_pose(np.array([0.0]))
    offset_P = R_WP[0].T @ (frame.T_WfromC[:3, 3] - p_P[0])
    assert np.allclose(offset_P, [0.3, 0.1, 0.2], atol=1e-9)


def test_gait_keys_reach_the_walk() -> None:
    slow = render(tiny("gait.speed_mps=0.8")).scene.walk
    fast = render(tiny("gait.speed_mps=1.6")).scene.walk
    assert fast.duration_s < slow.duration_s - 1.0
    long_stand = render(tiny("gait.stand_start_s=3")).scene.walk
    assert long_stand.duration_s > render(tiny()).scene.walk.duration_s + 1.5
    for index in range(4):  # frames are drawn inside the walking phase
        cfg = tiny("gait.stand_start_s=3", "gait.stand_end_s=2")
        frame = render(cfg, index=index)
        assert 3.5 <= frame.t_s <= frame.scene.walk.duration_s - 2.5


def test_sensor_keys_shape_the_delivered_images() -> None:
    near = render(tiny("sensor.max_range_m=2", "sensor.min_range_m=1"))
    valid = near.depth_m[near.depth_m > 0]
    assert valid.size > 0 and valid.min() >= 1.0 - 0.05 and valid.max() <= 2.0 + 0.05
    blue = render(tiny("sensor.white_balance=[1, 1, 0.3]")).rgb.reshape(-1, 3).mean(0)
    neutral = render(tiny()).rgb.reshape(-1, 3).mean(0)
    assert blue[2] / blue[0] < 0.8 * neutral[2] / neutral[0]


#: Keys added by the realism pass, each with a valid value other than its default. Each must
#: change what a data-set frame delivers (colour, depth or labels) or be refused above.
REALISM_KEYS = [
    "camera.motion_blur=false", "camera.exposure_time_ref_s=0.03",
    "camera.exposure_time_range_s=[0.001, 0.002]",
    "floor_relief.slope_deg=1.5", "floor_relief.waviness_mm=4", "floor_relief.lip_mm=2.5",
    "mount.impact_peak_g=5", "mount.impact_freq_hz=8", "mount.impact_damping_ratio=0.9",
    "mount.wobble_freq_hz=1.5", "mount.wobble_damping_ratio=0.9", "mount.wobble_gain=1",
    "mount.wobble_tilt_deg_per_mm=3",
    "gait.variability=0", "gait.stand_width_m=0.35", "gait.toe_off_ankle_deg=-25",
    "gait.push_off_ankle_deg=-29", "gait.swing_ankle_deg=12", "gait.sway_ap_rms_m=0.015",
    "gait.sway_ml_rms_m=0.015",
    "sensor.correlated_fraction=0", "sensor.match_window_px=21", "sensor.disparity_offset_px=0.8",
    "sensor.waviness_px=0.4", "sensor.subpixel_steps=4", "sensor.flying_fraction=1",
    "sensor.dark_radiance=0.5", "sensor.glare_radiance=0.6", "sensor.dark_hole_prob=0",
    "sensor.hole_cluster_px=40",
]  # fmt: skip


@pytest.mark.parametrize("override", REALISM_KEYS)
def test_realism_keys_act_on_dataset_frames(override: str) -> None:
    common = ["scene.floor_family=tiles"] if "lip_mm" in override else []  # joints: tiles, wood
    base = [render(tiny(*common), index=i) for i in range(2)]
    changed = [render(tiny(*common, override), index=i) for i in range(2)]
    differs = any(
        not np.array_equal(a.rgb, b.rgb)
        or not np.array_equal(a.depth_m, b.depth_m)
        or not np.array_equal(a.render.label, b.render.label)
        for a, b in zip(base, changed, strict=True)
    )
    assert differs, f"{override} does not change any data-set frame"
