"""Active-stereo depth model (gaitnet/sim/sensor_depth.py) and floor relief (floor_relief.py).

Each test measures one effect on small synthetic frames and shows that its key turns it off.
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from gaitnet.config import load_config
from gaitnet.errors import ConfigError
from gaitnet.geometry import make_T, so3_exp
from gaitnet.sim.clutter import ClutterBox
from gaitnet.sim.config import SimConfig
from gaitnet.sim.floor import make_floor
from gaitnet.sim.floor_relief import FloorRelief, FloorReliefConfig, sample_floor_relief
from gaitnet.sim.render import render_frame
from gaitnet.sim.render_types import RenderResult
from gaitnet.sim.scene import Appearance, BodyState
from gaitnet.sim.sensor_depth import DepthUnit, depth_image, sample_depth_unit
from gaitnet.sim.sensor_model import SensorNoiseConfig
from gaitnet.sim.session import simulate_session

W, H, F = 160, 120, 96.0
K = np.array([[F, 0.0, (W - 1) / 2], [0.0, F, (H - 1) / 2], [0.0, 0.0, 1.0]])
FB = F * 0.095
R_PfromC_LEVEL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
APPEARANCE = Appearance((0.05, 0.08, 0.2), (0.5, 0.05, 0.04), (0.8, 0.8, 0.78))
NO_BODY = BodyState((), ())
#: Only the matching noise (every other depth effect off).
BARE = SensorNoiseConfig(
    disparity_offset_px=0.0,
    waviness_px=0.0,
    subpixel_steps=0,
    flying_fraction=0.0,
    dark_hole_prob=0.0,
    dropout_fraction=0.0,
    blob_fraction=0.0,
)
EXTENT = ((-2.0, 5.0), (-3.0, 3.0))


def camera(p, pitch_deg: float) -> np.ndarray:
    R = so3_exp([0.0, np.deg2rad(pitch_deg), 0.0]) @ R_PfromC_LEVEL
    return make_T(R, np.asarray(p, float))


def wall(z, radiance: float = 0.3, shape=(H, W)) -> RenderResult:
    """A synthetic frame: depth ``z`` (scalar or (H, W)), uniform radiance."""
    depth = np.broadcast_to(np.asarray(z, np.float32), shape).copy()
    lab = np.zeros(shape, np.uint8)
    return RenderResult(np.full((*shape, 3), radiance, np.float32), depth, lab, lab)


def err(cfg, z=1.0, seed=0, unit=None, shape=(H, W)) -> np.ndarray:
    depth = depth_image(wall(z, shape=shape), K, np.random.default_rng(seed), cfg, unit)
    return np.where(depth > 0, depth - np.asarray(z, np.float32), np.nan)


@pytest.fixture(scope="module")
def plain_floor():
    return make_floor("concrete", np.random.default_rng(0), EXTENT, texel_m=0.005,
                      room_height_m=None)  # fmt: skip


# ----------------------------------------------------------------------------- floor relief


def relief_of(seed: int = 1, family: str = "tiles", **kw) -> FloorRelief:
    cfg = FloorReliefConfig(**kw) if kw else FloorReliefConfig()
    return sample_floor_relief(np.random.default_rng(seed), cfg, family, EXTENT)


def rays(n: int, seed: int = 0, rho_max: float = 5.0):
    """Random downward rays (D_z = −1) with horizontal reach up to ``rho_max``."""
    rng = np.random.default_rng(seed)
    ang, rho = rng.uniform(0, 2 * np.pi, n), rng.uniform(0.1, rho_max, n)
    D = [(rho * np.cos(ang)).astype(np.float32), (rho * np.sin(ang)).astype(np.float32)]
    return D + [np.full(n, -1.0, np.float32)]


def test_relief_ray_intersection_is_exact_to_well_below_a_micrometre():
    relief = relief_of()
    c = np.array([0.3, 0.1, 1.0])
    D = rays(300 * 400)
    t0 = np.full(D[0].shape, 1.0, np.float32)  # the hits on z = 0 (c_z = 1, D_z = −1)
    t = relief.ray_t(t0, c, D).astype(np.float64)
    x, y = c[0] + t * D[0], c[1] + t * D[1]
    residual = c[2] - t - relief.height(x, y)  # ray height − floor height at the hit
    smooth = FloorRelief(relief.waves)
    ts = smooth.ray_t(t0, c, D).astype(np.float64)
    res_s = c[2] - ts - smooth.height(c[0] + ts * D[0], c[1] + ts * D[1])
    assert np.abs(res_s).max() < 2e-7  # float32 rounding of t ≈ 1 m; the method: ~1e-11 m
    # With tile lips: exact except in the band where the ray crosses a joint between the
    # plane hit and the relief hit (reach × |h| ≤ 5 × 3 mm), where the step is vertical.
    assert np.mean(np.abs(residual) < 2e-7) > 0.98
    assert np.abs(residual).max() <= np.abs(relief.lips).max() * 2 + 1e-6
    # First-order correction alone (one Newton step) is not enough at the far end.
    assert np.abs(t - 1.0).max() > 1e-3  # the relief moves the hit by millimetres


def test_relief_magnitudes_and_keys():
    r = relief_of()
    x, y = np.meshgrid(np.linspace(*EXTENT[0], 300), np.linspace(*EXTENT[1], 200))
    h = r.height(x, y)
    assert 0.5e-3 < np.abs(h).max() < 4e-3  # millimetres over metres

    def max_slope_deg(relief: FloorRelief) -> float:
        gy, gx = np.gradient(relief.waves_at(x, y), y[:, 0], x[0])
        return float(np.degrees(np.arctan(np.hypot(gx, gy))).max())

    assert max_slope_deg(FloorRelief(r.waves[:1])) == pytest.approx(0.2, rel=0.05)
    assert max_slope_deg(r) < 0.6
    lips = np.abs(np.diff(r.lips, axis=1)).max()
    assert 0.3e-3 < lips <= 0.6e-3
    assert relief_of(family="concrete").lips.size == 0  # no joints
    # Each key switches its part off; all zero: the plane.
    assert relief_of(slope_deg=0.0).waves.shape[0] == 2
    assert relief_of(waviness_mm=0.0).waves.shape[0] == 1
    assert not np.any(relief_of(lip_mm=0.0).lips)
    assert relief_of(slope_deg=0.0, waviness_mm=0.0, lip_mm=0.0).is_flat
    # The other parts' draws do not change when one is switched off.
    np.testing.assert_array_equal(relief_of(slope_deg=0.0).lips, r.lips)


def test_relief_in_the_render_colour_depth_agree(plain_floor):
    relief = relief_of()
    T = camera((0.0, 0.0, 1.0), 45.0)
    flat = render_frame(K, W, H, T, plain_floor, NO_BODY, APPEARANCE)
    bumpy = render_frame(K, W, H, T, plain_floor, NO_BODY, APPEARANCE, relief=relief)
    d = bumpy.depth_m - flat.depth_m
    hit = np.isfinite(flat.depth_m) & (flat.depth_m < 4.0)
    assert 0.2e-3 < np.abs(d[hit]).max() < 1e-2
    # Back-projected floor points lie on h(x, y).
    v, u = np.nonzero(hit)
    z = bumpy.depth_m[v, u].astype(np.float64)
    p = np.stack([(u - K[0, 2]) / F * z, (v - K[1, 2]) / F * z, z], axis=1)
    p_W = p @ T[:3, :3].T + T[:3, 3]
    off = np.abs(p_W[:, 2] - relief.height(p_W[:, 0], p_W[:, 1]))
    assert np.mean(off < 1e-6) > 0.98
    flat_relief = relief_of(slope_deg=0.0, waviness_mm=0.0, lip_mm=0.0)
    same = render_frame(K, W, H, T, plain_floor, NO_BODY, APPEARANCE, relief=flat_relief)
    np.testing.assert_array_equal(same.depth_m, flat.depth_m)


# ----------------------------------------------------------------------------- depth noise


def autocorr(e: np.ndarray, lag: int) -> float:
    e = e - np.nanmean(e)
    a, b = e[:, :-lag], e[:, lag:]
    m = np.isfinite(a) & np.isfinite(b)
    return float(np.sum(a[m] * b[m]) / np.sum(a[m] ** 2))


def test_noise_is_correlated_over_the_matching_window():
    e = err(BARE, shape=(240, 320))
    assert autocorr(e, 2) > 0.4 and autocorr(e, 9) < 0.15
    white = err(replace(BARE, correlated_fraction=0.0), shape=(240, 320))
    assert abs(autocorr(white, 2)) < 0.05
    single = err(replace(BARE, match_window_px=1), shape=(240, 320))
    assert abs(autocorr(single, 2)) < 0.05
    # σ_z = z² σ_d / (f b) whatever the correlation
    for e_ in (e, white):
        assert np.nanstd(e_) == pytest.approx(0.08 / FB, rel=0.1)


def test_bias_grows_with_the_square_of_the_distance_and_follows_the_unit():
    cfg = replace(BARE, disparity_noise_px=0.0)
    on = replace(cfg, disparity_offset_px=0.08)
    b1, b2 = np.nanmean(err(on, 1.0)), np.nanmean(err(on, 2.0))
    assert b1 == pytest.approx(-0.08 / FB, rel=0.05)  # depth reads short by z² Δd / (f b)
    assert b2 / b1 == pytest.approx(4.0, rel=0.05)
    flip = np.nanmean(err(on, 1.0, unit=DepthUnit(offset_sign=-1.0)))
    assert flip == pytest.approx(-b1, rel=0.05)
    assert np.nanmax(np.abs(err(cfg, 2.0))) < 1e-6


def test_waviness_is_a_smooth_distortion_of_a_flat_surface():
    cfg = replace(BARE, disparity_noise_px=0.0, waviness_px=0.05)
    e = err(cfg, 1.5)
    rms = np.sqrt(np.nanmean((e - np.nanmean(e)) ** 2))
    assert rms == pytest.approx(1.5**2 * 0.05 / FB, rel=0.05)
    assert np.nanmax(np.abs(np.diff(e, axis=1))) < rms / 10  # smooth, low order
    other = err(cfg, 1.5, unit=sample_depth_unit(np.random.default_rng(3)))
    assert np.nanmax(np.abs(other - e)) > rms / 2  # the shape depends on the unit
    assert np.nanmax(np.abs(err(replace(cfg, waviness_px=0.0), 1.5))) < 1e-6


def test_depth_is_quantised_in_disparity():
    ramp = np.broadcast_to(np.linspace(2.0, 2.6, W, dtype=np.float32), (H, W))
    cfg = replace(BARE, disparity_noise_px=0.0, subpixel_steps=32)
    depth = depth_image(wall(ramp), K, np.random.default_rng(0), cfg)
    d32 = FB / depth[H // 2].astype(np.float64) * 32
    assert np.abs(d32 - np.round(d32)).max() < 1e-3  # on the 1/32 px grid
    steps = np.diff(np.unique(depth[H // 2]))
    assert np.median(steps) == pytest.approx(2.3**2 / (32 * FB), rel=0.25)
    off = depth_image(wall(ramp), K, np.random.default_rng(0), replace(cfg, subpixel_steps=0))
    assert np.unique(off[H // 2]).size == W


def test_flying_pixels_at_depth_edges(plain_floor):
    T = camera((1.0, 0.0, 1.0), 89.999)
    box = ClutterBox((1.0, 0.0), 0.0, (0.3, 0.3, 0.5), (0.5, 0.5, 0.5))
    res = render_frame(K, W, H, T, plain_floor, NO_BODY, APPEARANCE, (box,))
    z = res.depth_m
    edge = np.zeros_like(z, bool)
    edge[:, 1:] |= np.abs(np.diff(z, axis=1)) > 0.1
    edge[:, :-1] |= np.abs(np.diff(z, axis=1)) > 0.1

    def flying(cfg) -> float:
        depth = depth_image(res, K, np.random.default_rng(0), cfg)
        d = depth[edge]
        return float(np.mean((d > 0.53) & (d < 0.97)))

    assert 0.1 < flying(replace(BARE, flying_fraction=0.3)) < 0.5
    assert flying(BARE) == 0.0


def test_holes_on_dark_and_glaring_surfaces():
    cfg = replace(BARE, dark_hole_prob=0.6)

    def holes(radiance, c=cfg) -> float:
        depth = depth_image(wall(1.5, radiance, (240, 320)), K, np.random.default_rng(0), c)
        return float((depth == 0).mean())

    assert holes(0.0) == pytest.approx(0.6, abs=0.1)
    assert 0.1 < holes(0.015) < 0.5
    assert holes(0.3) == 0.0
    assert holes(5.0) == pytest.approx(0.6, abs=0.1)
    assert holes(0.0, replace(cfg, dark_hole_prob=0.0)) == 0.0
    assert holes(0.0, replace(cfg, dark_radiance=0.0)) == 0.0
    # clustered, not salt-and-pepper: a hole's right neighbour is mostly a hole too
    depth = depth_image(wall(1.5, 0.01, (240, 320)), K, np.random.default_rng(0), cfg)
    hole = depth == 0
    assert np.mean(hole[:, 1:][hole[:, :-1]]) > 0.8


def test_plane_fit_from_one_frame_is_no_longer_exact(plain_floor):
    T = camera((0.0, 0.0, 1.0), 45.0)

    def fit(relief, cfg, unit) -> tuple[float, float]:
        res = render_frame(K, W, H, T, plain_floor, NO_BODY, APPEARANCE, relief=relief)
        depth = depth_image(res, K, np.random.default_rng(0), cfg, unit)
        v, u = np.nonzero((depth > 0) & (depth < 3.0))
        z = depth[v, u].astype(np.float64)
        p_W = np.stack([(u - K[0, 2]) / F * z, (v - K[1, 2]) / F * z, z], 1) @ T[:3, :3].T
        p_W += T[:3, 3]
        c = p_W.mean(0)
        n = np.linalg.svd(p_W - c, full_matrices=False)[2][-1]
        return float(np.degrees(np.arccos(abs(n[2])))), float(c[2])

    quiet = replace(BARE, disparity_noise_px=0.0)
    angle0, offset0 = fit(None, quiet, None)
    assert angle0 < 0.01 and abs(offset0) < 1e-4
    defaults = SensorNoiseConfig(disparity_noise_px=0.0)
    angle, offset = fit(relief_of(), defaults, DepthUnit())
    assert angle > 0.05 and abs(offset) > 1e-3


# ----------------------------------------------------------------------------- config, truth


@pytest.mark.parametrize(
    ("section", "key", "bad"),
    [
        ("sensor", "match_window_px", 0),
        ("sensor", "subpixel_steps", 300),
        ("sensor", "flying_fraction", 1.5),
        ("sensor", "glare_radiance", 0.1),
        ("floor_relief", "slope_deg", 5.0),
        ("floor_relief", "lip_mm", -1.0),
    ],
)
def test_bad_values_are_one_line_config_errors(tmp_path, section, key, bad):
    path = tmp_path / "c.yaml"
    path.write_text(f"{section}:\n  {key}: {bad}\n")
    with pytest.raises(ConfigError) as info:
        load_config(SimConfig, path)
    assert key in str(info.value) and "\n" not in str(info.value)


def test_session_writes_floor_relief_and_depth_unit(tmp_path):
    cfg = load_config(SimConfig, None)
    cfg = replace(
        cfg,
        camera=replace(cfg.camera, width=64, height=48, fx=38.6, fy=38.6, cx=31.5, cy=23.5),
        gait=replace(cfg.gait, walk_length_m=3.0, stand_start_s=1.0, stand_end_s=1.0),
        scene=replace(cfg.scene, floor_family="tiles", clutter_count=0, texel_m=0.01),
        output=replace(cfg.output, labels=False, preview_frames=0),
    )
    out = simulate_session(cfg, 3, tmp_path / "s").path
    relief = json.loads((out / "groundtruth" / "floor_relief.json").read_text())
    waves = np.array([[w["amplitude_m"], w["kx_rad_per_m"], w["ky_rad_per_m"], w["phase_rad"]]
                      for w in relief["waves"]])  # fmt: skip
    rebuilt = FloorRelief(waves, tuple(relief["lip_origin_m"]), tuple(relief["lip_pitch_m"]),
                          np.array(relief["lips_m"]))  # fmt: skip
    assert waves.shape == (3, 4) and np.array(relief["lips_m"]).size > 0
    x, y = np.random.default_rng(0).uniform(0, 1, (2, 50))
    assert np.abs(rebuilt.height(x, y)).max() > 0
    unit = json.loads((out / "groundtruth" / "depth_unit.json").read_text())
    assert abs(unit["disparity_offset_px"]) == pytest.approx(0.08)
    assert len(unit["waviness_coefficients"]) == 5
