"""Cutting coefficients from measured mean forces: Altintas' linear-regression method.

With the immersion and the axial depth held, the per-revolution mean forces of a flat end mill
are linear in the feed per tooth c (Altintas, *Manufacturing Automation*, 2nd ed., 2012,
ch. 2; :func:`~cnctwin.mechanics.milling.flat_end_mill_mean_forces`)::

    mean F_q(c) = a1_q c + a0_q,   q = x, y, z,

where the slopes depend only on the shear coefficients (Ktc, Krc, Kac) and the intercepts only
on the edge coefficients (Kte, Kre, Kae). Mean forces measured at several feeds give a1 and a0
per axis by least squares; the coefficients follow from the closed form. For a slot
(0..pi, N teeth, depth a) this is the familiar

    Ktc = 4 a1_y / (N a),  Krc = -4 a1_x / (N a),  Kac = pi a1_z / (N a),
    Kte = pi a0_y / (N a), Kre = -pi a0_x / (N a), Kae = 2 a0_z / (N a),

(with Fz = -Fa, the sign convention of :mod:`cnctwin.mechanics.milling`). The helix does not
change mean forces, so a helical cutter's records serve as well.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cnctwin.errors import DataError
from cnctwin.mechanics.coefficients import CuttingCoefficients
from cnctwin.mechanics.milling import flat_end_mill_mean_forces

__all__ = ["CoefficientFit", "identify_coefficients"]


@dataclass(frozen=True)
class CoefficientFit:
    """Identified coefficients and the goodness of the per-axis linear fits.

    Attributes
    ----------
    coefficients
        The six identified coefficients (Pa, N/m).
    feeds_per_tooth_m
        Feeds per tooth of the measurements, in m (n values).
    measured_n
        Measured mean forces in N, shape (n, 3): Fx, Fy, Fz in the tool frame.
    predicted_n
        Mean forces of the identified coefficients at the same feeds, in N, shape (n, 3).
    slopes_n_m
        Fitted slopes a1 (x, y, z) in N per m of feed per tooth.
    intercepts_n
        Fitted intercepts a0 (x, y, z) in N.
    r_squared
        Coefficient of determination of each axis' fit (x, y, z); NaN where the measured
        forces do not vary.
    """

    coefficients: CuttingCoefficients
    feeds_per_tooth_m: np.ndarray
    measured_n: np.ndarray
    predicted_n: np.ndarray
    slopes_n_m: np.ndarray
    intercepts_n: np.ndarray
    r_squared: np.ndarray

    @property
    def residuals_n(self) -> np.ndarray:
        """Measured minus predicted mean forces in N, shape (n, 3)."""
        residuals: np.ndarray = self.measured_n - self.predicted_n
        return residuals

    @property
    def relative_residuals(self) -> np.ndarray:
        """Residuals divided by the measured magnitudes (a fraction), shape (n, 3)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            relative: np.ndarray = self.residuals_n / np.abs(self.measured_n)
        return relative


def identify_coefficients(
    feeds_per_tooth_m: np.ndarray,
    mean_forces_n: np.ndarray,
    *,
    teeth: int,
    depth_m: float,
    entry_rad: float = 0.0,
    exit_rad: float = math.pi,
) -> CoefficientFit:
    """Identify the six coefficients from mean forces measured at several feeds per tooth.

    Parameters
    ----------
    feeds_per_tooth_m
        Feeds per tooth in m, at least two distinct values > 0.
    mean_forces_n
        Per-revolution mean forces on the tool in N, shape (n, 3): Fx (feed), Fy, Fz (axis,
        toward the spindle), in the frame of :mod:`cnctwin.mechanics.engagement`.
    teeth
        Number of teeth N.
    depth_m
        Axial depth of cut in m.
    entry_rad, exit_rad
        Entry and exit angles of the cuts in rad (default: a slot).

    Returns
    -------
    CoefficientFit
        The coefficients with the fits' slopes, intercepts, R^2 and residuals.

    Raises
    ------
    DataError
        If the data cannot determine the coefficients (too few or repeated feeds, bad shapes,
        or an immersion for which the tangential and radial terms cannot be separated).
    """
    c = np.asarray(feeds_per_tooth_m, dtype=np.float64)
    f = np.asarray(mean_forces_n, dtype=np.float64)
    if c.ndim != 1 or f.shape != (c.size, 3):
        raise DataError(
            f"{c.size} feeds and forces of shape {f.shape}; give n feeds and an (n, 3) array"
        )
    if not (np.all(np.isfinite(c)) and np.all(c > 0.0) and np.all(np.isfinite(f))):
        raise DataError("feeds must be finite and > 0 m, forces finite")
    if np.unique(c).size < 2:
        raise DataError(f"feeds {c.tolist()!r} m; give at least two distinct feeds per tooth")
    design = np.column_stack([c, np.ones_like(c)])
    (slopes, intercepts), *_ = np.linalg.lstsq(design, f, rcond=None)
    predicted = design @ np.vstack([slopes, intercepts])
    spread = np.sum((f - f.mean(axis=0)) ** 2, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        r_squared = np.where(
            spread > 0.0, 1.0 - np.sum((f - predicted) ** 2, axis=0) / spread, np.nan
        )
    # Mean forces per unit coefficient: columns Ktc, Krc, Kac (per unit feed) and Kte, Kre, Kae.
    basis = np.empty((3, 6))
    for i in range(6):
        unit = np.zeros(6)
        unit[i] = 1.0
        m = flat_end_mill_mean_forces(
            CuttingCoefficients(*unit),
            teeth,
            1.0,
            entry_rad,
            exit_rad,
            depth_m,
            1.0,
            0.0,
        )
        basis[:, i] = (m.fx_n, m.fy_n, m.fz_n)
    try:
        shear = np.linalg.solve(basis[:, :3], slopes)
        edge = np.linalg.solve(basis[:, 3:], intercepts)
    except np.linalg.LinAlgError:
        raise DataError(
            f"immersion {entry_rad!r}..{exit_rad!r} rad cannot separate the coefficients"
        ) from None
    return CoefficientFit(
        coefficients=CuttingCoefficients(*shear, *edge),
        feeds_per_tooth_m=c,
        measured_n=f,
        predicted_n=predicted,
        slopes_n_m=slopes,
        intercepts_n=intercepts,
        r_squared=r_squared,
    )
