"""Frequency response functions from impact (tap) tests: windows, the H1 estimator, coherence.

An impact test records the hammer force ``f(t)`` and the response ``y(t)`` (usually an
accelerometer) once per hit. With ``F_i`` and ``Y_i`` the discrete Fourier transforms of hit
``i`` of ``n`` hits, the H1 estimator and the ordinary coherence are (Bendat and Piersol,
*Random Data*, 4th ed. 2010, ch. 9; the auto- and cross-spectra are sums over hits):

    H1(w) = sum_i conj(F_i) Y_i / sum_i |F_i|^2
    gamma^2(w) = |sum_i conj(F_i) Y_i|^2 / (sum_i |F_i|^2  sum_i |Y_i|^2)

H1 is unbiased by noise on the response; gamma^2 in [0, 1] says how much of the response is
linearly explained by the force (1 for a single hit by construction, so not reported).

Windows. The *force window* keeps the pulse and zeroes the force after it, removing the noise a
long record adds to ``|F|^2``. The *exponential window* ``exp(-t / tau)`` forces a lightly damped
response to decay inside the record (no leakage). Applied to force and response alike it turns
the measured FRF into ``H(j w + 1/tau)``: every pole moves left by ``1/tau``, and the residues
do not change (Fladung and Rost, Mech. Syst. Signal Process. 11(1), 1997).
:func:`window_damping_correction` removes that added damping from fitted modes; :class:`FRF`
carries ``1/tau`` as ``window_decay`` so that :func:`cnctwin.dynamics.modal.fit_modes` does it
by itself.

Units: SI. Angular frequency in rad/s, time in s, force in N; the FRF in (response unit)/N: m/N
for a receptance, (m/s)/N for a mobility, (m/s^2)/N for an accelerance.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cnctwin.errors import DataError

__all__ = [
    "FRF",
    "FRFQuantity",
    "accelerance_to_receptance",
    "exponential_window",
    "force_window",
    "impact_frf",
    "window_damping_correction",
]

_log = logging.getLogger(__name__)

FRFQuantity = Literal["receptance", "mobility", "accelerance"]
_QUANTITIES: tuple[str, ...] = ("receptance", "mobility", "accelerance")
# Powers of (j w) that turn each quantity into a receptance: H_x = H / (j w)^p.
_POWER = {"receptance": 0, "mobility": 1, "accelerance": 2}
# A force auto-spectrum this far below its peak (240 dB) counts as no excitation at all.
_NULL_POWER = 1e-24


@dataclass(frozen=True)
class FRF:
    """A frequency response function on a grid of angular frequencies.

    Attributes
    ----------
    omega
        Angular frequencies, rad/s, increasing, >= 0.
    h
        Complex FRF at ``omega``: m/N (receptance), (m/s)/N (mobility) or (m/s^2)/N
        (accelerance), as ``quantity`` says.
    quantity
        ``"receptance"``, ``"mobility"`` or ``"accelerance"``.
    coherence
        Ordinary coherence gamma^2 in [0, 1] at ``omega``, or None when unknown (an FRF read
        from a file).
    averages
        Number of hits averaged (0 when unknown).
    window_decay
        Decay rate ``1/tau`` of the exponential window applied to the records, 1/s (0 for none).
        Every pole of this FRF is ``1/tau`` more damped than the structure's.
    """

    omega: NDArray[np.float64]
    h: NDArray[np.complex128]
    quantity: FRFQuantity = "receptance"
    coherence: NDArray[np.float64] | None = None
    averages: int = 0
    window_decay: float = 0.0

    def __post_init__(self) -> None:
        omega = np.asarray(self.omega, dtype=float)
        h = np.asarray(self.h, dtype=complex)
        if omega.ndim != 1 or h.shape != omega.shape:
            raise DataError(
                f"FRF: omega has shape {omega.shape} and h {h.shape}; give two 1-D arrays of "
                "equal length"
            )
        if omega.size < 2 or not np.all(np.isfinite(omega)) or np.any(np.diff(omega) <= 0.0):
            raise DataError("FRF: omega must hold at least 2 finite, strictly increasing rad/s")
        if omega[0] < 0.0:
            raise DataError(f"FRF: omega starts at {omega[0]:g} rad/s; give omega >= 0")
        if self.quantity not in _QUANTITIES:
            raise DataError(f"FRF: quantity {self.quantity!r}; valid: {', '.join(_QUANTITIES)}")
        if not (np.isfinite(self.window_decay) and self.window_decay >= 0.0):
            raise DataError(f"FRF: window_decay {self.window_decay!r} 1/s; give a value >= 0")
        object.__setattr__(self, "omega", omega)
        object.__setattr__(self, "h", h)
        if self.coherence is not None:
            coherence = np.asarray(self.coherence, dtype=float)
            if coherence.shape != omega.shape:
                raise DataError(
                    f"FRF: coherence has shape {coherence.shape}; give one value per frequency "
                    f"({omega.shape})"
                )
            object.__setattr__(self, "coherence", coherence)

    def band(self, omega_low: float, omega_high: float) -> FRF:
        """The part of this FRF with ``omega_low <= omega <= omega_high`` (rad/s).

        Raises
        ------
        DataError
            When fewer than 2 frequencies fall in the band.
        """
        keep = (self.omega >= omega_low) & (self.omega <= omega_high)
        if np.count_nonzero(keep) < 2:
            raise DataError(
                f"band {omega_low:g}..{omega_high:g} rad/s holds {np.count_nonzero(keep)} "
                f"frequencies; the FRF spans {self.omega[0]:g}..{self.omega[-1]:g} rad/s"
            )
        return FRF(
            self.omega[keep],
            self.h[keep],
            self.quantity,
            None if self.coherence is None else self.coherence[keep],
            self.averages,
            self.window_decay,
        )

    def to_receptance(self) -> FRF:
        """The same FRF as a receptance, m/N: ``H_x = H / (j w + 1/tau)^p``, p = 0, 1, 2.

        ``1/tau`` is ``window_decay`` (0 without an exponential window). A windowed record
        measures the structure at ``s = j w + 1/tau``, where ``X(s) = A(s) / s^2``; dividing by
        ``(j w)^2`` instead would distort the windowed FRF away from ``X(j w + 1/tau)`` and spoil
        :func:`window_damping_correction`. The bin at ``omega = 0`` is dropped from a mobility or
        an accelerance (it has no displacement); see :func:`accelerance_to_receptance`.
        """
        power = _POWER[self.quantity]
        if power == 0:
            return self
        keep = self.omega > 0.0
        omega = self.omega[keep]
        return FRF(
            omega,
            self.h[keep] / (1j * omega + self.window_decay) ** power,
            "receptance",
            None if self.coherence is None else self.coherence[keep],
            self.averages,
            self.window_decay,
        )


def accelerance_to_receptance(omega: ArrayLike, accelerance: ArrayLike) -> NDArray[np.complex128]:
    """Receptance from accelerance: ``X/F = (A/F) / (j w)^2 = -(A/F) / w^2``.

    Parameters
    ----------
    omega
        Angular frequencies, rad/s, all > 0.
    accelerance
        Complex accelerance at ``omega``, (m/s^2)/N.

    Returns
    -------
    numpy.ndarray
        Complex receptance, m/N.

    Raises
    ------
    DataError
        When an ``omega`` is <= 0 (a static displacement cannot be had from acceleration) or
        not finite.
    """
    w = np.asarray(omega, dtype=float)
    if not np.all(np.isfinite(w) & (w > 0.0)):
        bad = float(w[~(np.isfinite(w) & (w > 0.0))].flat[0])
        raise DataError(
            f"accelerance_to_receptance: omega {bad!r} rad/s; give finite values > 0 "
            "(drop the 0 bin)"
        )
    receptance: NDArray[np.complex128] = -np.asarray(accelerance, dtype=complex) / w**2
    return receptance


def force_window(
    force: ArrayLike,
    dt: float,
    width: float | None = None,
    *,
    threshold: float = 0.02,
) -> NDArray[np.float64]:
    """The force window of one impact record: 1 up to the end of the window, 0 after it.

    The window starts at the record's start (so a pre-trigger stays in) and ends ``width`` after
    the impact begins; the impact begins at the last sample before the force peak whose
    magnitude is below ``threshold`` times the peak. Without ``width`` the window ends two pulse
    lengths after the pulse (the pulse ends at the first sample after the peak below
    ``threshold`` times the peak), which keeps the whole pulse and its ringing out of the noise.

    Parameters
    ----------
    force
        Hammer force of one hit, N, sampled every ``dt``.
    dt
        Sampling interval, s.
    width
        Length of the window after the start of the impact, s; None for the automatic length.
    threshold
        Fraction of the peak force below which the force counts as zero, in (0, 1).

    Returns
    -------
    numpy.ndarray
        The window, same length as ``force``, values 0 or 1.

    Raises
    ------
    DataError
        For a record with no force, a bad ``dt``, ``width`` or ``threshold``.
    """
    f = np.abs(np.asarray(force, dtype=float))
    if f.ndim != 1 or f.size < 4:
        raise DataError(f"force_window: force has shape {f.shape}; give one record of >= 4 samples")
    if not (dt > 0.0 and np.isfinite(dt)):
        raise DataError(f"force_window: dt {dt!r} s; give a sampling interval > 0")
    if not 0.0 < threshold < 1.0:
        raise DataError(f"force_window: threshold {threshold!r}; give a fraction in (0, 1)")
    peak_index = int(np.argmax(f))
    peak = f[peak_index]
    if not (peak > 0.0 and np.isfinite(peak)):
        raise DataError("force_window: the force record is zero or not finite; no impact found")
    below = f < threshold * peak
    before = np.flatnonzero(below[:peak_index])
    start = int(before[-1]) if before.size else 0
    after = np.flatnonzero(below[peak_index:])
    end = peak_index + int(after[0]) if after.size else f.size
    if width is None:
        stop = end + 2 * (end - start)
    else:
        if not (width > 0.0 and np.isfinite(width)):
            raise DataError(f"force_window: width {width!r} s; give a length > 0")
        stop = start + int(np.ceil(width / dt))
        if stop < end:
            _log.warning(
                "force window of %.3g s ends %.3g s before the pulse does", width, (end - stop) * dt
            )
    window = np.zeros(f.size)
    window[: min(stop + 1, f.size)] = 1.0
    return window


def exponential_window(n: int, dt: float, tau: float) -> NDArray[np.float64]:
    """The exponential window ``exp(-t / tau)`` at ``t = 0, dt, ..., (n - 1) dt``.

    Parameters
    ----------
    n
        Number of samples.
    dt
        Sampling interval, s.
    tau
        Time constant, s (> 0). The window adds ``1/tau`` (1/s) to every pole's decay rate.

    Returns
    -------
    numpy.ndarray
        The window, length ``n``.
    """
    if not (tau > 0.0 and np.isfinite(tau)):
        raise DataError(f"exponential window: tau {tau!r} s; give a time constant > 0")
    window: NDArray[np.float64] = np.exp(-np.arange(n) * dt / tau)
    return window


def window_damping_correction(
    omega_n: ArrayLike, zeta: ArrayLike, window_decay: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Remove an exponential window's damping from fitted modes.

    A mode fitted to a windowed FRF has the pole ``-zeta_w w_w + j w_d``; the structure's pole is
    ``1/tau`` to the right with the same damped frequency ``w_d`` (Fladung and Rost 1997):
    ``sigma = zeta_w w_w - 1/tau``, ``w_n = sqrt(sigma^2 + w_d^2)``, ``zeta = sigma / w_n``.

    Parameters
    ----------
    omega_n
        Natural frequencies fitted to the windowed FRF, rad/s.
    zeta
        Damping ratios fitted to the windowed FRF (dimensionless).
    window_decay
        ``1/tau`` of the window, 1/s.

    Returns
    -------
    omega_n, zeta
        The structure's natural frequencies (rad/s) and damping ratios. A ratio that comes out
        <= 0 (the window's damping exceeded the fitted one: noise, or a bad ``tau``) is returned
        as is, negative, and logged.
    """
    w = np.asarray(omega_n, dtype=float)
    z = np.asarray(zeta, dtype=float)
    sigma = z * w - window_decay
    omega_d = w * np.sqrt(np.clip(1.0 - z**2, 0.0, None))
    w_true = np.hypot(sigma, omega_d)
    z_true = sigma / w_true
    if np.any(z_true <= 0.0):
        _log.warning(
            "exponential window decay %.3g 1/s exceeds a fitted mode's decay; damping <= 0",
            window_decay,
        )
    return w_true, z_true


def impact_frf(
    force: ArrayLike,
    response: ArrayLike,
    dt: float,
    *,
    quantity: FRFQuantity = "accelerance",
    force_window_width: float | None = None,
    use_force_window: bool = True,
    tau: float | None = None,
) -> FRF:
    """The H1 FRF and the coherence of one or several impact records.

    Parameters
    ----------
    force
        Hammer force, N: one record (1-D) or one row per hit (2-D), sampled every ``dt``, each
        record starting before its impact.
    response
        Response, same shape as ``force``: m/s^2 (accelerometer), m/s or m as ``quantity``
        says.
    dt
        Sampling interval, s.
    quantity
        What ``response`` measures: ``"accelerance"`` (acceleration), ``"mobility"``
        (velocity) or ``"receptance"`` (displacement). Convert with :meth:`FRF.to_receptance`.
    force_window_width
        Length of the force window after the start of the impact, s; None for the automatic
        length of :func:`force_window`.
    use_force_window
        Apply the force window (True) or take the force record as it is.
    tau
        Time constant of an exponential window applied to force and response, s; None for no
        exponential window. The returned FRF carries ``window_decay = 1/tau``.

    Returns
    -------
    FRF
        H1 at the ``n//2 + 1`` frequencies ``2 pi k / (n dt)``, rad/s (less any where the
        hits put no force in, 240 dB below the peak: a spectral null), with the number of hits
        and the coherence (None for a single hit, whose coherence is 1 by construction); the bin
        ``omega = 0`` included.

    Raises
    ------
    DataError
        For records of different shapes, too short, not finite, or a record with no force.
    """
    f = np.atleast_2d(np.asarray(force, dtype=float))
    y = np.atleast_2d(np.asarray(response, dtype=float))
    if f.ndim != 2 or f.shape != y.shape:
        raise DataError(
            f"impact_frf: force {f.shape} and response {y.shape}; give equal shapes, one row "
            "per hit"
        )
    if f.shape[1] < 4:
        raise DataError(f"impact_frf: records of {f.shape[1]} samples; give at least 4")
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(y))):
        raise DataError("impact_frf: the records hold NaN or infinite samples")
    if not (dt > 0.0 and np.isfinite(dt)):
        raise DataError(f"impact_frf: dt {dt!r} s; give a sampling interval > 0")
    if quantity not in _QUANTITIES:
        raise DataError(f"impact_frf: quantity {quantity!r}; valid: {', '.join(_QUANTITIES)}")
    n = f.shape[1]
    if use_force_window:
        f = f * np.array([force_window(row, dt, force_window_width) for row in f])
    decay = 0.0
    if tau is not None:
        exp = exponential_window(n, dt, tau)
        f = f * exp
        y = y * exp
        decay = 1.0 / tau
    spectrum_f = np.fft.rfft(f, axis=1)
    spectrum_y = np.fft.rfft(y, axis=1)
    s_ff = np.sum(np.abs(spectrum_f) ** 2, axis=0)
    s_yy = np.sum(np.abs(spectrum_y) ** 2, axis=0)
    s_fy = np.sum(np.conj(spectrum_f) * spectrum_y, axis=0)
    # Bins where the hit put (numerically) no force in have no FRF: they are left out.
    live = s_ff > _NULL_POWER * np.max(s_ff)
    if not np.any(live):
        raise DataError("impact_frf: the force records are zero; no impact found")
    if not np.all(live):
        _log.info("impact_frf: %d frequencies without force left out", np.count_nonzero(~live))
    h1 = s_fy[live] / s_ff[live]
    with np.errstate(invalid="ignore", divide="ignore"):
        coherence = np.where(s_yy > 0.0, np.abs(s_fy) ** 2 / (s_ff * s_yy), 0.0)[live]
    omega = 2.0 * np.pi * np.fft.rfftfreq(n, dt)[live]
    hits = f.shape[0]
    return FRF(omega, h1, quantity, np.clip(coherence, 0.0, 1.0) if hits > 1 else None, hits, decay)
