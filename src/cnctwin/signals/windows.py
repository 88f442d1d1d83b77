"""Sliding windows over a signal and the features of a window (Heide 2025, cycle step 7).

A :class:`SlidingWindow` is a fixed-length ring buffer: :meth:`SlidingWindow.push` is O(1) and
allocates nothing; a feature is computed on demand in O(window) (spectra in O(window log
window)). The features are also plain functions of an array (:func:`mean`, :func:`rms`,
:func:`slope`, :func:`quantiles`, :func:`peak_to_peak`, :func:`amplitude_at`,
:func:`band_rms`), so an offline analysis computes exactly what the live twin computes.

Times are in s, frequencies in Hz; values keep the unit of the signal (a slope is unit/s).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cnctwin.errors import ConfigError, DataError, InputError

__all__ = [
    "SCALAR_FEATURES",
    "SlidingWindow",
    "amplitude_at",
    "band_rms",
    "mean",
    "peak_to_peak",
    "quantiles",
    "rms",
    "slope",
]


def _values(x: ArrayLike) -> NDArray[np.float64]:
    values = np.asarray(x, dtype=float)
    if values.ndim != 1 or values.size == 0:
        raise DataError(f"window has shape {values.shape}; a feature needs a non-empty 1-D array")
    return values


def mean(x: ArrayLike) -> float:
    """Arithmetic mean of the samples, unit of the signal."""
    return float(np.mean(_values(x)))


def rms(x: ArrayLike) -> float:
    """Root mean square of the samples, unit of the signal."""
    values = _values(x)
    return float(math.sqrt(float(np.dot(values, values)) / values.size))


def peak_to_peak(x: ArrayLike) -> float:
    """Largest minus smallest sample, unit of the signal."""
    values = _values(x)
    return float(values.max() - values.min())


def quantiles(x: ArrayLike, q: float | Sequence[float]) -> NDArray[np.float64]:
    """Quantiles ``q`` (each in [0, 1]) of the samples, linear interpolation (numpy default)."""
    probs = np.atleast_1d(np.asarray(q, dtype=float))
    if not np.all((probs >= 0.0) & (probs <= 1.0)):
        raise InputError(f"quantile levels {q!r}; give levels between 0 and 1")
    return np.asarray(np.quantile(_values(x), probs), dtype=float)


def slope(x: ArrayLike, t_s: ArrayLike) -> float:
    """Least-squares slope of the samples against their times, unit of the signal per s.

    ``sum((t - t_mean)(x - x_mean)) / sum((t - t_mean)^2)``; NaN for fewer than two distinct
    times.
    """
    values = _values(x)
    times = np.asarray(t_s, dtype=float)
    if times.shape != values.shape:
        raise DataError(f"times have shape {times.shape}, values {values.shape}; give one each")
    tc = times - times.mean()
    stt = float(np.dot(tc, tc))
    if stt == 0.0:
        return math.nan
    return float(np.dot(tc, values - values.mean()) / stt)


def amplitude_at(
    x: ArrayLike, sample_rate_hz: float, freqs_hz: float | Sequence[float]
) -> NDArray[np.float64]:
    """Amplitude of the sinusoidal component at each frequency, unit of the signal.

    The mean is removed, a periodic Hann window ``w`` applied and the discrete-time Fourier
    transform evaluated at each frequency:
    ``A(f) = 2 |sum w_k x_k exp(-2 pi i f k / fs)| / sum w_k`` (the window's coherent gain
    corrected), so a sine of amplitude ``A`` at the asked frequency reads ``A`` (exactly on a DFT
    bin from bin 2 up); a sine half a bin (``fs / 2N``) away reads up to 1.42 dB low, the Hann
    window's scalloping loss (Harris 1978,
    Table 1). At 0 Hz and Nyquist the factor 2 does not apply and is not removed.
    """
    values = _values(x)
    freqs = np.atleast_1d(np.asarray(freqs_hz, dtype=float))
    if not (sample_rate_hz > 0.0 and np.all((freqs >= 0) & (freqs <= sample_rate_hz / 2))):
        raise InputError(
            f"frequencies {freqs_hz!r} Hz at {sample_rate_hz!r} Hz; give a rate > 0 and "
            f"frequencies between 0 and Nyquist"
        )
    n = values.size
    k = np.arange(n)
    window = 0.5 - 0.5 * np.cos(2.0 * np.pi * k / n)  # periodic Hann
    weighted = (values - values.mean()) * window
    phase = np.exp(-2j * np.pi * np.outer(freqs, k) / sample_rate_hz)
    return np.asarray(2.0 * np.abs(phase @ weighted) / window.sum(), dtype=float)


def band_rms(x: ArrayLike, sample_rate_hz: float, low_hz: float, high_hz: float) -> float:
    """RMS of the signal's content between ``low_hz`` and ``high_hz`` (inclusive), unit of x.

    From the one-sided power spectrum of the samples with their mean removed (rectangular
    window) by Parseval's theorem: ``sqrt(sum_k c_k |X_k|^2) / N`` over the bins in the band,
    ``c_k = 2`` except at 0 Hz and Nyquist. Over the whole band it equals the standard
    deviation of the samples.
    """
    values = _values(x)
    if not (sample_rate_hz > 0.0 and 0.0 <= low_hz <= high_hz):
        raise InputError(
            f"band {low_hz!r}-{high_hz!r} Hz at {sample_rate_hz!r} Hz; give 0 <= low <= high"
        )
    n = values.size
    spectrum = np.fft.rfft(values - values.mean())
    freqs = np.fft.rfftfreq(n, d=1.0 / sample_rate_hz)
    power = np.abs(spectrum) ** 2
    power[1:] *= 2.0
    if n % 2 == 0:
        power[-1] /= 2.0  # the Nyquist bin has no mirror image
    in_band = (freqs >= low_hz) & (freqs <= high_hz)
    return float(math.sqrt(float(power[in_band].sum())) / n)


class SlidingWindow:
    """The last ``length`` samples of a signal and their times, in a ring buffer.

    Parameters
    ----------
    length
        Samples in the window, >= 2.
    sample_rate_hz
        Nominal sampling rate in Hz, > 0: the times of samples pushed without one
        (``t_s = None``) and the frequency axis of the spectral features.

    Notes
    -----
    :meth:`push` stores a value and a time in preallocated arrays (no allocation); features
    read the window in chronological order. A window that is not yet full computes its features
    over the samples it has.
    """

    def __init__(self, length: int, sample_rate_hz: float) -> None:
        if length < 2:
            raise ConfigError(f"window length={length}; give at least 2 samples")
        if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0.0):
            raise ConfigError(f"window sample_rate_hz={sample_rate_hz!r}; give a rate > 0")
        self.length = int(length)
        self.sample_rate_hz = float(sample_rate_hz)
        self._x = np.zeros(self.length)
        self._t = np.zeros(self.length)
        self._head = 0  # next slot to write
        self._count = 0
        self._pushed = 0

    @classmethod
    def of_duration(cls, duration_s: float, sample_rate_hz: float) -> SlidingWindow:
        """A window of ``round(duration_s * sample_rate_hz)`` samples (``duration_s`` in s)."""
        if not (math.isfinite(duration_s) and duration_s > 0.0):
            raise ConfigError(f"window duration_s={duration_s!r}; give a duration > 0")
        return cls(max(2, round(duration_s * sample_rate_hz)), sample_rate_hz)

    def __len__(self) -> int:
        return self._count

    @property
    def full(self) -> bool:
        """Whether the window holds ``length`` samples."""
        return self._count == self.length

    def clear(self) -> None:
        """Forget every sample."""
        self._head = self._count = self._pushed = 0

    def push(self, x: float, t_s: float | None = None) -> None:
        """Append the sample ``x`` taken at ``t_s`` (s; default: the nominal sample time)."""
        head = self._head
        self._x[head] = x
        self._t[head] = self._pushed / self.sample_rate_hz if t_s is None else t_s
        self._head = (head + 1) % self.length
        self._pushed += 1
        if self._count < self.length:
            self._count += 1

    def _ordered(self, buffer: NDArray[np.float64]) -> NDArray[np.float64]:
        if self._count < self.length:
            return buffer[: self._count]
        if self._head == 0:
            return buffer
        return np.concatenate((buffer[self._head :], buffer[: self._head]))

    def values(self) -> NDArray[np.float64]:
        """The samples, oldest first (a view or a copy: do not modify)."""
        self._require_samples()
        return self._ordered(self._x)

    def times(self) -> NDArray[np.float64]:
        """The samples' times in s, oldest first."""
        self._require_samples()
        return self._ordered(self._t)

    def _require_samples(self) -> None:
        if self._count == 0:
            raise DataError("the window is empty; push samples before computing features")

    def _unordered(self) -> NDArray[np.float64]:
        self._require_samples()
        return self._x[: self._count]

    def mean(self) -> float:
        """Mean of the window, unit of the signal."""
        return mean(self._unordered())

    def rms(self) -> float:
        """RMS of the window, unit of the signal."""
        return rms(self._unordered())

    def peak_to_peak(self) -> float:
        """Peak-to-peak of the window, unit of the signal."""
        return peak_to_peak(self._unordered())

    def quantiles(self, q: float | Sequence[float]) -> NDArray[np.float64]:
        """Quantiles ``q`` in [0, 1] of the window."""
        return quantiles(self._unordered(), q)

    def slope(self) -> float:
        """Least-squares slope against the samples' times, unit of the signal per s."""
        self._require_samples()
        return slope(self._x[: self._count], self._t[: self._count])

    def amplitude_at(self, freqs_hz: float | Sequence[float]) -> NDArray[np.float64]:
        """Amplitude at each frequency (Hz) of the window, see :func:`amplitude_at`."""
        return amplitude_at(self.values(), self.sample_rate_hz, freqs_hz)

    def band_rms(self, low_hz: float, high_hz: float) -> float:
        """RMS content of the window between two frequencies (Hz), see :func:`band_rms`."""
        return band_rms(self.values(), self.sample_rate_hz, low_hz, high_hz)


#: The scalar features by name, for configuration-driven feature lists.
SCALAR_FEATURES: dict[str, Callable[[SlidingWindow], float]] = {
    "mean": SlidingWindow.mean,
    "rms": SlidingWindow.rms,
    "peak_to_peak": SlidingWindow.peak_to_peak,
    "slope": SlidingWindow.slope,
}
