"""``run_vio`` and ``gaitnet vio`` end to end: accuracy on a realistic session, and every
degradation the issue lists (no tags, frames without depth, an IMU gap, a texture-poor floor,
a diverging filter) runs to the end with its reason logged, or stops with one clear error."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from gaitnet.cli import main
from gaitnet.config import load_config
from gaitnet.evaluation.metrics import ate_yaw_aligned, match_times
from gaitnet.io import open_session
from gaitnet.io.trajectory import read_tum
from gaitnet.io.types import Frame, ImuSamples
from gaitnet.vio.config import VioConfig
from gaitnet.vio.errors import FilterDivergedError
from gaitnet.vio.report import write_result
from gaitnet.vio.run import run_vio

ROOT = Path(__file__).resolve().parents[1]


class _Edited:
    """A session source with edited calibration, IMU or frames (the rest delegated)."""

    def __init__(self, source, calibration=None, imu=None, frame_edit=None) -> None:
        self._source = source
        self._calibration = calibration
        self._imu = imu
        self._frame_edit = frame_edit

    @property
    def calibration(self):
        return self._calibration or self._source.calibration

    @property
    def frame_times_ns(self):
        return self._source.frame_times_ns

    @property
    def imu(self):
        return self._imu or self._source.imu

    def __len__(self) -> int:
        return len(self._source)

    def frame(self, index: int) -> Frame:
        f = self._source.frame(index)
        return self._frame_edit(f) if self._frame_edit else f

    def frames(self):
        for i in range(len(self)):
            yield self.frame(i)


def _finite(result) -> bool:
    arrays = [result.T_WfromC_filter, result.T_WfromC_imu_only, result.T_WfromC]
    return all(np.all(np.isfinite(a)) for a in arrays) and all(
        np.all(np.isfinite(s.xy)) for s in result.stance_feet
    )


@pytest.fixture(scope="module")
def walk(tmp_path_factory) -> Path:
    """A realistic 640×480 session: 2 m walk on a textured floor with tag sheets."""
    from gaitnet.sim.config import SimConfig
    from gaitnet.sim.session import simulate_session

    cfg = load_config(
        SimConfig,
        ROOT / "configs" / "sim" / "default.yaml",
        [
            "gait.walk_length_m=3.0",
            "gait.stand_start_s=1.0",
            "gait.stand_end_s=1.0",
            "scene.floor_family=tiles",
            "output.preview_frames=2",
        ],
    )
    out = tmp_path_factory.mktemp("vio") / "walk"
    simulate_session(cfg, 7, out)
    return out


@pytest.fixture(scope="module")
def walk_result(walk: Path):
    """The default run (filter then smoother) on the walk."""
    return run_vio(open_session(walk), VioConfig())


def _ate(walk: Path, t_s: np.ndarray, T_WfromC: np.ndarray) -> float:
    truth = np.loadtxt(walk / "groundtruth" / "camera_frames.tum")
    i, j = match_times(np.round(t_s * 1e9), np.round(truth[:, 0] * 1e9))
    return ate_yaw_aligned(T_WfromC[i, :3, 3], truth[j, 1:4])


def test_walk_strides_and_stance_feet_match_the_truth(
    walk: Path, walk_result, tmp_path: Path
) -> None:
    import csv

    result = walk_result
    assert result.initialisation == "apriltag" and _finite(result)
    events = list(csv.DictReader((walk / "groundtruth" / "events.csv").open()))
    soles = np.array([[float(e["sole_x_m"]), float(e["sole_y_m"])] for e in events])
    for foot in result.stance_feet:  # each landmark lies on a true flat sole of its side
        same = [i for i, e in enumerate(events) if e["side"] == foot.side]
        d = np.linalg.norm(soles[same] - foot.xy, axis=1).min()
        assert d < 0.05, f"{foot.side} stance at {foot.xy} is {d:.3f} m from every true sole"
    assert len(result.stance_feet) >= len(events) - 2
    out = write_result(result, tmp_path / "out", "x: 1\n")
    assert (
        main(["evaluate", str(out), "--session", str(walk), "--json", str(tmp_path / "m.json")])
        == 0
    )
    metrics = json.loads((tmp_path / "m.json").read_text())
    assert metrics["stride_rmse_m"]["all"] < 0.03  # thesis: 3.8 cm on real data
    assert metrics["body_ate_m"] < 0.05
    assert sum(metrics["n_strides"].values()) >= 3
    t, T = read_tum(out / "camera_frames.tum")
    assert len(t) == len(open_session(walk)) and np.all(np.isfinite(T))
    assert (out / "trajectory.png").stat().st_size > 10_000


def test_a_stance_counts_the_sightings_before_its_confirmation(walk: Path, walk_result) -> None:
    """``filter.min_foot_observations`` counts the frames the stance's track saw the foot
    before the stance was confirmed (a brisk real walk's 0.14 s foot flat leaves too few
    updates after it). With every foot update after the confirmation refused by a gate of
    probability 1e-9, the stances are still reported, each on a true sole of its side, with
    as many sightings as they had at the confirmation (three frames at 30 Hz at least)."""
    import csv

    refused = run_vio(
        open_session(walk), load_config(VioConfig, None, ["filter.foot_gate_probability=1e-9"])
    )
    assert refused.skipped.get("foot", {}).get("outside the chi2 gate", 0) > 0
    events = list(csv.DictReader((walk / "groundtruth" / "events.csv").open()))
    soles = {s: np.array([[float(e["sole_x_m"]), float(e["sole_y_m"])] for e in events
                          if e["side"] == s]) for s in ("left", "right")}  # fmt: skip
    assert len(refused.stance_feet) >= len(events) - 2
    for foot in refused.stance_feet:
        assert foot.n_observations >= 3
        assert np.linalg.norm(soles[foot.side] - foot.xy, axis=1).min() < 0.05
    by_default = {round(f.t_first_s, 3): f.n_observations for f in walk_result.stance_feet}
    for foot in refused.stance_feet:  # the default run adds its accepted updates
        if round(foot.t_first_s, 3) in by_default:
            assert by_default[round(foot.t_first_s, 3)] > foot.n_observations


def test_the_smoother_improves_on_the_filter(walk: Path, walk_result) -> None:
    """Sec. 3.5: smoothing all frames with every measurement the filter accepted gives a body
    trajectory closer to the truth than the filter's, and it lands in ``camera_frames.tum``
    (``T_WfromC``); the stance feet it reports are the smoothed landmarks."""
    r = walk_result
    assert r.smoother["ran"] and r.T_WfromC_smoothed is not None
    assert r.T_WfromC is r.T_WfromC_smoothed
    ate_smoothed = _ate(walk, r.t_s, r.T_WfromC_smoothed)
    ate_filter = _ate(walk, r.t_s, r.T_WfromC_filter)
    assert ate_smoothed < ate_filter
    assert ate_smoothed < 0.02
    costs = r.smoother["cost_per_iteration"]
    assert costs[-1] < costs[0]  # Gauss–Newton from the filter's estimates lowers the cost
    by_id = {f.landmark_id: f for f in r.stance_feet_filter}
    moved = [np.linalg.norm(f.xy - by_id[f.landmark_id].xy) for f in r.stance_feet]
    assert len(moved) == len(by_id) and max(moved) > 0.0


def test_smoother_keys_act(tiny_sim_session: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``smoother.enabled=false`` reports the filter's estimates; the iteration keys reach
    the smoother's options (their effect: tests/test_vio_smoother.py)."""
    import gaitnet.vio.run as run_module

    source = open_session(tiny_sim_session)
    off = run_vio(source, load_config(VioConfig, None, ["smoother.enabled=false"]))
    assert off.T_WfromC_smoothed is None and off.smoother == {}
    assert off.T_WfromC is off.T_WfromC_filter
    assert [f.xy.tolist() for f in off.stance_feet] == [
        f.xy.tolist() for f in off.stance_feet_filter
    ]
    seen = []
    real_smooth = run_module.smooth
    monkeypatch.setattr(
        run_module, "smooth", lambda rec, opts: seen.append(opts) or real_smooth(rec, opts)
    )
    keys = ["smoother.max_iterations=7", "smoother.step_tol=0.125"]
    on = run_vio(source, load_config(VioConfig, None, keys))
    assert on.smoother["ran"] and on.T_WfromC_smoothed is not None
    assert [(o.max_iterations, o.step_tol) for o in seen] == [(7, 0.125)]


def test_without_tags_the_filter_starts_from_gravity_and_the_floor(walk: Path) -> None:
    source = open_session(walk)
    calib = dataclasses.replace(source.calibration, apriltag_boards=())
    result = run_vio(_Edited(source, calibration=calib), VioConfig())
    assert result.initialisation == "gravity_floor"
    assert "no AprilTag board" in result.initialisation_note and _finite(result)
    truth = np.loadtxt(walk / "groundtruth" / "camera_frames.tum")
    assert result.T_WfromC_filter[0, 2, 3] == pytest.approx(truth[0, 3], abs=0.03)  # height


def test_frames_without_depth_and_an_imu_gap_are_survived(tiny_sim_session: Path) -> None:
    source = open_session(tiny_sim_session)
    imu = source.imu
    t = imu.t_ns
    gap = (t > t[0] + int(2.0e9)) & (t < t[0] + int(2.3e9))
    holed = ImuSamples(t[~gap], imu.accel[~gap], imu.gyro[~gap])

    def no_depth(f: Frame) -> Frame:
        if 5 <= f.index < 9:
            return dataclasses.replace(f, depth_m=np.zeros_like(f.depth_m))
        return f

    seen: list[tuple[int, np.ndarray]] = []
    result = run_vio(
        _Edited(source, imu=holed, frame_edit=no_depth),
        VioConfig(),
        on_frame=lambda frame, T: seen.append((frame.index, T.copy())),
    )
    assert _finite(result)
    assert result.skipped["frame"]["no floor plane"] >= 4
    # on_frame: once per processed frame, in order, with the filter's pose of that frame
    assert [i for i, _ in seen] == list(result.session_index)
    np.testing.assert_allclose(np.array([T for _, T in seen]), result.T_WfromC_filter, atol=1e-12)


def test_textureless_floor_runs_to_the_end_with_odometry_skips(tmp_path: Path) -> None:
    from gaitnet.sim.config import SimConfig
    from gaitnet.sim.session import simulate_session

    cfg = load_config(
        SimConfig,
        ROOT / "configs" / "sim" / "tiny.yaml",
        ["scene.floor_family=textureless", "camera.fps=10", "output.preview_frames=2"],
    )
    simulate_session(cfg, 4, tmp_path / "s")
    result = run_vio(open_session(tmp_path / "s"), VioConfig())
    assert _finite(result)
    assert sum(result.skipped.get("vo", {}).values()) > 0


def test_a_diverging_filter_stops_with_one_error_and_writes_nothing(
    tiny_sim_session: Path, tmp_path: Path, capsys
) -> None:
    source = open_session(tiny_sim_session)
    imu = source.imu
    accel = imu.accel.copy()
    accel[len(accel) // 2] = np.nan  # a corrupt sample the reader did not catch
    with pytest.raises(FilterDivergedError):
        run_vio(_Edited(source, imu=ImuSamples(imu.t_ns, accel, imu.gyro)), VioConfig())


def test_config_switches_act(tiny_sim_session: Path) -> None:
    source = open_session(tiny_sim_session)
    off = load_config(VioConfig, None, ["filter.use_vo=false", "filter.use_feet=false"])
    result = run_vio(source, off)
    assert "vo" not in result.used and "vo" not in result.skipped and not result.stance_feet
    on = run_vio(source, VioConfig())  # at 6 Hz the odometry is attempted (and mostly refused)
    assert on.used["vo"] + sum(on.skipped.get("vo", {}).values()) == len(source) - 1


def test_cli_vio_writes_every_output(tiny_sim_session: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "vio"
    # overrides may follow --out (argparse alone would refuse them there)
    assert main(["vio", str(tiny_sim_session), "--out", str(out), "smoother.enabled=false"]) == 0
    assert "smoother:\n  enabled: false" in (out / "vio_config.yaml").read_text()
    for name in (
        "camera_frames.tum",
        "filter_frames.tum",
        "imu_only_frames.tum",
        "stance_feet.csv",
        "strides.csv",
        "summary.json",
        "trajectory.png",
        "vio_config.yaml",
    ):
        assert (out / name).is_file(), name
    summary = json.loads((out / "summary.json").read_text())
    assert summary["frames"] == len(open_session(tiny_sim_session))
    assert main(["vio", str(tiny_sim_session), "--out", str(out)]) == 1  # exists
    assert main(["vio", str(tiny_sim_session), "--out", str(tmp_path / "x"), "filter.foo=1"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("gaitnet vio: error:") and "filter.foo" in err[-1]


def test_tag_gate_refuses_a_pose_metres_off(
    tiny_sim_session: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """After sheets seen where the filter expects them, a wrong decode reporting the camera
    2 m away with a confident covariance is refused by the default loose gate
    (``filter.tag_gate_probability``); without a gate it is accepted and followed."""
    import gaitnet.vio.apriltags as apriltags
    from gaitnet.vio.apriltags import TagObservation

    source = open_session(tiny_sim_session)
    assert source.calibration.apriltag_boards and len(source) > 12
    board = source.calibration.apriltag_boards[0].name

    def decoded(frame, calib, params, T_WfromC_guess=None):
        if T_WfromC_guess is None:  # initialisation: no board, gravity and floor instead
            return None
        T = np.array(T_WfromC_guess, dtype=np.float64)
        if frame.index >= 8:
            T[0, 3] += 2.0
        cov6 = np.diag([1e-4] * 3 + [1e-4] * 3)
        empty = np.zeros(0)
        return TagObservation(board, T, cov6, 4, 0.2, 0.25, empty, empty, empty)

    monkeypatch.setattr(apriltags, "detect_board_pose", decoded)
    gated = run_vio(source, VioConfig())
    # refused while the filter is sure of where it is (IMU-only at 6 Hz, its covariance grows
    # until, seconds later, 2 m becomes plausible)
    assert gated.used["tag"] >= 7 and gated.skipped["tag"]["outside the chi2 gate"] >= 5
    ungated = run_vio(source, load_config(VioConfig, None, ["filter.tag_gate_probability=0"]))
    assert ungated.used["tag"] == len(ungated.t_s) - 1 and "tag" not in ungated.skipped
    k = int(np.searchsorted(gated.session_index, 10))
    shift = ungated.T_WfromC_filter[k, 0, 3] - gated.T_WfromC_filter[k, 0, 3]
    assert shift > 1.0


def test_a_sheet_far_from_the_prediction_is_searched_and_given_to_the_smoother(
    walk: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A sheet that the prediction does not put in view (the odometry drifted) is searched in
    the whole frame every ``filter.full_search_every``-th frame once the camera is predicted
    near it; its pose, 0.3 m from the prediction and refused by the tag gate of a confident
    filter, goes to the smoother when ``filter.odometry_scale_std`` × the distance walked
    covers it, which moves the smoothed end towards it and leaves the filter as it was;
    without the search it is never found, without the drift it is refused."""
    import gaitnet.vio.apriltags as apriltags
    from gaitnet.io.trajectory import read_tum
    from gaitnet.vio.apriltags import TagObservation

    source = open_session(walk)
    boards = source.calibration.apriltag_boards
    assert len(boards) == 2
    t_true, T_true = read_tum(walk / "groundtruth" / "camera_frames.tum")
    last = len(source) - 30
    searched: list[int] = []
    empty = np.zeros(0)
    cov6 = np.diag([1e-6] * 3 + [1e-6] * 3)

    def decoded(frame, calib, params, T_WfromC_guess=None):
        T = T_true[int(np.argmin(np.abs(t_true - frame.t_ns * 1e-9)))].copy()
        if frame.index == 0:  # the start sheet initialises the filter
            return TagObservation(boards[0].name, T, cov6, 35, 0.2, 0.25, empty, empty, empty)
        if T_WfromC_guess is not None or frame.index < last:
            return None  # the prediction's region shows nothing
        searched.append(frame.index)
        T[0, 3] += 0.3  # where the sheet says the camera is: 0.3 m beyond the odometry's
        return TagObservation(boards[1].name, T, cov6, 20, 0.2, 0.25, empty, empty, empty)

    monkeypatch.setattr(apriltags, "detect_board_pose", decoded)

    def run(*keys: str):
        searched.clear()
        cfg = load_config(VioConfig, None, ["filter.odometry_scale_std=0.5", *keys])
        return run_vio(source, cfg)

    taken = run()
    assert len(searched) >= 5 and all(k % 3 == 0 for k in searched)  # every 3rd frame
    assert taken.used["tag_smoother_only"] == len(searched) and taken.used["tag"] == 0
    never = run("filter.full_search_every=0")
    assert not searched and never.used["tag_smoother_only"] == 0
    refused = run("filter.odometry_scale_std=0", "smoother.enabled=false")  # the filter's
    assert refused.used["tag_smoother_only"] == 0
    assert refused.skipped["tag"]["outside the chi2 gate"] == len(searched) > 0
    moved = taken.T_WfromC[-1, 0, 3] - never.T_WfromC[-1, 0, 3]
    assert 0.1 < moved < 0.35  # the smoother follows the sheet, weighed against the odometry
    np.testing.assert_allclose(taken.T_WfromC_filter, never.T_WfromC_filter)  # filter untouched


def test_a_sheet_refused_steadily_frame_after_frame_is_taken_after_widening(
    walk: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A sheet decoded in every one of the last 30 frames, 0.3 m from where a confident filter
    puts the camera, is refused by the tag gate; after ``filter.tag_recovery_frames`` steady
    refusals the filter's navigation covariance is widened and the sheet taken, which moves
    the filter's end by about the offset. Never with 0; never when the refused poses jump
    (a wrong decode), however often they come."""
    import gaitnet.vio.apriltags as apriltags
    from gaitnet.io.trajectory import read_tum
    from gaitnet.vio.apriltags import TagObservation

    source = open_session(walk)
    boards = source.calibration.apriltag_boards
    t_true, T_true = read_tum(walk / "groundtruth" / "camera_frames.tum")
    last = len(source) - 30
    empty = np.zeros(0)
    cov6 = np.diag([1e-6] * 3 + [1e-6] * 3)
    jumpy = [False]

    def decoded(frame, calib, params, T_WfromC_guess=None):
        T = T_true[int(np.argmin(np.abs(t_true - frame.t_ns * 1e-9)))].copy()
        if frame.index == 0:
            return TagObservation(boards[0].name, T, cov6, 35, 0.2, 0.25, empty, empty, empty)
        if frame.index < last:
            return None
        T[0, 3] += 0.3 if not jumpy[0] or frame.index % 2 else -0.3
        return TagObservation(boards[1].name, T, cov6, 35, 0.2, 0.25, empty, empty, empty)

    monkeypatch.setattr(apriltags, "detect_board_pose", decoded)

    def run(*keys: str):
        keys = ("smoother.enabled=false", *keys)  # the filter's own counts and poses
        cfg = load_config(VioConfig, None, ["filter.odometry_scale_std=0", *keys])
        return run_vio(source, cfg)

    taken = run()
    assert taken.used["tag_recovered"] == 1
    assert taken.skipped["tag"]["outside the chi2 gate"] == 4  # the 5th refusal is taken
    assert taken.used["tag"] == 30 - 4
    never = run("filter.tag_recovery_frames=0")
    assert never.used["tag_recovered"] == 0 and never.used["tag"] == 0
    assert never.skipped["tag"]["outside the chi2 gate"] == 30
    moved = taken.T_WfromC_filter[-1, 0, 3] - never.T_WfromC_filter[-1, 0, 3]
    assert 0.2 < moved < 0.4  # the 0.3 m offset, give or take what the feet hold (0.35 measured)
    jumpy[0] = True
    wrong = run()
    assert wrong.used["tag_recovered"] == 0 and wrong.used["tag"] == 0


def test_partial_foot_noise_key_acts(walk: Path, walk_result) -> None:
    """``filter.partial_foot_noise`` (default on) weighs partly hidden feet less: off, the same
    walk's landmarks and path come out otherwise (the noise itself:
    tests/test_vio_models.py)."""
    off = run_vio(
        open_session(walk), load_config(VioConfig, None, ["filter.partial_foot_noise=false"])
    )
    assert len(off.stance_feet) == len(walk_result.stance_feet)
    moved = [
        float(np.linalg.norm(a.xy - b.xy))
        for a, b in zip(off.stance_feet, walk_result.stance_feet, strict=True)
    ]
    assert max(moved) > 1e-5
    assert not np.allclose(off.T_WfromC, walk_result.T_WfromC, atol=1e-6)
