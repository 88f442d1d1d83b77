"""Causal, stateful real-time filters for measured signals (Hampel, Kalman, Butterworth).

Heide 2025 (Section 2.3, step 6 of the cycle) filters the machine's signals with Hampel,
Kalman and Butterworth filters in every cycle. Each filter here sees one sample at a time
(:meth:`CausalFilter.update`) and never looks ahead; :meth:`CausalFilter.process` filters a
whole array and equals the same samples fed one by one (and leaves the filter in the same
state), so an offline run reproduces the live one.

Non-finite input (NaN, infinity: a sample the machine did not deliver or delivered as garbage)
never enters a filter's state as such; each filter counts it in ``invalid_count``:

- :class:`HampelFilter` and :class:`ButterworthFilter` repeat the last finite input (a
  zero-order hold), which keeps their sample clock aligned with real time; before the first
  finite sample the output is NaN;
- :class:`KalmanFilter` predicts without a measurement update (the textbook treatment of a
  missing measurement), so its output is the prediction; before the first finite sample it
  is NaN.

Filters work on plain floats in the unit of the signal; the sample rate is in Hz.
"""

from __future__ import annotations

import bisect
import logging
import math
from abc import ABC, abstractmethod
from collections import deque
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal as sps

from cnctwin.errors import ConfigError

__all__ = [
    "ButterworthFilter",
    "CausalFilter",
    "HampelFilter",
    "KalmanFilter",
]

logger = logging.getLogger(__name__)

#: Scale of the median absolute deviation to the standard deviation of a normal distribution,
#: 1 / Phi^-1(3/4) (Hampel 1974; Pearson et al. 2016, "Generalized Hampel filters", Eq. 3).
MAD_TO_SIGMA = 1.4826


class CausalFilter(ABC):
    """A causal filter of one signal, one sample at a time.

    Attributes
    ----------
    invalid_count
        Non-finite inputs seen since construction or :meth:`reset`.
    """

    def __init__(self) -> None:
        self.invalid_count = 0

    @abstractmethod
    def update(self, x: float) -> float:
        """Filter one sample ``x`` (unit of the signal) and return the filtered value."""

    def process(self, x: ArrayLike) -> NDArray[np.float64]:
        """Filter the 1-D array ``x`` sample by sample; equals repeated :meth:`update`."""
        values = _as_1d(x)
        out = np.empty_like(values)
        update = self.update
        for i, v in enumerate(values.tolist()):
            out[i] = update(v)
        return out

    @abstractmethod
    def reset(self) -> None:
        """Forget every past sample (the state after construction)."""


def _as_1d(x: ArrayLike) -> NDArray[np.float64]:
    values = np.asarray(x, dtype=float)
    if values.ndim != 1:
        raise ConfigError(f"filter input has shape {values.shape}; give a 1-D array of samples")
    return values


class HampelFilter(CausalFilter):
    """Causal Hampel filter: replaces an outlier by the median of the last ``window`` samples.

    The window holds the current sample and the ``window - 1`` before it. With ``m`` its median
    and ``s = 1.4826 * median(|w - m|)`` (the scaled median absolute deviation), a sample with
    ``|x - m| > n_sigmas * s`` is an outlier and the output is ``m``; otherwise it is ``x``
    (Pearson et al. 2016, Eq. 1-3, made causal by ending the window at the current sample).
    The window holds the raw inputs, so a step in the signal passes once it fills more than
    half the window. Until the window is full the filter passes samples through.

    The price of causality: at a turning point of a smooth signal the newest sample lies at the
    edge of its window and may be replaced by the median (an error of up to the signal's
    change over half a window); a straight line or a constant passes exactly. A centred
    window would avoid this at the cost of a delay of half a window.

    Parameters
    ----------
    window
        Samples in the window, >= 3.
    n_sigmas
        Threshold in scaled MADs, > 0 (3 is the usual choice).

    Notes
    -----
    Cost per sample is O(window log window) in plain Python (a sorted copy of the window is
    kept), which for windows of tens of samples is a few microseconds.
    """

    def __init__(self, window: int = 7, n_sigmas: float = 3.0) -> None:
        super().__init__()
        if window < 3:
            raise ConfigError(f"Hampel window={window}; give at least 3 samples")
        if not n_sigmas > 0.0:
            raise ConfigError(f"Hampel n_sigmas={n_sigmas}; give a threshold > 0")
        self.window = int(window)
        self.n_sigmas = float(n_sigmas)
        self.outlier_count = 0
        self._fifo: deque[float] = deque()
        self._sorted: list[float] = []
        self._last_input = math.nan

    def reset(self) -> None:
        self.invalid_count = 0
        self.outlier_count = 0
        self._fifo.clear()
        self._sorted.clear()
        self._last_input = math.nan

    def update(self, x: float) -> float:
        if not math.isfinite(x):
            self.invalid_count += 1
            x = self._last_input
            if math.isnan(x):
                return math.nan
        else:
            self._last_input = x
        fifo, ordered = self._fifo, self._sorted
        if len(fifo) == self.window:
            old = fifo.popleft()
            del ordered[bisect.bisect_left(ordered, old)]
        fifo.append(x)
        bisect.insort(ordered, x)
        n = len(ordered)
        if n < self.window:
            return x
        half = n // 2
        median = ordered[half] if n % 2 else 0.5 * (ordered[half - 1] + ordered[half])
        deviations = sorted(abs(v - median) for v in ordered)
        mad = deviations[half] if n % 2 else 0.5 * (deviations[half - 1] + deviations[half])
        if abs(x - median) > self.n_sigmas * MAD_TO_SIGMA * mad:
            self.outlier_count += 1
            return median
        return x


class KalmanFilter(CausalFilter):
    """Linear Kalman filter of a scalar measurement: random-walk or constant-velocity model.

    ``model="random_walk"``: state ``x`` with ``x_k = x_{k-1} + w``, ``Var w = q``.
    ``model="constant_velocity"``: state ``(x, v)`` with ``F = [[1, dt], [0, 1]]`` and the
    continuous white-noise acceleration of spectral density ``q`` discretised as
    ``Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]]`` (Bar-Shalom, Li & Kirubarajan 2001, Sec. 6.2.2).
    Both measure ``z = x + v_z`` with ``Var v_z = r``. One :meth:`update` is a prediction and a
    measurement update (Kalman 1960); the output is the filtered position ``x``.

    Parameters
    ----------
    process_noise
        ``q``: (unit)^2 per step (random walk) or (unit/s^2)^2 s (constant velocity), > 0.
    measurement_noise
        ``r``: variance of one measurement, (unit)^2, > 0.
    model
        ``"random_walk"`` or ``"constant_velocity"``.
    dt_s
        Sample period in s (constant velocity only), > 0.
    initial_variance
        Variance of the state after the first measurement initialises it, (unit)^2; the
        default ``None`` uses ``measurement_noise`` (position) and ``1e6 * measurement_noise``
        per s^2 (velocity: unknown).

    Attributes
    ----------
    gain
        The last measurement update's Kalman gain of the position (NaN before the first).
    variance
        Posterior variance of the position estimate, (unit)^2.
    """

    def __init__(
        self,
        process_noise: float,
        measurement_noise: float,
        model: Literal["random_walk", "constant_velocity"] = "random_walk",
        dt_s: float = 1.0,
        initial_variance: float | None = None,
    ) -> None:
        super().__init__()
        for name, value in (
            ("process_noise", process_noise),
            ("measurement_noise", measurement_noise),
            ("dt_s", dt_s),
        ):
            if not (math.isfinite(value) and value > 0.0):
                raise ConfigError(f"Kalman {name}={value!r}; give a finite value > 0")
        if model not in ("random_walk", "constant_velocity"):
            raise ConfigError(
                f"Kalman model={model!r}; valid models are 'random_walk', 'constant_velocity'"
            )
        if initial_variance is not None and not initial_variance > 0.0:
            raise ConfigError(f"Kalman initial_variance={initial_variance!r}; give a value > 0")
        self.q = float(process_noise)
        self.r = float(measurement_noise)
        self.model = model
        self.dt_s = float(dt_s)
        self.initial_variance = initial_variance
        self.reset()

    def reset(self) -> None:
        self.invalid_count = 0
        self.gain = math.nan
        self._started = False
        # state (x, v) and covariance [[p00, p01], [p01, p11]]; v, p01, p11 stay 0 for a
        # random walk
        self._x = self._v = 0.0
        self._p00 = self._p01 = self._p11 = 0.0

    @property
    def variance(self) -> float:
        return self._p00 if self._started else math.nan

    @property
    def velocity(self) -> float:
        """Estimated rate of change, unit/s (constant velocity; 0 for a random walk)."""
        return self._v if self._started else math.nan

    def _start(self, z: float) -> float:
        self._started = True
        self._x = z
        self._p00 = self.r if self.initial_variance is None else self.initial_variance
        if self.model == "constant_velocity":
            self._p11 = 1e6 * self.r
        self.gain = 1.0
        return z

    def update(self, x: float) -> float:
        valid = math.isfinite(x)
        if not valid:
            self.invalid_count += 1
        if not self._started:
            return self._start(x) if valid else math.nan
        q = self.q
        # predict
        if self.model == "random_walk":
            p00 = self._p00 + q
            p01 = p11 = 0.0
        else:
            dt = self.dt_s
            self._x += dt * self._v
            p00 = self._p00 + 2.0 * dt * self._p01 + dt * dt * self._p11 + q * dt**3 / 3.0
            p01 = self._p01 + dt * self._p11 + q * dt * dt / 2.0
            p11 = self._p11 + q * dt
        if not valid:
            self._p00, self._p01, self._p11 = p00, p01, p11
            return self._x
        # measurement update, H = [1, 0]
        s = p00 + self.r
        k0 = p00 / s
        k1 = p01 / s
        innovation = x - self._x
        self._x += k0 * innovation
        self._v += k1 * innovation
        self._p00 = (1.0 - k0) * p00
        self._p01 = (1.0 - k0) * p01
        self._p11 = p11 - k1 * p01
        self.gain = k0
        return self._x


class ButterworthFilter(CausalFilter):
    """Digital Butterworth low-, high- or band-pass filter as cascaded second-order sections.

    The sections come from :func:`scipy.signal.butter` (``output="sos"``); one :meth:`update`
    runs each section in transposed direct form II, the same recursion as
    :func:`scipy.signal.sosfilt`, and :meth:`process` calls ``sosfilt`` with the filter's state
    as ``zi``, so streaming and batch filtering agree to rounding.

    Parameters
    ----------
    order
        Filter order, >= 1 (a band-pass has twice as many poles).
    cutoff_hz
        Cutoff frequency in Hz, or ``(low, high)`` for ``btype="bandpass"``; below Nyquist.
    sample_rate_hz
        Sampling rate in Hz, > 0 (80 Hz for the twin's 12.5 ms cycle).
    btype
        ``"lowpass"``, ``"highpass"`` or ``"bandpass"``.
    steady_start
        If true, the state is initialised to the steady state of the first finite sample
        (:func:`scipy.signal.sosfilt_zi`), which avoids the start-up transient of a signal
        with an offset; if false (default), the filter starts at rest (zero state), as
        ``sosfilt`` without ``zi`` does.
    """

    def __init__(
        self,
        order: int,
        cutoff_hz: float | tuple[float, float],
        sample_rate_hz: float,
        btype: Literal["lowpass", "highpass", "bandpass"] = "lowpass",
        steady_start: bool = False,
    ) -> None:
        super().__init__()
        if order < 1:
            raise ConfigError(f"Butterworth order={order}; give an order >= 1")
        if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0.0):
            raise ConfigError(f"Butterworth sample_rate_hz={sample_rate_hz!r}; give a rate > 0")
        cutoffs = np.atleast_1d(np.asarray(cutoff_hz, dtype=float))
        nyquist = sample_rate_hz / 2.0
        expected = 2 if btype == "bandpass" else 1
        if cutoffs.size != expected or not np.all((cutoffs > 0) & (cutoffs < nyquist)):
            raise ConfigError(
                f"Butterworth cutoff_hz={cutoff_hz!r} for btype {btype!r}; give {expected} "
                f"frequency(ies) strictly between 0 and Nyquist ({nyquist:g} Hz)"
            )
        self.order = int(order)
        self.sample_rate_hz = float(sample_rate_hz)
        self.steady_start = steady_start
        self.sos: NDArray[np.float64] = sps.butter(
            order,
            cutoffs if expected == 2 else float(cutoffs[0]),
            btype=btype,
            fs=sample_rate_hz,
            output="sos",
        )
        self._zi_unit: NDArray[np.float64] = sps.sosfilt_zi(self.sos)
        self._coef = [tuple(float(c) for c in row) for row in self.sos]
        self._z = [[0.0, 0.0] for _ in self._coef]
        self._last_input = math.nan

    def reset(self) -> None:
        self.invalid_count = 0
        self._z = [[0.0, 0.0] for _ in self._coef]
        self._last_input = math.nan

    @property
    def state(self) -> NDArray[np.float64]:
        """The filter's state, shaped like ``zi`` of :func:`scipy.signal.sosfilt`."""
        return np.array(self._z, dtype=float)

    def _first(self, x: float) -> None:
        if self.steady_start:
            self._z = (self._zi_unit * x).tolist()

    def update(self, x: float) -> float:
        if not math.isfinite(x):
            self.invalid_count += 1
            x = self._last_input
            if math.isnan(x):
                return math.nan
        else:
            if math.isnan(self._last_input):
                self._first(x)
            self._last_input = x
        y = x
        for (b0, b1, b2, _a0, a1, a2), z in zip(self._coef, self._z, strict=True):
            out = b0 * y + z[0]
            z[0] = b1 * y - a1 * out + z[1]
            z[1] = b2 * y - a2 * out
            y = out
        return y

    def process(self, x: ArrayLike) -> NDArray[np.float64]:
        values = _as_1d(x).copy()
        bad = ~np.isfinite(values)
        n_bad = int(bad.sum())
        self.invalid_count += n_bad
        if n_bad:
            # zero-order hold of the last finite input, carried over from earlier calls
            index = np.where(bad, 0, np.arange(values.size))
            np.maximum.accumulate(index, out=index)
            held = values[index]
            leading = bad & (index == 0) & bad[0]
            held[leading] = self._last_input
            values = held
        finite = np.isfinite(values)
        out = np.full_like(values, math.nan)
        if not finite.any():
            return out
        start = int(np.argmax(finite))  # samples before it are NaN (no finite input yet)
        if math.isnan(self._last_input):
            self._first(float(values[start]))
        y, zf = sps.sosfilt(self.sos, values[start:], zi=np.array(self._z, dtype=float))
        out[start:] = y
        self._z = zf.tolist()
        self._last_input = float(values[-1])
        return out
