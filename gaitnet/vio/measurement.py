"""A linearised measurement: residual, Jacobian blocks per state variable, noise covariance.

Every measurement model (:mod:`~gaitnet.vio.vo_model`, :mod:`~gaitnet.vio.tag_model`,
:mod:`~gaitnet.vio.foot_model`) returns a :class:`Measurement` with
``residual = z ⊟ h(x̂)`` and ``H[var] = ∂ h(x̂ ⊞ δx) / ∂ δx[var]`` at ``δx = 0`` (so the update
is ``δx = K residual``), as in OpenVINS: the Jacobian comes with the variables its columns refer
to, and :func:`stack_jacobian` scatters the blocks into the full ``H`` for the state layout.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.linalg import block_diag

from gaitnet.vio.state import FilterState, Var


@dataclass
class Measurement:
    """``residual`` (m,), ``H`` {var: (m, dim(var))}, ``R`` (m, m) noise covariance, ``name``."""

    residual: np.ndarray
    H: dict[Var, np.ndarray]
    R: np.ndarray
    name: str

    @property
    def dim(self) -> int:
        return int(self.residual.shape[0])


def stack_jacobian(m: Measurement, state: FilterState) -> np.ndarray:
    """The full ``H`` (m, n) of ``m`` for ``state``'s layout (blocks of one variable add up)."""
    H = np.zeros((m.dim, state.dim))
    for var, block in m.H.items():
        sl = state.index(var)
        if block.shape != (m.dim, sl.stop - sl.start):
            raise ValueError(
                f"{m.name}: Jacobian block {var!r} has shape {block.shape}, "
                f"expected {(m.dim, sl.stop - sl.start)}"
            )
        H[:, sl] += block
    return H


def stack_measurements(measurements: Sequence[Measurement], name: str) -> Measurement:
    """Several independent measurements as one (residuals stacked, ``R`` block diagonal)."""
    if not measurements:
        raise ValueError("stack_measurements needs at least one measurement")
    sizes = [m.dim for m in measurements]
    total = sum(sizes)
    widths: dict[Var, int] = {}
    for m in measurements:
        for var, block in m.H.items():
            widths[var] = block.shape[1]
    H = {var: np.zeros((total, w)) for var, w in widths.items()}
    row = 0
    for m in measurements:
        for var, block in m.H.items():
            H[var][row : row + m.dim] = block
        row += m.dim
    return Measurement(
        residual=np.concatenate([m.residual for m in measurements]),
        H=H,
        R=block_diag(*[m.R for m in measurements]),
        name=name,
    )


@dataclass
class Augmentation:
    """A new state variable initialised from a measurement (thesis (3.38)–(3.43)).

    ``value`` (d,) the new variable's nominal value ``g(x̂, ŷ)``; ``G`` {var: (d, dim(var))}
    the Jacobian ``G_X = ∂g/∂δx``; ``R`` (d, d) the measurement noise mapped into the new
    variable, ``G_y R_y G_yᵀ``. Used by :func:`gaitnet.vio.covariance.augment_landmark`.
    """

    value: np.ndarray
    G: dict[Var, np.ndarray]
    R: np.ndarray
    name: str
