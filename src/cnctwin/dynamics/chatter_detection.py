"""Chatter detection from a measured vibration or force signal: sliding-window spectra.

A stable milling cut vibrates periodically at the tooth period ``T = 60 / (N n)`` (n in rpm,
N teeth): its spectrum holds the tooth-passing frequency ``f_T = N n / 60`` and its harmonics
(and, with runout, the spindle frequency ``n / 60`` and its harmonics). Regenerative chatter
adds a component off these harmonics: near a natural frequency of the structure (Hopf
bifurcation, at ``f_c + k f_T``) or at odd multiples of ``f_T / 2`` (period doubling, flip).
The detector reads chatter where Ward 2021 (sec. 4.3) does, in the spectrum of the cut: a
dominant component away from the tooth-passing frequency (their 4591 Hz chatter against 656 Hz
tooth passing). Per window of ``window_s`` seconds it does:

1. take the window's samples, remove their mean, apply a Hann window and the real FFT
   (bin spacing, the spectral resolution, ``df = fs / n_window``);
2. notch out bands around the harmonics ``k f_T`` (k = 0, 1, ..., the k = 0 band removes the
   mean and slow drift) and, if asked, ``k n / 60``: half-width
   ``notch_bins df + k f_T speed_tolerance`` (the Hann main lobe is 2 bins wide on each side;
   the relative speed tolerance allows for a spindle running off its command);
3. the energy ratio ``R = sum(P off the notches) / sum(P outside the k = 0 band)``
   (P = |FFT|^2): 0 for a perfectly periodic response at the tooth period, near 1 when
   chatter dominates;
4. the dominant remaining peak: the strongest bin off the notches, refined by a parabola
   through the logarithms of the three bins around it (the chatter frequency, better than
   ``df`` for a single tone) and its amplitude (Hann-corrected, in the signal's unit);
5. the verdict: chatter when ``R > threshold`` (default :data:`DEFAULT_THRESHOLD` = 0.2).

The threshold: on the time-domain simulations of tests/dynamics/test_chatter_detection.py
(Insperger & Stépán's slot and a/D = 0.05 cuts at 0.7 and 1.3 times the semi-discretization's
critical depth) stable cuts give ``R`` below 0.02 once the entry transient has died away and
chattering ones 0.4 ... 1; 0.2 separates them with margin either side. A measured signal
also carries noise and structural resonances excited by the cut's harmonics, which raise R
of a stable cut: calibrate the threshold on a known stable cut of the same set-up
(docs/chatter.md).

With an even number of teeth, period-doubling chatter (odd multiples of ``f_T / 2``) falls
on spindle harmonics: notching those (``spindle_harmonics=True``, for a spindle with runout)
hides it.

:func:`detect_chatter` analyses a whole record; :class:`StreamingChatterDetector` takes the
samples as they arrive (a twin cycle's worth at a time) and analyses the same windows, with
the same result (tests/dynamics/test_chatter_detection.py).

Units: s, Hz, rpm at the edges named so; the signal in any unit (m, m/s^2, g, N).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from cnctwin.errors import ConfigError, DataError

__all__ = [
    "DEFAULT_THRESHOLD",
    "ChatterDetection",
    "DetectorSettings",
    "StreamingChatterDetector",
    "WindowVerdict",
    "analyse_window",
    "detect_chatter",
]

logger = logging.getLogger(__name__)

#: Default threshold of the energy ratio off the harmonics (module notes).
DEFAULT_THRESHOLD = 0.2
_NOTCH_BINS = 3.0  # notch half-width in bins: the Hann main lobe (2) and one more
_SPEED_TOLERANCE = 0.002  # relative spindle-speed error allowed for, per harmonic


@dataclass(frozen=True)
class DetectorSettings:
    """What and how the detector analyses.

    Attributes
    ----------
    sample_rate_hz
        Sampling rate of the signal in Hz, > 0.
    spindle_rpm
        Spindle speed in rpm, > 0.
    teeth
        Number of teeth N, >= 1.
    window_s
        Length of a window in s; rounded to whole samples, at least 16 samples.
    hop_s
        Time between the starts of consecutive windows in s; default (``None``) the window
        length (windows end to end); rounded to whole samples, at least one.
    threshold
        Energy ratio above which a window chatters, 0 < threshold < 1.
    spindle_harmonics
        Notch the spindle-frequency harmonics too (runout), not only the tooth-passing ones.
    notch_bins
        Half-width of each notch in bins (FFT bin spacing), >= 2.
    speed_tolerance
        Relative spindle-speed error allowed for: the notch of harmonic ``k`` widens by
        ``k f speed_tolerance`` Hz, >= 0.
    """

    sample_rate_hz: float
    spindle_rpm: float
    teeth: int
    window_s: float
    hop_s: float | None = None
    threshold: float = DEFAULT_THRESHOLD
    spindle_harmonics: bool = False
    notch_bins: float = _NOTCH_BINS
    speed_tolerance: float = _SPEED_TOLERANCE

    def __post_init__(self) -> None:
        _positive("sample_rate_hz", self.sample_rate_hz)
        _positive("spindle_rpm", self.spindle_rpm)
        if isinstance(self.teeth, bool) or not isinstance(self.teeth, int) or self.teeth < 1:
            raise ConfigError(f"teeth={self.teeth!r}; give an integer >= 1")
        _positive("window_s", self.window_s)
        if self.hop_s is not None:
            _positive("hop_s", self.hop_s)
        if not (0.0 < self.threshold < 1.0):
            raise ConfigError(f"threshold={self.threshold!r}; give 0 < threshold < 1")
        if not (math.isfinite(self.notch_bins) and self.notch_bins >= 2.0):
            raise ConfigError(f"notch_bins={self.notch_bins!r}; give a number >= 2")
        if not (math.isfinite(self.speed_tolerance) and self.speed_tolerance >= 0.0):
            raise ConfigError(f"speed_tolerance={self.speed_tolerance!r}; give a number >= 0")
        if self.window_samples < 16:
            raise ConfigError(
                f"window_s={self.window_s!r} s is {self.window_samples} samples at "
                f"{self.sample_rate_hz:g} Hz; give a window of at least 16 samples"
            )

    @property
    def window_samples(self) -> int:
        """Samples per window."""
        return int(round(self.window_s * self.sample_rate_hz))

    @property
    def hop_samples(self) -> int:
        """Samples between the starts of consecutive windows."""
        if self.hop_s is None:
            return self.window_samples
        return max(1, int(round(self.hop_s * self.sample_rate_hz)))

    @property
    def resolution_hz(self) -> float:
        """Spectral resolution (bin spacing) ``fs / n_window`` in Hz."""
        return self.sample_rate_hz / self.window_samples

    @property
    def tooth_passing_hz(self) -> float:
        """Tooth-passing frequency ``N n / 60`` in Hz."""
        return self.teeth * self.spindle_rpm / 60.0

    def notch_mask(self) -> np.ndarray:
        """True at the rfft bins inside a notch (k = 0 included), shape ``(n_window // 2 + 1,)``."""
        n = self.window_samples
        frequency = np.fft.rfftfreq(n, 1.0 / self.sample_rate_hz)
        base = [self.tooth_passing_hz]
        if self.spindle_harmonics:
            base.append(self.spindle_rpm / 60.0)
        mask = np.zeros(frequency.size, dtype=bool)
        width = self.notch_bins * self.resolution_hz
        for f0 in base:
            order = np.rint(frequency / f0)
            half = width + order * f0 * self.speed_tolerance
            mask |= np.abs(frequency - order * f0) <= half
        return mask


@dataclass(frozen=True)
class WindowVerdict:
    """The analysis of one window.

    Attributes
    ----------
    start_s, end_s
        Time of the window's first sample and just after its last, s from the record's start.
    energy_ratio
        Energy off the notches over the energy outside the k = 0 band, 0 ... 1.
    chatter_frequency_hz
        Frequency in Hz of the dominant peak off the notches (NaN if there is no energy).
    peak_amplitude
        Amplitude of that peak in the signal's unit (Hann-corrected, single-sided).
    chatter
        ``energy_ratio > threshold``.
    """

    start_s: float
    end_s: float
    energy_ratio: float
    chatter_frequency_hz: float
    peak_amplitude: float
    chatter: bool


@dataclass(frozen=True, eq=False)
class ChatterDetection:
    """Per-window results of :func:`detect_chatter`, as arrays (one entry per window).

    Attributes
    ----------
    settings
        The settings used.
    start_s, end_s
        Window start and end times in s.
    energy_ratio
        Energy ratio per window.
    chatter_frequency_hz
        Chatter (dominant off-harmonic) frequency per window in Hz.
    peak_amplitude
        Amplitude of that peak per window, signal unit.
    chatter
        Verdict per window.
    """

    settings: DetectorSettings
    start_s: np.ndarray
    end_s: np.ndarray
    energy_ratio: np.ndarray
    chatter_frequency_hz: np.ndarray
    peak_amplitude: np.ndarray
    chatter: np.ndarray

    def __len__(self) -> int:
        return int(self.start_s.size)

    def window(self, index: int) -> WindowVerdict:
        """The verdict of window ``index`` (negative counts from the end)."""
        return WindowVerdict(
            float(self.start_s[index]),
            float(self.end_s[index]),
            float(self.energy_ratio[index]),
            float(self.chatter_frequency_hz[index]),
            float(self.peak_amplitude[index]),
            bool(self.chatter[index]),
        )

    @property
    def chatter_fraction(self) -> float:
        """Fraction of the windows that chatter (0 without windows)."""
        return float(np.mean(self.chatter)) if len(self) else 0.0

    @property
    def first_chatter_s(self) -> float:
        """End time in s of the first chattering window: when chatter is known (NaN if none)."""
        hits = np.flatnonzero(self.chatter)
        return float(self.end_s[hits[0]]) if hits.size else math.nan


def analyse_window(
    samples: np.ndarray, settings: DetectorSettings, mask: np.ndarray | None = None
) -> tuple[float, float, float]:
    """Energy ratio, chatter frequency (Hz) and peak amplitude of one window (module notes).

    Parameters
    ----------
    samples
        ``settings.window_samples`` samples, any unit.
    settings
        Detector settings.
    mask
        :meth:`DetectorSettings.notch_mask`, if already computed.

    Returns
    -------
    tuple of float
        ``(energy_ratio, chatter_frequency_hz, peak_amplitude)``; ``(0, NaN, 0)`` for a window
        without energy outside the k = 0 band.
    """
    n = settings.window_samples
    x = np.asarray(samples, dtype=np.float64)
    if x.shape != (n,):
        raise DataError(f"window of shape {x.shape}; give {n} samples")
    notch = settings.notch_mask() if mask is None else mask
    taper = np.hanning(n)
    spectrum = np.fft.rfft((x - x.mean()) * taper)
    power = spectrum.real**2 + spectrum.imag**2
    frequency_step = settings.resolution_hz
    low = np.arange(power.size) * frequency_step <= settings.notch_bins * frequency_step
    total = float(power[~low].sum())
    off = np.where(notch, 0.0, power)
    remaining = float(off.sum())
    if total <= 0.0 or remaining <= 0.0:
        return 0.0, math.nan, 0.0
    peak = int(np.argmax(off))
    shift = 0.0
    if 0 < peak < power.size - 1 and off[peak - 1] > 0.0 and off[peak + 1] > 0.0:
        a, b, c = np.log(off[peak - 1 : peak + 2])
        curvature = a - 2.0 * b + c
        if curvature < 0.0:
            shift = 0.5 * (a - c) / curvature
    amplitude = 2.0 * math.sqrt(off[peak]) / float(taper.sum())
    return remaining / total, (peak + shift) * frequency_step, amplitude


def detect_chatter(
    signal: np.ndarray | list[float],
    settings: DetectorSettings,
) -> ChatterDetection:
    """Detect chatter in a record: windows of ``settings.window_s`` every ``settings.hop_s``.

    Window j holds samples ``j hop ... j hop + n_window - 1``; a tail shorter than a window
    is not analysed.

    Parameters
    ----------
    signal
        One-dimensional record, sampled at ``settings.sample_rate_hz``, any unit.
    settings
        Detector settings.

    Returns
    -------
    ChatterDetection
        Per-window energy ratio, chatter frequency, peak amplitude and verdict.

    Raises
    ------
    DataError
        If the signal is not one-dimensional and finite, or shorter than one window.
    """
    x = np.asarray(signal, dtype=np.float64)
    if x.ndim != 1 or not np.all(np.isfinite(x)):
        raise DataError(f"signal of shape {x.shape}; give one finite value per sample")
    n, hop = settings.window_samples, settings.hop_samples
    if x.size < n:
        raise DataError(
            f"signal of {x.size} samples ({x.size / settings.sample_rate_hz:g} s) is shorter "
            f"than one window of {n} samples ({settings.window_s:g} s); give a shorter window"
        )
    mask = settings.notch_mask()
    starts = np.arange(0, x.size - n + 1, hop)
    results = np.array([analyse_window(x[s : s + n], settings, mask) for s in starts])
    rate = settings.sample_rate_hz
    return ChatterDetection(
        settings=settings,
        start_s=starts / rate,
        end_s=(starts + n) / rate,
        energy_ratio=results[:, 0],
        chatter_frequency_hz=results[:, 1],
        peak_amplitude=results[:, 2],
        chatter=results[:, 0] > settings.threshold,
    )


class StreamingChatterDetector:
    """Chatter detection on samples as they arrive: the windows of :func:`detect_chatter`.

    Feed each cycle's new samples to :meth:`push`; every time a window completes (the first
    after ``n_window`` samples, then one per ``hop``) it is analysed, and :attr:`latest`
    holds the newest verdict. The windows, and so the verdicts, are those of
    :func:`detect_chatter` on the concatenated samples. Cost: one FFT of ``n_window`` samples
    per completed window (about 0.1 ms for 4096 samples), a ring buffer of one window.

    Parameters
    ----------
    settings
        Detector settings.
    """

    def __init__(self, settings: DetectorSettings) -> None:
        self.settings = settings
        self._n = settings.window_samples
        self._hop = settings.hop_samples
        self._mask = settings.notch_mask()
        self._buffer = np.zeros(self._n)
        self._count = 0  # samples received
        self._next_end = self._n  # sample count at which the next window completes
        self.latest: WindowVerdict | None = None

    @property
    def samples_received(self) -> int:
        """Samples pushed so far."""
        return self._count

    def push(self, samples: np.ndarray | list[float]) -> list[WindowVerdict]:
        """Add new samples; analyse every window they complete.

        Parameters
        ----------
        samples
            The next samples of the signal (any number, possibly none).

        Returns
        -------
        list of WindowVerdict
            The windows completed by these samples, oldest first (often none or one).

        Raises
        ------
        DataError
            If the samples are not a finite one-dimensional array.
        """
        x = np.asarray(samples, dtype=np.float64)
        if x.ndim != 1 or not np.all(np.isfinite(x)):
            raise DataError(f"samples of shape {x.shape}; give one finite value per sample")
        done: list[WindowVerdict] = []
        position = 0
        while position < x.size:
            take = min(x.size - position, self._next_end - self._count)
            self._append(x[position : position + take])
            position += take
            if self._count == self._next_end:
                done.append(self._analyse())
                self._next_end += self._hop
        if done:
            self.latest = done[-1]
        return done

    def _append(self, x: np.ndarray) -> None:
        n = self._n
        if x.size >= n:
            self._buffer[:] = x[-n:]
        elif x.size:
            self._buffer[: -x.size] = self._buffer[x.size :]
            self._buffer[-x.size :] = x
        self._count += x.size

    def _analyse(self) -> WindowVerdict:
        ratio, frequency, amplitude = analyse_window(self._buffer, self.settings, self._mask)
        rate = self.settings.sample_rate_hz
        return WindowVerdict(
            (self._count - self._n) / rate,
            self._count / rate,
            ratio,
            frequency,
            amplitude,
            ratio > self.settings.threshold,
        )


def _positive(name: str, value: float) -> None:
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = math.nan
    if not (math.isfinite(number) and number > 0.0):
        raise ConfigError(f"{name}={value!r}; give a finite number > 0")
