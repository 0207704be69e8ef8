"""Relative camera pose from tracked corners (3-D in the previous frame, 2-D in the current).

RANSAC perspective-n-point (minimal AP3P samples) keeps the motion most corners agree on, which
rejects corners on the legs and shoes that move on their own, then Levenberg–Marquardt refines
the pose on the inliers. The covariance comes from the Gauss–Newton information of the inlier
reprojection residuals with the pixel noise scaled by the residual itself — the sparse analogue
of the thesis's ``R_vo = J_vo diag(r_vo,q I3, r_vo,t I3)`` (D.-C. Dang's thesis, after (3.21)),
where ``J_vo`` is the sum of squared photometric residuals of the alignment.

Pose convention: ``p_Ck = R p_Ck-1 + t`` (``T_CkfromCk1``). Perturbation (the VO residual of the
filter): ``R = exp([dphi]x) R_hat``, ``t = t_hat + dt``; the covariance is over ``(dphi, dt)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2 as cv
import numpy as np
from numpy.typing import NDArray

from gaitnet.geometry.rotation import so3_exp

FloatArray = NDArray[np.float64]

__all__ = [
    "PoseFit",
    "fit_pose",
    "pose_information",
    "refine_weighted",
    "reprojection_jacobian",
    "reprojection_residuals",
]


@dataclass(frozen=True)
class PoseFit:
    """Result of :func:`fit_pose`: ``R``, ``t`` (``p_Ck = R p_Ck-1 + t``), the inlier mask,
    the inlier residuals (n_in, 2) in working-resolution pixels and their inverse pixel
    covariances ``weights`` (n_in, 2, 2). ``R`` is None on failure."""

    R: FloatArray | None
    t: FloatArray | None
    inliers: NDArray[np.bool_]
    residuals: FloatArray
    weights: FloatArray


def _rt_from_vecs(rvec: np.ndarray, tvec: np.ndarray) -> tuple[FloatArray, FloatArray]:
    R, _ = cv.Rodrigues(np.asarray(rvec, np.float64).reshape(3, 1))
    return R, np.asarray(tvec, np.float64).reshape(3)


def reprojection_residuals(
    K: FloatArray, R: FloatArray, t: FloatArray, p_prev: FloatArray, uv_cur: FloatArray
) -> FloatArray:
    """Measured minus predicted pixels (n, 2); rows for points behind the camera are +inf."""
    q = p_prev @ R.T + t
    z = q[:, 2]
    front = z > 1e-6
    zs = np.where(front, z, 1.0)
    u = K[0, 0] * q[:, 0] / zs + K[0, 2]
    v = K[1, 1] * q[:, 1] / zs + K[1, 2]
    r = uv_cur - np.stack([u, v], axis=1)
    r[~front] = np.inf
    return r


def reprojection_jacobian(
    K: FloatArray, R: FloatArray, t: FloatArray, p_prev: FloatArray
) -> FloatArray:
    """Jacobian (n, 2, 6) of the predicted pixels w.r.t. ``(dphi, dt)``.

    With ``q = R p + t`` and ``R = exp([dphi]x) R_hat``: ``dq/d(dphi) = -[R p]x``,
    ``dq/d(dt) = I``; ``du/dq = [[fx/z, 0, -fx x/z²], [0, fy/z, -fy y/z²]]``.
    """
    Rp = p_prev @ R.T
    q = Rp + t
    x, y, z = q[:, 0], q[:, 1], q[:, 2]
    n = len(q)
    J_proj = np.zeros((n, 2, 3))
    J_proj[:, 0, 0] = K[0, 0] / z
    J_proj[:, 0, 2] = -K[0, 0] * x / z**2
    J_proj[:, 1, 1] = K[1, 1] / z
    J_proj[:, 1, 2] = -K[1, 1] * y / z**2
    skew = np.zeros((n, 3, 3))
    skew[:, 0, 1], skew[:, 0, 2] = -Rp[:, 2], Rp[:, 1]
    skew[:, 1, 0], skew[:, 1, 2] = Rp[:, 2], -Rp[:, 0]
    skew[:, 2, 0], skew[:, 2, 1] = -Rp[:, 1], Rp[:, 0]
    return np.concatenate([-J_proj @ skew, J_proj], axis=2)


def pose_information(
    K: FloatArray,
    R: FloatArray,
    t: FloatArray,
    p_prev: FloatArray,
    weights: FloatArray | None = None,
    common_px: float = 0.0,
) -> FloatArray:
    """Information (6×6) of the reprojections about ``(dphi, dt)``: ``Jᵀ Σ⁻¹ J``.

    Pixel noise ``Σ = blockdiag(W_i⁻¹) + c² U Uᵀ``: independent per corner (``weights``
    (n, 2, 2) = ``W_i``, default identity) plus, when ``common_px = c > 0``, one image shift
    shared by all corners (``U`` stacks n 2×2 identities) — tracking errors are correlated
    (blur, interpolation), which matters when the corners cover a small part of the image and
    a shift of all of them is nearly the same as a rotation. Woodbury:
    ``Jᵀ Σ⁻¹ J = Σ JᵢᵀWᵢJᵢ − B (c⁻² I + Σ Wᵢ)⁻¹ Bᵀ`` with ``B = Σ JᵢᵀWᵢ``.
    """
    J = reprojection_jacobian(K, R, t, p_prev)
    if weights is None:
        weights = np.broadcast_to(np.eye(2), (len(J), 2, 2))
    JtW = np.swapaxes(J, 1, 2) @ weights  # (n, 6, 2)
    info = np.tensordot(JtW, J, axes=([0, 2], [0, 1]))
    if common_px > 0:
        B = JtW.sum(axis=0)
        C = np.eye(2) / common_px**2 + weights.sum(axis=0)
        info = info - B @ np.linalg.solve(C, B.T)
    return 0.5 * (info + info.T)


def refine_weighted(
    K: FloatArray,
    R: FloatArray,
    t: FloatArray,
    p_prev: FloatArray,
    uv_cur: FloatArray,
    weights: FloatArray,
    iterations: int = 3,
) -> tuple[FloatArray, FloatArray]:
    """Gauss–Newton on ``Σ r_iᵀ W_i r_i`` over ``(dphi, dt)`` (``W_i`` per corner, so a corner
    on an edge constrains only the direction across it)."""
    for _ in range(iterations):
        r = reprojection_residuals(K, R, t, p_prev, uv_cur)
        J = reprojection_jacobian(K, R, t, p_prev)
        JtW = np.swapaxes(J, 1, 2) @ weights  # (n, 6, 2)
        H = np.tensordot(JtW, J, axes=([0, 2], [0, 1]))
        g = np.tensordot(JtW, r, axes=([0, 2], [0, 1]))
        try:
            d = np.linalg.solve(H, g)
        except np.linalg.LinAlgError:
            break
        R = so3_exp(d[:3]) @ R
        t = t + d[3:]
        if np.abs(d).max() < 1e-9:
            break
    return R, t


def fit_pose(
    K: FloatArray,
    p_prev: FloatArray,
    uv_cur: FloatArray,
    cov_track: FloatArray,
    R_guess: FloatArray,
    t_guess: FloatArray,
    *,
    ransac_px: float,
    ransac_iterations: int,
    sigma_min_px: float,
    gate_chi2: float,
    min_inliers: int,
) -> PoseFit:
    """Robust pose: hypothesis (the guess if half the tracks agree with it within
    ``ransac_px``, else RANSAC AP3P), LM refinement on its inliers, then twice: pixel noise
    ``σ² I + cov_track_i`` with ``σ²`` the inlier residual variance (≥ ``sigma_min_px²``),
    weighted Gauss–Newton, inliers re-selected by ``rᵀ W r ≤ gate_chi2``.

    ``K``, ``uv_cur`` and ``cov_track`` (n, 2, 2: the tracking noise of each corner from its
    texture) at the working resolution.
    """
    n = len(p_prev)
    none = PoseFit(None, None, np.zeros(n, bool), np.zeros((0, 2)), np.zeros((0, 2, 2)))
    if n < max(min_inliers, 4):
        return none
    obj = p_prev.reshape(-1, 1, 3).astype(np.float64)
    img = uv_cur.reshape(-1, 1, 2).astype(np.float64)
    r_guess = np.linalg.norm(reprojection_residuals(K, R_guess, t_guess, p_prev, uv_cur), axis=1)
    inl = r_guess <= ransac_px
    R, t = R_guess, t_guess
    if inl.sum() < max(min_inliers, n // 2):
        rvec0, _ = cv.Rodrigues(R_guess)
        ok, rvec, tvec, idx = cv.solvePnPRansac(
            obj,
            img,
            K,
            None,
            rvec0.copy(),
            t_guess.reshape(3, 1).copy(),
            useExtrinsicGuess=False,
            iterationsCount=ransac_iterations,
            reprojectionError=ransac_px,
            confidence=0.999,
            flags=cv.SOLVEPNP_AP3P,
        )
        if not ok or idx is None or len(idx) < min_inliers:
            return none
        R, t = _rt_from_vecs(rvec, tvec)
        inl = np.zeros(n, bool)
        inl[idx.reshape(-1)] = True
    rvec, _ = cv.Rodrigues(R)
    rvec, tvec = cv.solvePnPRefineLM(obj[inl], img[inl], K, None, rvec, t.reshape(3, 1).copy())
    R, t = _rt_from_vecs(rvec, tvec)
    W = np.zeros((n, 2, 2))
    for _ in range(2):
        r = reprojection_residuals(K, R, t, p_prev, uv_cur)
        if inl.sum() < min_inliers:
            return none
        sigma2 = max(float((r[inl] ** 2).sum()) / max(2 * int(inl.sum()) - 6, 1), sigma_min_px**2)
        W = np.linalg.inv(sigma2 * np.eye(2) + cov_track)
        R, t = refine_weighted(K, R, t, p_prev[inl], uv_cur[inl], W[inl])
        r = reprojection_residuals(K, R, t, p_prev, uv_cur)
        r = np.where(np.isfinite(r), r, 1e6)
        m2 = np.einsum("na,nab,nb->n", r, W, r)
        inl = m2 <= gate_chi2
    if inl.sum() < min_inliers:
        return none
    return PoseFit(R, t, inl, r[inl], W[inl])
