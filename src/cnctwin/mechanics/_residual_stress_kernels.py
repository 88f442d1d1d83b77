"""Numba kernel of the elastic MIRS model (see :mod:`cnctwin.mechanics.residual_stress`).

Arrays in SI units (Pa, N/m). The loaded state of each depth is the position of the largest von
Mises stress of the combined field; one pass over the grid finds it, without the eleven
temporary arrays of the field a NumPy expression builds (the twin's MIRS stage evaluates the
model every sample, and about twenty times in its override search).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def loaded_states(
    normal: float,
    tangential: float,
    nu: float,
    thermal: np.ndarray,
    n_xx: np.ndarray,
    n_zz: np.ndarray,
    n_xz: np.ndarray,
    q_xx: np.ndarray,
    q_zz: np.ndarray,
    q_xz: np.ndarray,
    worst: np.ndarray,
    mises: np.ndarray,
    sxx: np.ndarray,
    syy: np.ndarray,
    szz: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """Per depth (column), the row of the largest von Mises stress of the combined field.

    The field is ``normal * n_* + tangential * q_*`` (shape ``(positions, depths)``, Pa per
    N/m) with the thermal stress ``thermal`` (Pa, per depth) on sigma_xx and sigma_yy
    (plane strain: ``sigma_yy = nu (sigma_xx + sigma_zz)``); the arithmetic is that of
    ``ElasticMirsModel.profile``'s element-wise expression, term by term. Writes per depth the
    row (first of equal maxima, as ``numpy.argmax``), its von Mises stress and its sigma_xx,
    sigma_yy, sigma_zz (Pa) into ``worst``, ``mises``, ``sxx``, ``syy``, ``szz``.
    """
    rows, cols = n_xx.shape
    for i in range(rows):
        for j in range(cols):
            mxx = normal * n_xx[i, j] + tangential * q_xx[i, j]
            zz = normal * n_zz[i, j] + tangential * q_zz[i, j]
            xz = normal * n_xz[i, j] + tangential * q_xz[i, j]
            xx = mxx + thermal[j]
            yy = nu * (mxx + zz) + thermal[j]
            a = xx - yy
            b = yy - zz
            c = zz - xx
            value = math.sqrt(0.5 * (a * a + b * b + c * c) + 3.0 * (xz * xz))
            if i == 0 or value > mises[j]:
                worst[j] = i
                mises[j] = value
                sxx[j] = xx
                syy[j] = yy
                szz[j] = zz
