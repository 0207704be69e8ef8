"""Write a simulated session's ``groundtruth/`` folder (documented in docs/groundtruth.md).

Everything is in SI units and the world frame (z up, floor z = 0). Trajectories are TUM files
(world-from-sensor poses), tables are CSV with a header row, arrays are ``.npz`` (no pickles).
"""

from __future__ import annotations

import dataclasses
import io
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import yaml

from gaitnet.geometry import make_T
from gaitnet.io.atomic import atomic_save, atomic_write_text
from gaitnet.io.images import encode_png
from gaitnet.io.trajectory import write_tum
from gaitnet.motion.skeleton import JOINT_NAMES, ROTATED_SMPL_INDICES, SMPL_JOINT_INDICES
from gaitnet.sim.frame_timing import FrameTimes
from gaitnet.sim.gait import Walk
from gaitnet.sim.imu import ImuCalibration, ImuTruth
from gaitnet.sim.mount_dynamics import MountMotion
from gaitnet.sim.scene import SIDES


def _csv(header: list[str], rows: list[list]) -> str:
    out = io.StringIO()
    out.write(",".join(header) + "\n")
    for row in rows:
        out.write(",".join(_fmt(v) for v in row) + "\n")
    return out.getvalue()


def _fmt(value) -> str:
    if isinstance(value, (bool, np.bool_)):
        return str(int(value))
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return "" if not np.isfinite(value) else f"{float(value):.6f}"
    return str(value)


def _save_npz(path: Path, **arrays: np.ndarray) -> None:
    def save(tmp: str) -> None:
        with open(tmp, "wb") as handle:
            np.savez_compressed(handle, **arrays)

    atomic_save(path, save)


class GroundTruthWriter:
    """Collects per-frame label maps and writes the tables at the end."""

    def __init__(
        self, root: Path, write_labels: bool = True, write_png: Callable | None = None
    ) -> None:
        self.root = Path(root)
        self._write_png = write_png or (lambda path, image: path.write_bytes(encode_png(image)))
        self.write_labels = write_labels
        self.root.mkdir(parents=True, exist_ok=True)
        if write_labels:
            (self.root / "labels").mkdir(exist_ok=True)
            (self.root / "instances").mkdir(exist_ok=True)

    def add_frame(self, t_ns: int, label: np.ndarray, instance: np.ndarray) -> None:
        if not self.write_labels:
            return
        self._write_png(self.root / "labels" / f"{t_ns}.png", label)
        self._write_png(self.root / "instances" / f"{t_ns}.png", instance)

    def write_floor_and_depth(self, floor_relief: dict, depth_unit: dict) -> None:
        """``floor_relief.json`` (the floor's height field, :mod:`gaitnet.sim.floor_relief`)
        and ``depth_unit.json`` (the depth camera's fixed errors, :mod:`gaitnet.sim.
        sensor_depth`)."""
        for name, obj in (("floor_relief.json", floor_relief), ("depth_unit.json", depth_unit)):
            atomic_write_text(self.root / name, json.dumps(obj, indent=1) + "\n")

    def write_motion(self, walk: Walk, times: np.ndarray, t_ns: np.ndarray) -> None:
        """For a played clip (``walk.source``), ``motion.json`` and ``motion_frames.csv``:
        where each frame's pose came from (docs/groundtruth.md); nothing for a generated walk."""
        if walk.source is None:
            return
        atomic_write_text(self.root / "motion.json", walk.source.to_json() + "\n")
        rows = walk.source.frame_rows(times)
        atomic_write_text(
            self.root / "motion_frames.csv",
            _csv(
                ["t_ns", "clip_time_s", "blend_weight", "time_rate", "synthetic"],
                [[int(t), *r[:3], int(r[3])] for t, r in zip(t_ns, rows, strict=True)],
            ),
        )

    def write_rig(
        self,
        mount: MountMotion,
        frames: FrameTimes,
        imu: ImuTruth,
        calibration: ImuCalibration,
    ) -> None:
        """The rig's motion on the pelvis, the IMU's sensor errors and the frame timing
        (``mount_frames.tum``, ``mount_motion.npz``, ``imu_calibration.yaml``,
        ``frame_times.csv``; docs/groundtruth.md)."""
        root = self.root
        write_tum(
            root / "mount_frames.tum",
            frames.stamp_ns * 1e-9,
            mount.T_PfromC(frames.true_s),
            "camera in the pelvis frame (T_PfromC) at frame times",
        )
        impact, wobble = mount.parts(imu.t_s)
        _, tilt = mount.displacement(imu.t_s)
        _save_npz(
            root / "mount_motion.npz",
            t_ns=imu.t_ns if imu.t_ns is not None else np.round(imu.t_s * 1e9).astype(np.int64),
            t_true_s=imu.t_s,
            impact_m=impact,
            wobble_m=wobble,
            tilt_rad=tilt,
            T_PfromC_nominal=mount.T_PfromC_nominal,
        )
        cal = calibration.as_dict()
        cal["dropped_frames"] = [int(i) for i in frames.dropped]
        atomic_write_text(root / "imu_calibration.yaml", yaml.safe_dump(cal, sort_keys=False))
        n = len(frames.index) + len(frames.dropped)
        stamp = dict(zip(frames.index.tolist(), frames.stamp_ns.tolist(), strict=True))
        true = dict(zip(frames.index.tolist(), frames.true_s.tolist(), strict=True))
        rows = []
        for k in range(n):
            if k in stamp:
                rows.append([k, stamp[k], true[k], False])
            else:
                rows.append([k, "", float("nan"), True])
        atomic_write_text(
            root / "frame_times.csv",
            _csv(["frame", "t_ns", "true_exposure_mid_s", "dropped"], rows),
        )

    def write_all(
        self,
        walk: Walk,
        times: np.ndarray,
        T_WfromC: np.ndarray,
        T_CfromI: np.ndarray,
        imu: ImuTruth,
        marker_checks: list[tuple],
        frame_t_ns: np.ndarray | None = None,
    ) -> None:
        """Everything per frame is evaluated at the true exposure mid-times ``times`` and
        keyed by the frames' timestamps ``frame_t_ns`` (default: ``times`` in ns)."""
        root = self.root
        t_ns = np.round(times * 1e9).astype(np.int64) if frame_t_ns is None else frame_t_ns
        t_key = t_ns * 1e-9
        R_WP, p_P = walk.pelvis_pose(times)
        T_WP = make_T(R_WP, p_P)
        T_IfromC = np.linalg.inv(T_CfromI)
        write_tum(root / "camera_frames.tum", t_key, T_WfromC, "camera (colour) at frame times")
        write_tum(root / "imu_frames.tum", t_key, T_WfromC @ T_CfromI, "IMU at frame times")
        write_tum(root / "pelvis_frames.tum", t_key, T_WP, "pelvis (SMPL joint 0) at frame times")
        T_WI = make_T(imu.R_WfromI, imu.p_IinW)
        write_tum(root / "imu_imurate.tum", imu.t_s, T_WI, "IMU at true IMU sample times")
        write_tum(root / "camera_imurate.tum", imu.t_s, T_WI @ T_IfromC, "camera at true IMU times")

        root_orient, trans, joint_aa = walk.smpl_pose(times)
        _save_npz(
            root / "joints.npz",
            t_ns=t_ns,
            smpl_indices=np.asarray(SMPL_JOINT_INDICES, np.int64),
            joint_names=np.asarray(JOINT_NAMES),
            positions=walk.joints(times),
            root_orient=root_orient,
            trans=trans,
            joint_aa=joint_aa,
            joint_aa_indices=np.asarray(ROTATED_SMPL_INDICES, np.int64),
            rest_joints=walk.skeleton.rest_joints,
        )
        markers, soles = walk.marker_points(times), walk.sole_centres(times)
        header = ["t_ns"] + [
            f"{what}_{side}_{a}" for what in ("marker", "sole") for side in SIDES for a in "xyz"
        ]
        rows = [[int(t), *markers[k].ravel(), *soles[k].ravel()] for k, t in enumerate(t_ns)]
        atomic_write_text(root / "feet.csv", _csv(header, rows))

        ev_rows, stride_rows = [], []
        for side in SIDES:
            ev = walk.events[side]
            for i in range(len(ev.flat_start_s)):
                ev_rows.append(
                    [
                        side,
                        i,
                        ev.hs_s[i],
                        ev.ff_s[i],
                        ev.ho_s[i],
                        ev.to_s[i],
                        ev.flat_start_s[i],
                        ev.flat_end_s[i],
                        *ev.sole_centre_W[i],
                        ev.yaw_rad[i],
                    ]
                )
            for i, length in enumerate(ev.stride_lengths_m):
                stride_rows.append(
                    [side, i, ev.flat_start_s[i], ev.flat_start_s[i + 1], ev.hs_s[i + 1], length]
                )
        atomic_write_text(
            root / "events.csv",
            _csv(
                [
                    "side",
                    "stance",
                    "heel_strike_s",
                    "foot_flat_s",
                    "heel_off_s",
                    "toe_off_s",
                    "flat_start_s",
                    "flat_end_s",
                    "sole_x_m",
                    "sole_y_m",
                    "sole_z_m",
                    "yaw_rad",
                ],
                ev_rows,
            ),
        )
        atomic_write_text(
            root / "strides.csv",
            _csv(
                [
                    "side",
                    "stride",
                    "from_flat_start_s",
                    "to_flat_start_s",
                    "heel_strike_s",
                    "stride_length_m",
                ],
                stride_rows,
            ),
        )
        steps = walk.steps
        atomic_write_text(
            root / "steps.csv",
            _csv(
                ["side", "heel_strike_s", "step_length_m", "step_width_m"],
                [
                    [s, h, length, w]
                    for s, h, length, w in zip(
                        steps.side, steps.hs_s, steps.length_m, steps.width_m, strict=True
                    )
                ],
            ),
        )
        _save_npz(
            root / "imu_truth.npz",
            t_ns=imu.t_ns if imu.t_ns is not None else np.round(imu.t_s * 1e9).astype(np.int64),
            t_true_s=imu.t_s,
            specific_force=imu.specific_force,
            angular_rate=imu.omega_I,
            gyro_bias=imu.gyro_bias,
            accel_bias=imu.accel_bias,
            velocity_W=imu.v_IinW,
        )
        atomic_write_text(
            root / "marker_pixels.csv",
            _csv(
                ["t_ns", "side", "u", "v", "in_image", "visible", "on_foot_label"],
                [list(c) for c in marker_checks],
            ),
        )
        subject = {
            k: (list(v) if isinstance(v, tuple) else v)
            for k, v in dataclasses.asdict(walk.subject).items()
        }
        subject["marker_in_shoe_m"] = walk.subject.marker_in_shoe().tolist()
        subject["ankle_in_shoe_m"] = walk.subject.ankle_in_shoe().tolist()
        atomic_write_text(root / "subject.yaml", yaml.safe_dump(subject, sort_keys=False))
