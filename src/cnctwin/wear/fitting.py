"""Fitting the wear models of the torque EKF to measurements: the logistic wear law to
measured wear progressions, the wear-torque model to measured (wear, torque) pairs.

The discrete law of Christiand 2024 (Eq. 32) is, for small steps, the logistic equation
``dVB/dMR = q VB (1 - VB/VBmax)``, whose solution from ``VB0`` is
``VB(MR) = VBmax / (1 + (VBmax/VB0 - 1) exp(-q MR))``. :func:`fit_logistic_wear` finds
``q``, ``VBmax`` and ``VB0`` by least squares over one or several tools' measurements, so a
law fitted on some tools can predict another. The driving input is the material removed in
mm^3 (or any monotone measure of use, e.g. cutting time, with ``q`` in its inverse unit).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares, minimize_scalar

from cnctwin.errors import DataError
from cnctwin.wear.ekf import LogisticWear, WearTorque

__all__ = ["LogisticFit", "fit_logistic_wear", "fit_wear_torque", "logistic_wear_curve"]


def logistic_wear_curve(
    mr_mm3: ArrayLike, q_per_mm3: float, vb_max_mm: float, vb0_mm: float
) -> NDArray[np.float64]:
    """Wear along the continuous logistic law, mm.

    Parameters
    ----------
    mr_mm3
        Material removed since the tool was new, mm^3.
    q_per_mm3
        Growth rate, 1/mm^3.
    vb_max_mm
        Saturation wear, mm.
    vb0_mm
        Wear of the new tool (at ``mr = 0``), mm, in (0, vb_max_mm).

    Returns
    -------
    numpy.ndarray
        Wear, mm, shaped like ``mr_mm3``.
    """
    mr = np.asarray(mr_mm3, dtype=float)
    return vb_max_mm / (1.0 + (vb_max_mm / vb0_mm - 1.0) * np.exp(-q_per_mm3 * mr))


@dataclass(frozen=True, slots=True)
class LogisticFit:
    """A fitted logistic wear law.

    Attributes
    ----------
    law
        ``q`` and ``VBmax`` as a :class:`~cnctwin.wear.ekf.LogisticWear`.
    vb0_mm
        Fitted wear of a new tool, mm.
    rmse_mm
        Root-mean-square residual over the fitted points, mm.
    points
        Number of measurements fitted.
    """

    law: LogisticWear
    vb0_mm: float
    rmse_mm: float
    points: int

    def predict(self, mr_mm3: ArrayLike) -> NDArray[np.float64]:
        """Predicted wear at the given material removed, mm."""
        return logistic_wear_curve(mr_mm3, self.law.q_per_mm3, self.law.vb_max_mm, self.vb0_mm)


def fit_logistic_wear(
    series: Sequence[tuple[ArrayLike, ArrayLike]],
) -> LogisticFit:
    """Least-squares fit of one logistic law to one or more wear progressions.

    Parameters
    ----------
    series
        ``(mr_mm3, vb_mm)`` pairs of arrays, one pair per tool; missing measurements
        (``nan``) are skipped.

    Returns
    -------
    LogisticFit

    Raises
    ------
    cnctwin.errors.DataError
        With fewer than three usable measurements, or negative wear or material.
    """
    mr_parts, vb_parts = [], []
    for index, (mr, vb) in enumerate(series):
        mr_a = np.asarray(mr, dtype=float)
        vb_a = np.asarray(vb, dtype=float)
        if mr_a.shape != vb_a.shape:
            raise DataError(
                f"series {index}: {mr_a.size} material values but {vb_a.size} wear values"
            )
        keep = np.isfinite(mr_a) & np.isfinite(vb_a)
        if np.any(mr_a[keep] < 0) or np.any(vb_a[keep] < 0):
            raise DataError(f"series {index}: wear and material removed must be >= 0")
        mr_parts.append(mr_a[keep])
        vb_parts.append(vb_a[keep])
    mr_all = np.concatenate(mr_parts) if mr_parts else np.empty(0)
    vb_all = np.concatenate(vb_parts) if vb_parts else np.empty(0)
    if mr_all.size < 3:
        raise DataError(f"a logistic wear fit needs at least 3 measurements; got {mr_all.size}")
    top = float(vb_all.max())
    span = float(mr_all.max()) or 1.0
    positive = vb_all[vb_all > 0]
    start = float(positive.min()) if positive.size else 1e-3 * max(top, 1e-6)

    def residuals(x: NDArray[np.float64]) -> NDArray[np.float64]:
        q, vmax, v0 = np.exp(x)
        return logistic_wear_curve(mr_all, q, vmax, min(v0, 0.999 * vmax)) - vb_all

    # VBmax is kept within ten times the largest wear seen: a progression that shows no
    # saturation fits at that bound (the law is then practically exponential).
    lower = np.log([1e-12 / span, 1.0001 * top, 1e-6 * top])
    upper = np.log([1e6 / span, 10.0 * top, top])
    best = None
    for vmax_guess in (1.05 * top, 1.5 * top, 3.0 * top):
        v0 = min(max(start, 1e-6 * top), 0.5 * vmax_guess)
        q0 = math.log(max(vmax_guess / v0 - 1.0, 1.5)) * 2.0 / span
        x0 = np.clip(np.log([q0, vmax_guess, v0]), lower + 1e-9, upper - 1e-9)
        result = least_squares(residuals, x0, bounds=(lower, upper), max_nfev=2000)
        if best is None or result.cost < best.cost:
            best = result
    assert best is not None
    q, vmax, v0 = (float(v) for v in np.exp(best.x))
    v0 = min(v0, 0.999 * vmax)
    rmse = math.sqrt(2.0 * best.cost / mr_all.size)
    return LogisticFit(LogisticWear(q_per_mm3=q, vb_max_mm=vmax), v0, rmse, int(mr_all.size))


def fit_wear_torque(vb_mm: ArrayLike, torque_nm: ArrayLike) -> WearTorque:
    """Least-squares fit of the wear-torque model (Christiand 2024, Eq. 8) to calibration pairs.

    The model ``Tw = p0 ln(p1 VB / (p2 - p3 VB)) + p4`` has three independent parameters:
    with ``p1 = p3 = 1 /mm`` it is ``p0 ln(VB / (L - VB)) + p4``, ``L = p2`` the end of its
    domain, mm. For each ``L`` the best ``p0`` and ``p4`` are a linear least-squares fit;
    ``L`` is searched between 1.001 and 100 times the largest calibration wear.

    Parameters
    ----------
    vb_mm
        Flank wear of the calibration points (a tool measured under a microscope), mm, > 0.
    torque_nm
        The torque wear adds at each point (measured spindle torque minus the torque without
        wear under the same cutting conditions), N m.

    Returns
    -------
    WearTorque
        The fitted model, ``p1_per_mm = p3_per_mm = 1``.

    Raises
    ------
    cnctwin.errors.DataError
        With fewer than three finite points, a wear that is not > 0, arrays of different
        sizes, or torque that does not rise with wear (``p0 <= 0``).
    """
    vb = np.asarray(vb_mm, dtype=float).ravel()
    torque = np.asarray(torque_nm, dtype=float).ravel()
    if vb.shape != torque.shape:
        raise DataError(f"wear-torque fit: {vb.size} wear values but {torque.size} torques")
    keep = np.isfinite(vb) & np.isfinite(torque)
    vb, torque = vb[keep], torque[keep]
    if vb.size < 3:
        raise DataError(f"a wear-torque fit needs at least 3 finite points; got {vb.size}")
    if np.any(vb <= 0.0):
        raise DataError(f"wear-torque fit: wear {float(vb.min())!r} mm; every VB must be > 0")
    top = float(vb.max())

    def solve(limit_mm: float) -> tuple[float, float, float]:
        x = np.log(vb / (limit_mm - vb))
        design = np.column_stack((x, np.ones_like(x)))
        (p0, p4), *_ = np.linalg.lstsq(design, torque, rcond=None)
        return float(np.sum((design @ (p0, p4) - torque) ** 2)), float(p0), float(p4)

    found = minimize_scalar(
        lambda log_l: solve(math.exp(log_l))[0],
        bounds=(math.log(1.001 * top), math.log(100.0 * top)),
        method="bounded",
    )
    limit = math.exp(float(found.x))
    _, p0, p4 = solve(limit)
    if not p0 > 0.0:
        raise DataError(
            f"wear-torque fit: torque does not rise with wear (p0 = {p0:.3g} N m); check the "
            "calibration pairs"
        )
    return WearTorque(p0_nm=p0, p1_per_mm=1.0, p2=limit, p3_per_mm=1.0, p4_nm=p4)
