"""Real-time signal processing for the twin: causal filters, sliding windows and features.

Pure and free of I/O; every filter has a one-sample ``update`` and a batch ``process`` that
agree (Heide 2025, cycle steps 6-7: Hampel, Kalman and Butterworth filters, windowed features).
"""

from cnctwin.signals.filters import ButterworthFilter, CausalFilter, HampelFilter, KalmanFilter
from cnctwin.signals.windows import (
    SCALAR_FEATURES,
    SlidingWindow,
    amplitude_at,
    band_rms,
    mean,
    peak_to_peak,
    quantiles,
    rms,
    slope,
)

__all__ = [
    "SCALAR_FEATURES",
    "ButterworthFilter",
    "CausalFilter",
    "HampelFilter",
    "KalmanFilter",
    "SlidingWindow",
    "amplitude_at",
    "band_rms",
    "mean",
    "peak_to_peak",
    "quantiles",
    "rms",
    "slope",
]
