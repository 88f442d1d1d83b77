"""Sliding windows and features: the ring buffer holds the last samples in order, and every
feature equals numpy (or a closed form) on the same samples."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from cnctwin.errors import DataError, InputError
from cnctwin.signals import SCALAR_FEATURES, SlidingWindow, amplitude_at, band_rms, slope

FS_HZ = 80.0

pushes = arrays(
    np.float64,
    st.integers(1, 200),
    elements=st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False),
)


@settings(max_examples=60, deadline=None)
@given(x=pushes, length=st.integers(2, 64))
def test_window_features_equal_numpy(x: np.ndarray, length: int) -> None:
    window = SlidingWindow(length, FS_HZ)
    for v in x:
        window.push(float(v))
    last = x[-length:]
    times = (np.arange(x.size) / FS_HZ)[-length:]
    np.testing.assert_array_equal(window.values(), last)
    np.testing.assert_allclose(window.times(), times)
    assert len(window) == last.size and window.full == (x.size >= length)
    assert window.mean() == pytest.approx(np.mean(last), rel=1e-12, abs=1e-9)
    assert window.rms() == pytest.approx(np.sqrt(np.mean(last**2)), rel=1e-12, abs=1e-9)
    assert window.peak_to_peak() == np.ptp(last)
    np.testing.assert_allclose(
        window.quantiles([0.05, 0.5, 0.95]), np.quantile(last, [0.05, 0.5, 0.95])
    )
    if last.size >= 2:
        expected = np.polyfit(times, last, 1)[0]
        assert window.slope() == pytest.approx(expected, rel=1e-6, abs=1e-6)
    for name, feature in SCALAR_FEATURES.items():
        assert feature(window) == pytest.approx(getattr(window, name)(), nan_ok=True)


def test_slope_of_a_line_with_explicit_times() -> None:
    window = SlidingWindow.of_duration(0.5, FS_HZ)
    assert window.length == 40
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.01, 0.015, 100))  # jittered cycle times
    for ti in t:
        window.push(7.0 - 3.5 * ti, t_s=float(ti))
    assert window.slope() == pytest.approx(-3.5, rel=1e-9)
    assert math.isnan(slope([1.0, 2.0], [1.0, 1.0]))


def test_amplitude_at_reads_sines_on_and_between_bins() -> None:
    n = 160  # 2 s at 80 Hz: bins every 0.5 Hz
    t = np.arange(n) / FS_HZ
    x = 12.0 + 3.0 * np.sin(2 * np.pi * 10.0 * t) + 0.5 * np.cos(2 * np.pi * 25.0 * t + 1.0)
    window = SlidingWindow(n, FS_HZ)
    for v in x:
        window.push(float(v))
    np.testing.assert_allclose(window.amplitude_at([10.0, 25.0]), [3.0, 0.5], rtol=1e-9)
    # equals numpy's FFT of the Hann-weighted samples at the bins
    w = 0.5 - 0.5 * np.cos(2 * np.pi * np.arange(n) / n)
    fft = 2 * np.abs(np.fft.rfft((x - x.mean()) * w)) / w.sum()
    np.testing.assert_allclose(
        window.amplitude_at([10.0, 17.5, 25.0]), fft[[20, 35, 50]], atol=1e-12
    )
    # the transform is evaluated at the asked frequency, off the bins too; a sine half a bin
    # (0.25 Hz) away from it reads 1.42 dB low, the Hann window's scalloping loss (Harris 1978)
    off_bin = np.sin(2 * np.pi * 10.25 * t)
    assert amplitude_at(off_bin, FS_HZ, 10.25)[0] == pytest.approx(1.0, rel=1e-3)
    assert 20 * np.log10(amplitude_at(off_bin, FS_HZ, 10.0)[0]) == pytest.approx(-1.42, abs=0.01)


def test_band_rms_by_parseval() -> None:
    n = 400
    t = np.arange(n) / FS_HZ
    x = 4.0 * np.sin(2 * np.pi * 5.0 * t) + 2.0 * np.sin(2 * np.pi * 30.0 * t) + 100.0
    assert band_rms(x, FS_HZ, 4.0, 6.0) == pytest.approx(4.0 / math.sqrt(2), rel=1e-9)
    assert band_rms(x, FS_HZ, 20.0, 40.0) == pytest.approx(2.0 / math.sqrt(2), rel=1e-9)
    noise = np.random.default_rng(1).normal(size=401)  # odd length: no Nyquist bin
    assert band_rms(noise, FS_HZ, 0.0, 40.0) == pytest.approx(np.std(noise), rel=1e-9)
    assert band_rms(noise[:400], FS_HZ, 0.0, 40.0) == pytest.approx(np.std(noise[:400]), rel=1e-9)


def test_push_allocates_nothing_and_clear_empties() -> None:
    window = SlidingWindow(8, FS_HZ)
    buffer = window._x
    for i in range(20):
        window.push(float(i))
    assert window._x is buffer
    window.clear()
    with pytest.raises(DataError, match="empty"):
        window.mean()


@pytest.mark.parametrize(
    "make",
    [
        lambda: SlidingWindow(1, FS_HZ),
        lambda: SlidingWindow(4, 0.0),
        lambda: SlidingWindow.of_duration(-1.0, FS_HZ),
        lambda: amplitude_at([1.0, 2.0], FS_HZ, 50.0),
        lambda: band_rms([1.0], FS_HZ, 5.0, 1.0),
    ],
)
def test_bad_window_settings_are_input_errors(make) -> None:
    with pytest.raises(InputError):
        make()
