"""Process monitoring models of the twin: the force band (Heide 2025, use case 1).

Heide 2025 (Sec. 3.1) compares the measured process force with the force the twin predicts
from the dexel engagement and flags an anomaly when the measurement leaves a band around the
prediction. Here the band's half-width is the residual scatter (standard deviation of
measured minus predicted over recent in-band cycles) times ``k``, never below a minimum
width (absolute, and relative to the prediction); the scatter is learnt while the process
runs, so the band widens where the model fits worse.

The band also spans the previous cycle's prediction: the measurement and the prediction may
be up to one cycle apart in time (the measured force passes a causal filter, and the machine
samples its signals on its own clock), so where the prediction changes fast (entry into and
exit from the stock) the band covers both.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from cnctwin.twin.settings import ForceBandConfig

__all__ = ["BandResult", "ForceBand"]


@dataclass(frozen=True, slots=True)
class BandResult:
    """One cycle of the force band.

    Attributes
    ----------
    low_n, high_n
        Band edges, N.
    residual_n
        Measured minus predicted, N.
    scatter_n
        Residual standard deviation used for the width, N.
    armed
        Whether the band was checked this cycle (in contact long enough).
    out_of_band
        Armed and the measurement outside the band.
    """

    low_n: float
    high_n: float
    residual_n: float
    scatter_n: float
    armed: bool
    out_of_band: bool


class ForceBand:
    """A band around the predicted force, widened by the residual scatter.

    Parameters
    ----------
    config
        Width factor, minimum width, scatter window, arming threshold and settle time.
    """

    def __init__(self, config: ForceBandConfig) -> None:
        self.config = config
        self._residuals: deque[float] = deque(maxlen=config.scatter_window)
        self._sum = 0.0
        self._sum_sq = 0.0
        self._in_contact = 0
        self._previous_n: float | None = None

    def reset_contact(self) -> None:
        """Forget the contact count (after a gap): the band settles again before arming."""
        self._in_contact = 0
        self._previous_n = None

    @property
    def scatter_n(self) -> float:
        """Standard deviation of the kept residuals, N (0 with fewer than two)."""
        n = len(self._residuals)
        if n < 2:
            return 0.0
        mean = self._sum / n
        return math.sqrt(max(self._sum_sq / n - mean * mean, 0.0) * n / (n - 1))

    def update(self, predicted_n: float, measured_n: float) -> BandResult:
        """Check one cycle; learn its residual when it is in band.

        Parameters
        ----------
        predicted_n
            Predicted force, N.
        measured_n
            Measured (filtered) force, N.

        Returns
        -------
        BandResult
            The band and the verdict.
        """
        cfg = self.config
        residual = measured_n - predicted_n
        scatter = self.scatter_n
        half = max(cfg.k * scatter, cfg.min_width_n, cfg.min_width_rel * abs(predicted_n))
        previous = predicted_n if self._previous_n is None else self._previous_n
        self._previous_n = predicted_n
        low = min(predicted_n, previous) - half
        high = max(predicted_n, previous) + half
        if predicted_n >= cfg.min_predicted_n:
            self._in_contact += 1
        else:
            self._in_contact = 0
        armed = self._in_contact > cfg.settle_cycles
        out = armed and not (low <= measured_n <= high)
        # only a steady cycle teaches the scatter: where the prediction jumped (entry into or
        # exit from the stock) the band spans both predictions and a residual as large as the
        # jump would be learnt, widening the band for the next hundreds of cycles; the
        # coarser the cycle (an overloaded twin), the larger those jumps
        steady = abs(predicted_n - previous) <= half and abs(residual) <= half
        if armed and not out and steady:
            self._learn(residual)
        return BandResult(low, high, residual, scatter, armed, out)

    def _learn(self, residual: float) -> None:
        if len(self._residuals) == self._residuals.maxlen:
            old = self._residuals[0]
            self._sum -= old
            self._sum_sq -= old * old
        self._residuals.append(residual)
        self._sum += residual
        self._sum_sq += residual * residual
