"""The written-out second-order filters against scipy.signal (an independent implementation)
and against their defining properties."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from gaitnet.filters import butterworth2_lowpass, filtfilt2, lfilter2, lfilter2_zi


@pytest.mark.parametrize("cutoff", [0.01, 0.12, 0.5, 0.95])
def test_butterworth_coefficients_are_scipys_and_have_unit_dc_gain(cutoff) -> None:
    b, a = butterworth2_lowpass(cutoff)
    want_b, want_a = signal.butter(2, cutoff)
    np.testing.assert_allclose(b, want_b, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(a, want_a, rtol=1e-12, atol=1e-15)
    assert b.sum() / a.sum() == pytest.approx(1.0, abs=1e-12)
    # −3 dB at the cut-off: |H(e^{iω})|² = 1/2 at ω = π cutoff
    z = np.exp(-1j * np.pi * cutoff * np.arange(3))
    assert abs(b @ z / (a @ z)) ** 2 == pytest.approx(0.5, abs=1e-9)


@pytest.mark.parametrize("cutoff", [0.0, 1.0, -0.2, 1.5])
def test_butterworth_refuses_cut_offs_outside_nyquist(cutoff) -> None:
    with pytest.raises(ValueError, match="cut-off"):
        butterworth2_lowpass(cutoff)


def test_difference_equation_and_its_steady_state_are_scipys() -> None:
    rng = np.random.default_rng(2)
    b, a = rng.normal(size=3), np.array([1.3, -0.4, 0.2])
    x = rng.normal(size=(300, 2, 3))
    np.testing.assert_allclose(lfilter2(b, a, x), signal.lfilter(b, a, x, axis=0), atol=1e-12)
    zi = lfilter2_zi(b, a)
    np.testing.assert_allclose(zi, signal.lfilter_zi(b, a), atol=1e-12)
    # started in the steady state of a constant, the output is that constant times the DC gain
    step = lfilter2(b, a, np.full(50, 2.5), zi * 2.5)
    np.testing.assert_allclose(step, 2.5 * b.sum() / a.sum(), rtol=1e-12)
    assert lfilter2(b, a, np.zeros((0, 3))).shape == (0, 3)


@pytest.mark.parametrize("padlen", [0, 1, 6, 199])
@pytest.mark.parametrize("shape", [(200,), (200, 3)])
def test_zero_phase_filtering_is_scipys_filtfilt(padlen, shape) -> None:
    x = np.random.default_rng(4).normal(size=shape).cumsum(axis=0)
    b, a = butterworth2_lowpass(0.12)
    want = signal.filtfilt(b, a, x, axis=0, padlen=padlen)
    np.testing.assert_allclose(filtfilt2(b, a, x, padlen), want, atol=1e-10)


def test_zero_phase_filtering_does_not_shift_a_peak() -> None:
    t = np.arange(400)
    x = np.exp(-0.5 * ((t - 170.0) / 12.0) ** 2)
    y = filtfilt2(*butterworth2_lowpass(0.1), x, padlen=6)
    assert np.argmax(y) == 170 and y.max() < 1.0


def test_bad_signals_and_filters_are_refused() -> None:
    b, a = butterworth2_lowpass(0.1)
    with pytest.raises(ValueError, match="padlen"):
        filtfilt2(b, a, np.ones(5), padlen=5)
    with pytest.raises(ValueError, match="at least one sample"):
        filtfilt2(b, a, np.ones(0), padlen=0)
    with pytest.raises(ValueError, match="time axis"):
        lfilter2(b, a, np.float64(1.0))
    with pytest.raises(ValueError, match="pole at z = 1"):
        lfilter2_zi([1.0, 0.0, 0.0], [1.0, -1.0, 0.0])
    with pytest.raises(ValueError, match="3 coefficients"):
        lfilter2([1.0, 2.0], a, np.ones(4))


def test_gaitnet_infer_does_not_import_scipy_signal() -> None:
    """What the module is for: the infer command's modules run without ``scipy.signal``."""
    import subprocess
    import sys

    code = (
        "import sys, gaitnet.cli.commands, gaitnet.pipeline.infer, gaitnet.pipeline.outputs; "
        "print('scipy.signal' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
