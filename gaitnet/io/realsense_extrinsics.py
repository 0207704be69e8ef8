"""RealSense ``tf`` extrinsics and IMU-noise calibration, as stored in SDK ``.bag`` files.

Extrinsics: direction convention of the SDK's ``tf`` topics (assumption, documented here)
    Each stream's ``tf/<group>`` holds the extrinsic between that stream and its group's
    reference ("pin") stream — the depth stream on D400 devices. We take it as the transform
    **from the reference stream to this stream**: ``p_stream = R p_ref + t``, i.e.
    ``T_{stream from ref}`` (:data:`TF_REF_TO_STREAM`). Evidence in librealsense:
    ``ros_writer::write_extrinsics`` stores ``device::get_extrinsics(stream)``, which returns
    ``try_fetch_extrinsics(*pin_stream, stream)`` — extrinsics *from* the pin stream *to* the
    stream, and ``rs2_extrinsics`` from→to maps points as ``p_to = R p_from + t``
    (``rs2_transform_point_to_point``; the column-major rotation is converted to the quaternion
    of that same R by ``rot2quat``). Playback (``playback_device::calc_extrinsic``) registers
    stream1→stream2 as ``E2 · E1⁻¹``, which is only right with this reading — although a
    comment there says the opposite ("from the stream at hand to some reference point").
    Because of that contradiction the convention is a parameter: pass
    ``tf_convention=TF_STREAM_TO_REF`` to read ``tf`` as ``T_{ref from stream}``. Then
    ``T_CfromI = E_color · E_imu⁻¹`` (default) or ``E_color⁻¹ · E_imu`` (the other reading); see
    :func:`relative_extrinsic`. The IMU extrinsic is the gyro stream's tf (the accel's if the
    gyro has none). A depth stream without a tf is taken as the reference (identity).

IMU noise
    ``realsense_msgs/ImuIntrinsic`` carries ``noise_variances`` and ``bias_variances`` per
    axis. We read them as discrete per-sample variances at the stream's rate ``f`` (the
    StreamInfo fps, else the median record interval): noise density ``sqrt(var / f)`` and bias
    random walk ``sqrt(var_b · f)`` (Kalibr's discrete↔continuous relations), averaging the
    three axes' variances. ``imu_noise`` is None unless both the accelerometer and the gyro
    report positive, finite noise *and* bias variances (the SDK writes zeros when the device
    has no such calibration, which is the usual case).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from gaitnet.geometry import invert_T, make_T, rotmat_from_quat
from gaitnet.io.types import ImuNoise

TF_REF_TO_STREAM = "ref_to_stream"
"""``tf`` of a stream maps reference-stream points into that stream (librealsense's writer)."""
TF_STREAM_TO_REF = "stream_to_ref"
"""``tf`` of a stream maps that stream's points into the reference stream."""


def transform_to_matrix(msg: Any) -> np.ndarray:
    """4×4 matrix of a ``geometry_msgs/Transform`` (``[R t; 0 1]``, direction as stored).

    ``ValueError`` for a non-finite translation or a quaternion that is zero or not finite
    (the quaternion is normalised, as ROS does).
    """
    r, t = msg.rotation, msg.translation
    q_wxyz = np.array([r.w, r.x, r.y, r.z], dtype=np.float64)
    p = np.array([t.x, t.y, t.z], dtype=np.float64)
    if not np.isfinite(q_wxyz).all() or np.linalg.norm(q_wxyz) < 1e-9:
        raise ValueError(f"not a rotation quaternion (x, y, z, w): {np.roll(q_wxyz, -1).tolist()}")
    if not np.isfinite(p).all():
        raise ValueError(f"translation is not finite: {p.tolist()}")
    return make_T(rotmat_from_quat(q_wxyz), p)


def relative_extrinsic(
    E_target: np.ndarray, E_source: np.ndarray, convention: str = TF_REF_TO_STREAM
) -> np.ndarray:
    """``T_{target from source}`` from two streams' tf extrinsics of the same reference group.

    With :data:`TF_REF_TO_STREAM` each ``E`` is ``T_{stream from ref}``, so the result is
    ``E_target · E_source⁻¹``; with :data:`TF_STREAM_TO_REF` each ``E`` is ``T_{ref from
    stream}`` and the result is ``E_target⁻¹ · E_source``.
    """
    if convention == TF_REF_TO_STREAM:
        return E_target @ invert_T(E_source)
    if convention == TF_STREAM_TO_REF:
        return invert_T(E_target) @ E_source
    raise ValueError(f"unknown tf convention {convention!r}")


def imu_noise_from_intrinsics(
    acc_intr: Any, gyr_intr: Any, fps_acc: float | None, fps_gyr: float | None
) -> ImuNoise | None:
    """:class:`ImuNoise` from the accel and gyro ``realsense_msgs/ImuIntrinsic`` messages.

    ``fps_acc`` / ``fps_gyr`` are the streams' rates (module docstring, "IMU noise"). None when
    a message, a rate, or a positive finite noise or bias variance is missing.
    """

    def variances(msg: Any, name: str) -> float | None:
        if msg is None:
            return None
        v = np.asarray(getattr(msg, name, []), dtype=np.float64).ravel()
        if v.size == 0 or not np.isfinite(v).all() or (v <= 0).any():
            return None
        return float(v.mean())

    a_n, a_b = variances(acc_intr, "noise_variances"), variances(acc_intr, "bias_variances")
    g_n, g_b = variances(gyr_intr, "noise_variances"), variances(gyr_intr, "bias_variances")
    if None in (a_n, a_b, g_n, g_b, fps_acc, fps_gyr):
        return None
    return ImuNoise(
        gyro_noise_density=math.sqrt(g_n / fps_gyr),
        accel_noise_density=math.sqrt(a_n / fps_acc),
        gyro_bias_random_walk=math.sqrt(g_b * fps_gyr),
        accel_bias_random_walk=math.sqrt(a_b * fps_acc),
    )
