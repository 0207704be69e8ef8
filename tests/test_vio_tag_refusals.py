"""Refused sheet poses (gaitnet.vio.tag_refusals): when refusals are steady, and the widening."""

from __future__ import annotations

import numpy as np

from gaitnet.vio.covariance import chi2_gate
from gaitnet.vio.measurement import Measurement
from gaitnet.vio.tag_refusals import RECOVERY_STEP_M, RefusedSheets


def _refusals(frames: list[int], residuals: list[float], n: int = 3) -> RefusedSheets:
    sheets = RefusedSheets(n)
    sheets.refused = [(k, np.array([r, 0.0, 0.0])) for k, r in zip(frames, residuals, strict=True)]
    return sheets


def test_steady_needs_n_decodes_in_a_row_that_move_little() -> None:
    step = 0.5 * RECOVERY_STEP_M
    assert _refusals([10, 11, 12], [0.1, 0.1 + step, 0.1 + 2 * step]).steady()
    assert _refusals([10, 12, 13], [0.1, 0.1, 0.1]).steady()  # one frame without a decode
    assert not _refusals([10, 13, 16], [0.1, 0.1, 0.1]).steady()  # every 3rd frame only
    assert not _refusals([10, 11, 12], [0.1, -0.2, 0.1]).steady()  # a jumping decode
    assert not _refusals([11, 12], [0.1, 0.1]).steady()  # too few
    assert not _refusals([10, 11, 12], [0.1, 0.1, 0.1], n=0).steady()  # never


def test_widen_if_steady_records_and_widens_on_the_nth_refusal() -> None:
    from gaitnet.geometry import quat_from_rotvec
    from gaitnet.vio.state import FilterState, ImuState

    imu = ImuState(quat_from_rotvec(np.zeros(3)), np.zeros(3), np.zeros(3), np.zeros(3),
                   np.zeros(3), 0.0)  # fmt: skip
    state = FilterState.new(imu, 1e-4 * np.eye(15))
    sheets = RefusedSheets(3)
    m = Measurement(np.array([1.0, 0.0, 0.0]), {"pos": np.eye(3)}, 1e-4 * np.eye(3), "sheet")
    before = state.P.copy()
    assert np.isnan(sheets.widen_if_steady(state, 5, m, 100.0, 0.99999))
    assert np.isnan(sheets.widen_if_steady(state, 6, m, 100.0, 0.99999))
    np.testing.assert_array_equal(state.P, before)
    factor = sheets.widen_if_steady(state, 7, m, 100.0, 0.99999)
    assert factor > 1.0
    S = state.P[3:6, 3:6] + m.R
    assert np.isclose(
        m.residual @ np.linalg.solve(S, m.residual), 0.5 * chi2_gate(3, 0.99999), rtol=0.01
    )
    attitude = Measurement(
        np.zeros(6), {"pos": np.eye(6, 3), "att": np.eye(6, 3, -3)}, np.eye(6), "pose"
    )
    assert np.isnan(sheets.widen_if_steady(state, 8, attitude, 100.0, 0.99999))  # not position-only
