"""Causal filters: streaming equals batch, Butterworth equals scipy, Hampel removes spikes,
Kalman reaches the gain of the discrete algebraic Riccati equation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from numpy.lib.stride_tricks import sliding_window_view
from scipy import linalg, signal

from cnctwin.errors import ConfigError
from cnctwin.signals import ButterworthFilter, HampelFilter, KalmanFilter

FS_HZ = 80.0  # the twin's 12.5 ms cycle

samples = arrays(
    np.float64,
    st.integers(1, 300),
    elements=st.floats(-1e4, 1e4, allow_nan=False, allow_infinity=False),
)
samples_with_gaps = arrays(
    np.float64,
    st.integers(1, 300),
    elements=st.one_of(
        st.floats(-1e4, 1e4, allow_nan=False, allow_infinity=False),
        st.just(math.nan),
        st.just(math.inf),
    ),
)


def make_filters() -> list:
    return [
        HampelFilter(window=7, n_sigmas=3.0),
        KalmanFilter(process_noise=0.5, measurement_noise=4.0),
        KalmanFilter(
            process_noise=50.0, measurement_noise=4.0, model="constant_velocity", dt_s=1 / FS_HZ
        ),
        ButterworthFilter(4, 10.0, FS_HZ),
        ButterworthFilter(2, 10.0, FS_HZ, steady_start=True),
        ButterworthFilter(2, (5.0, 20.0), FS_HZ, btype="bandpass"),
    ]


# -- streaming == batch ------------------------------------------------------------------


@settings(max_examples=40, deadline=None)
@given(x=samples_with_gaps, split=st.integers(0, 300))
def test_batch_equals_streaming_and_splits(x: np.ndarray, split: int) -> None:
    """process() over any split of the array equals one update() per sample, and leaves the
    same state behind (the next sample filters the same)."""
    split = min(split, x.size)
    for one, other in zip(make_filters(), make_filters(), strict=True):
        streamed = np.array([one.update(float(v)) for v in x])
        batched = np.concatenate([other.process(x[:split]), other.process(x[split:])])
        np.testing.assert_allclose(batched, streamed, rtol=1e-9, atol=1e-6, equal_nan=True)
        assert one.invalid_count == other.invalid_count == int((~np.isfinite(x)).sum())
        assert one.update(1.0) == pytest.approx(other.update(1.0), rel=1e-9, abs=1e-6, nan_ok=True)


def test_reset_restores_the_initial_state() -> None:
    x = np.random.default_rng(1).normal(size=200)
    for flt in make_filters():
        first = flt.process(x)
        flt.reset()
        np.testing.assert_array_equal(flt.process(x), first)


# -- Butterworth -----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("order", "cutoff", "btype"),
    [(1, 5.0, "lowpass"), (4, 10.0, "lowpass"), (5, 3.0, "highpass"), (3, (4.0, 12.0), "bandpass")],
)
def test_butterworth_equals_scipy_sosfilt(order: int, cutoff, btype: str) -> None:
    """The streaming recursion reproduces scipy.signal.sosfilt on the whole record."""
    rng = np.random.default_rng(order)
    x = np.cumsum(rng.normal(size=2000)) + 5 * np.sin(2 * np.pi * 7 * np.arange(2000) / FS_HZ)
    sos = signal.butter(order, cutoff, btype=btype, fs=FS_HZ, output="sos")
    expected = signal.sosfilt(sos, x)
    flt = ButterworthFilter(order, cutoff, FS_HZ, btype=btype)
    streamed = np.array([flt.update(float(v)) for v in x])
    np.testing.assert_allclose(streamed, expected, rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(
        ButterworthFilter(order, cutoff, FS_HZ, btype=btype).process(x),
        expected,
        rtol=1e-12,
        atol=1e-12,
    )


def test_butterworth_steady_start_has_no_transient() -> None:
    """With steady_start a constant input passes unchanged from the first sample (sosfilt_zi)."""
    flt = ButterworthFilter(4, 5.0, FS_HZ, steady_start=True)
    np.testing.assert_allclose(flt.process(np.full(50, 321.0)), 321.0, rtol=1e-12)
    cold = ButterworthFilter(4, 5.0, FS_HZ)
    assert cold.update(321.0) < 1.0  # from rest the first output is tiny


def test_butterworth_attenuates_as_designed() -> None:
    """A sine's steady-state amplitude is the design's |H(f)| (scipy's sosfreqz), and at the
    cutoff -3 dB (the bilinear design is prewarped to the cutoff)."""
    n = 8000
    t = np.arange(n) / FS_HZ
    flt = ButterworthFilter(4, 10.0, FS_HZ)
    for f in (10.0, 20.0):
        flt.reset()
        y = flt.process(np.sin(2 * np.pi * f * t))[n // 2 :]
        _, h = signal.sosfreqz(flt.sos, worN=[f], fs=FS_HZ)
        assert np.sqrt(2) * np.std(y) == pytest.approx(abs(h[0]), rel=2e-3)
    _, h = signal.sosfreqz(flt.sos, worN=[10.0], fs=FS_HZ)
    assert abs(h[0]) == pytest.approx(1 / np.sqrt(2), rel=1e-6)


def test_butterworth_holds_input_over_nan() -> None:
    """A NaN is replaced by the last finite input: same as filtering the held sequence."""
    x = np.array([1.0, 2.0, np.nan, np.inf, 3.0])
    held = np.array([1.0, 2.0, 2.0, 2.0, 3.0])
    flt = ButterworthFilter(2, 10.0, FS_HZ)
    np.testing.assert_allclose(flt.process(x), ButterworthFilter(2, 10.0, FS_HZ).process(held))
    assert flt.invalid_count == 2
    assert math.isnan(ButterworthFilter(2, 10.0, FS_HZ).update(math.nan))


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(order=0, cutoff_hz=5.0),
        dict(order=2, cutoff_hz=40.0),
        dict(order=2, cutoff_hz=-1.0),
        dict(order=2, cutoff_hz=(1.0, 2.0)),
    ],
)
def test_butterworth_rejects_bad_design(kwargs) -> None:
    with pytest.raises(ConfigError, match="Butterworth"):
        ButterworthFilter(sample_rate_hz=FS_HZ, **kwargs)


# -- Hampel ----------------------------------------------------------------------------


def reference_hampel(x: np.ndarray, window: int, n_sigmas: float) -> np.ndarray:
    """Vectorised causal Hampel with numpy's median over each trailing window."""
    out = x.copy()
    win = sliding_window_view(x, window)  # row j covers samples j .. j+window-1
    med = np.median(win, axis=1)
    mad = 1.4826 * np.median(np.abs(win - med[:, None]), axis=1)
    current = x[window - 1 :]
    bad = np.abs(current - med) > n_sigmas * mad
    out[window - 1 :][bad] = med[bad]
    return out


@settings(max_examples=50, deadline=None)
@given(x=samples.filter(lambda a: a.size >= 3), window=st.integers(3, 15))
def test_hampel_equals_numpy_reference(x: np.ndarray, window: int) -> None:
    out = HampelFilter(window, 2.5).process(x)
    if x.size < window:
        np.testing.assert_array_equal(out, x)  # passes through until the window is full
    else:
        np.testing.assert_array_equal(out, reference_hampel(x, window, 2.5))


def test_hampel_leaves_clean_data_unchanged() -> None:
    """A constant and a straight line pass exactly (the newest sample of a linear window is
    (w-1)/2 steps from the median, inside 3 scaled MADs of ~w/4 steps)."""
    t = np.arange(2000) / FS_HZ
    for clean in (np.full(t.size, 412.0), 300.0 + 37.0 * t, 5.0 - 2.0 * t):
        assert np.array_equal(HampelFilter(9, 3.0).process(clean), clean)


def test_hampel_removes_injected_spikes() -> None:
    rng = np.random.default_rng(7)
    t = np.arange(4000) / FS_HZ
    clean = 300 + 80 * np.sin(2 * np.pi * 0.7 * t) + 10 * t  # a force with a trend, N
    spiky = clean.copy()
    where = rng.choice(np.arange(20, clean.size), size=60, replace=False)
    spiky[where] += rng.choice([-1, 1], size=where.size) * rng.uniform(200, 2000, where.size)
    out = HampelFilter(9, 3.0).process(spiky)
    # a replaced sample takes the median of the window, which lies inside the clean signal's
    # range over the window while fewer than half its samples are spikes
    windows = sliding_window_view(clean, 9)
    low, high = windows.min(axis=1) - 1e-9, windows.max(axis=1) + 1e-9
    assert np.all((out[8:] >= low) & (out[8:] <= high))
    # (the window spans < 40 N of clean signal, the spikes were 200-2000 N: all are gone)
    assert np.max(high - low) < 40.0
    # the limit of a causal window: at the sine's turning points the newest clean sample lies
    # at the window's edge and may be replaced too; a few percent of the samples here
    touched = np.setdiff1d(np.flatnonzero(out != spiky), where)
    assert touched.size < 0.05 * clean.size


def test_hampel_flags_few_samples_of_stationary_noise() -> None:
    """On Gaussian noise a 3-sigma rule replaces a small fraction (about 0.3 % for a known
    sigma; more here, as median and MAD are estimated from 9 samples)."""
    x = np.random.default_rng(3).normal(size=20000)
    flt = HampelFilter(9, 3.0)
    flt.process(x)
    assert 0.001 < flt.outlier_count / x.size < 0.05


def test_hampel_passes_until_full_and_holds_over_nan() -> None:
    flt = HampelFilter(5)
    assert [flt.update(v) for v in (1.0, 100.0, 1.0, 1.0)] == [1.0, 100.0, 1.0, 1.0]
    assert flt.update(math.nan) == 1.0  # held input 1.0 joins the window
    assert flt.update(1.0) == 1.0 and flt.invalid_count == 1


# -- Kalman ----------------------------------------------------------------------------


@pytest.mark.parametrize(("q", "r"), [(0.01, 1.0), (1.0, 1.0), (5.0, 0.2)])
def test_random_walk_gain_converges_to_riccati(q: float, r: float) -> None:
    """Steady-state gain: closed form of the scalar Riccati equation,
    P = (q + sqrt(q^2 + 4 q r)) / 2, K = P / (P + r), and scipy's DARE agree with the filter."""
    p_closed = (q + math.sqrt(q * q + 4 * q * r)) / 2
    k_closed = p_closed / (p_closed + r)
    p_dare = linalg.solve_discrete_are(np.eye(1), np.eye(1), np.array([[q]]), np.array([[r]]))
    assert p_dare[0, 0] == pytest.approx(p_closed, rel=1e-9)  # the a-priori covariance
    flt = KalmanFilter(q, r)
    flt.process(np.random.default_rng(0).normal(size=500))
    assert flt.gain == pytest.approx(k_closed, rel=1e-9)
    assert flt.variance == pytest.approx((1 - k_closed) * p_closed, rel=1e-9)


def test_constant_velocity_gain_converges_to_riccati() -> None:
    dt, q, r = 1 / FS_HZ, 200.0, 4.0
    f = np.array([[1.0, dt], [0.0, 1.0]])
    qm = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    h = np.array([[1.0, 0.0]])
    # filtering DARE is the dual of control: solve with (F^T, H^T) -> a priori covariance
    p_prior = linalg.solve_discrete_are(f.T, h.T, qm, np.array([[r]]))
    k = p_prior @ h.T / (h @ p_prior @ h.T + r)
    flt = KalmanFilter(q, r, model="constant_velocity", dt_s=dt)
    flt.process(np.random.default_rng(0).normal(size=3000))
    assert flt.gain == pytest.approx(k[0, 0], rel=1e-7)


def test_kalman_hand_computed_first_steps() -> None:
    """Two steps by hand: x0 = z0, P0 = r; then P- = P0 + q, K = P-/(P- + r)."""
    q, r = 1.0, 4.0
    flt = KalmanFilter(q, r)
    assert flt.update(10.0) == 10.0
    k = (r + q) / (r + q + r)  # 5/9
    assert flt.update(19.0) == pytest.approx(10.0 + k * 9.0)
    assert flt.variance == pytest.approx((1 - k) * (r + q))


def test_constant_velocity_tracks_a_ramp_without_lag() -> None:
    t = np.arange(2000) / FS_HZ
    ramp = 3.0 + 50.0 * t  # e.g. a force rising 50 N/s
    flt = KalmanFilter(1.0, 1.0, model="constant_velocity", dt_s=1 / FS_HZ)
    out = flt.process(ramp + np.random.default_rng(2).normal(0, 1.0, t.size))
    assert abs(np.mean(out[-500:] - ramp[-500:])) < 0.2
    assert flt.velocity == pytest.approx(50.0, rel=0.05)
    walk = KalmanFilter(1.0, 1.0).process(ramp)
    assert np.mean(ramp[-500:] - walk[-500:]) > 0.2  # the random walk lags a ramp


def test_kalman_predicts_over_missing_measurements() -> None:
    flt = KalmanFilter(1.0, 1.0, model="constant_velocity", dt_s=0.1)
    for i in range(200):
        flt.update(2.0 * i * 0.1)  # slope 2 per s
    last = flt.update(2.0 * 200 * 0.1)
    predicted = flt.update(math.nan)
    assert predicted == pytest.approx(last + 2.0 * 0.1, rel=1e-6)
    assert flt.invalid_count == 1
    assert math.isnan(KalmanFilter(1.0, 1.0).update(math.nan))


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(process_noise=0.0, measurement_noise=1.0),
        dict(process_noise=1.0, measurement_noise=-1.0),
        dict(process_noise=1.0, measurement_noise=1.0, model="bogus"),
    ],
)
def test_kalman_rejects_bad_parameters(kwargs) -> None:
    with pytest.raises(ConfigError, match="Kalman"):
        KalmanFilter(**kwargs)
