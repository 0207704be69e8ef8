"""Second-order digital filters, written out: the Butterworth low-pass, its difference equation
and zero-phase (forward-backward) filtering.

They give ``scipy.signal``'s numbers (``butter(2, …)``, ``lfilter``, ``lfilter_zi``,
``filtfilt`` with odd padding; tests compare them) without its import: ``import scipy.signal``
pulls in ``scipy.stats`` and takes 0.3–0.6 s, which every ``gaitnet infer`` run (gait events)
would pay for a few lines of arithmetic; the simulator's strap spring
(:func:`gaitnet.sim.mount_dynamics.spring_response`) runs its difference equation here too.

Arrays are filtered along axis 0 (time); other axes are independent signals.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["butterworth2_lowpass", "filtfilt2", "lfilter2", "lfilter2_zi"]

FloatArray = NDArray[np.float64]


def butterworth2_lowpass(cutoff: float) -> tuple[FloatArray, FloatArray]:
    """``(b, a)`` of the second-order Butterworth low-pass with its −3 dB point at ``cutoff``
    (a fraction of the Nyquist frequency, 0 < cutoff < 1): the analogue prototype
    ``1 / (s² + √2 s + 1)`` at the pre-warped frequency ``K = tan(π cutoff / 2)``, bilinear
    transform (``scipy.signal.butter(2, cutoff)``)."""
    if not 0.0 < cutoff < 1.0:
        raise ValueError(f"cut-off must be in (0, 1) × Nyquist, got {cutoff}")
    k = math.tan(math.pi * cutoff / 2.0)
    norm = 1.0 / (1.0 + math.sqrt(2.0) * k + k * k)
    b0 = k * k * norm
    b = np.array([b0, 2.0 * b0, b0])
    a = np.array([1.0, 2.0 * (k * k - 1.0) * norm, (1.0 - math.sqrt(2.0) * k + k * k) * norm])
    return b, a


def _normalised(b: ArrayLike, a: ArrayLike) -> tuple[list[float], list[float]]:
    b_, a_ = np.asarray(b, np.float64).ravel(), np.asarray(a, np.float64).ravel()
    if b_.shape != (3,) or a_.shape != (3,) or a_[0] == 0.0:
        raise ValueError(f"expected 3 coefficients each and a[0] != 0, got b={b_}, a={a_}")
    return (b_ / a_[0]).tolist(), (a_ / a_[0]).tolist()


def lfilter2_zi(b: ArrayLike, a: ArrayLike) -> FloatArray:
    """The filter's state (2,) after a unit step held for ever: scaled by a signal's first
    value, it starts the filter without a transient (``scipy.signal.lfilter_zi``)."""
    (b0, b1, b2), (_, a1, a2) = _normalised(b, a)
    if 1.0 + a1 + a2 == 0.0:
        raise ValueError("a filter with a pole at z = 1 has no steady state")
    gain = (b0 + b1 + b2) / (1.0 + a1 + a2)  # the output in that steady state
    # the transposed direct form II's state at x = 1, y = gain (see lfilter2)
    return np.array([b1 + b2 - (a1 + a2) * gain, b2 - a2 * gain])


def lfilter2(b: ArrayLike, a: ArrayLike, x: ArrayLike, zi: ArrayLike | None = None) -> FloatArray:
    """``x`` filtered along axis 0 by ``y[n] = (b0 x[n] + b1 x[n−1] + b2 x[n−2] − a1 y[n−1] −
    a2 y[n−2]) / a0`` (transposed direct form II; ``scipy.signal.lfilter``), from rest or
    from the state ``zi`` (2, …) broadcast against one sample of ``x``."""
    (b0, b1, b2), (_, a1, a2) = _normalised(b, a)
    x = np.asarray(x, np.float64)
    if x.ndim == 0:
        raise ValueError("lfilter2: x must have a time axis (axis 0)")
    if x.shape[0] == 0:
        return x.copy()
    flat = x.reshape(len(x), -1)
    if zi is None:
        state = np.zeros((2, flat.shape[1]))
    else:
        state = np.broadcast_to(np.asarray(zi, np.float64).reshape(2, -1), (2, flat.shape[1]))
    out = np.empty_like(flat)
    for j in range(flat.shape[1]):  # the recursion on Python floats: fastest for short signals
        z0, z1 = float(state[0, j]), float(state[1, j])
        column = []
        for v in flat[:, j].tolist():
            y = b0 * v + z0
            z0 = b1 * v - a1 * y + z1
            z1 = b2 * v - a2 * y
            column.append(y)
        out[:, j] = column
    return out.reshape(x.shape)


def filtfilt2(b: ArrayLike, a: ArrayLike, x: ArrayLike, padlen: int) -> FloatArray:
    """Zero-phase filtering along axis 0 (``scipy.signal.filtfilt(b, a, x, axis=0,
    padlen=padlen)``): ``x`` extended by ``padlen`` samples at each end by odd reflection
    about its end values, filtered forwards and backwards, each pass started in the steady
    state of its first value, the extension cut off again. The magnitude response is the
    filter's squared, with no phase shift."""
    x = np.asarray(x, np.float64)
    if x.ndim == 0 or len(x) == 0:
        raise ValueError("filtfilt2: x must hold at least one sample along axis 0")
    if not 0 <= padlen < len(x):
        raise ValueError(f"padlen must be in [0, {len(x) - 1}] for {len(x)} samples, got {padlen}")
    ext = np.concatenate(
        [2 * x[0] - x[padlen:0:-1], x, 2 * x[-1] - x[-2 : -padlen - 2 : -1]], axis=0
    )
    zi = lfilter2_zi(b, a).reshape((2,) + (1,) * (x.ndim - 1))
    forward = lfilter2(b, a, ext, zi * ext[0])
    backward = lfilter2(b, a, forward[::-1], zi * forward[-1])[::-1]
    return backward[padlen : len(backward) - padlen].copy()
