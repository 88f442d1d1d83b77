"""How runtime scales with dexel density and cycle time: Heide 2025's ``T* = rho^2 / t_cycle``.

Heide 2025 (Eq. 1, after Boess et al.) expects the cost of one step of a Cartesian multi-dexel
model to grow with the square of the density and the number of steps over a process with
``1 / t_cycle``, so the runtime of a process should follow ``T* = rho^2 / t_cycle``. The check
fits ``runtime = c (T*)^k`` by least squares on logarithms (``k = 1`` when T* holds) and, freer,
``runtime = c rho^a t_cycle^b`` (T*: ``a = 2``, ``b = -1``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cnctwin.errors import ConfigError

__all__ = ["TStarFit", "fit_t_star", "t_star"]


def t_star(density_per_mm: ArrayLike, cycle_s: ArrayLike) -> NDArray[np.float64]:
    """Heide 2025's computational effort ``T* = rho^2 / t_cycle`` (Eq. 1), 1/(mm^2 s).

    Parameters
    ----------
    density_per_mm
        Dexel density, 1/mm.
    cycle_s
        Cycle time, s.
    """
    rho = np.asarray(density_per_mm, dtype=np.float64)
    return rho * rho / np.asarray(cycle_s, dtype=np.float64)


@dataclass(frozen=True, slots=True)
class TStarFit:
    """Power-law fits of runtime against T* and against density and cycle time.

    Attributes
    ----------
    exponent
        ``k`` of ``runtime = c (T*)^k`` (1 when runtime follows T*).
    prefactor_s
        ``c``, s per unit of ``(T*)^k`` (T* in 1/(mm^2 s)).
    r2
        Coefficient of determination of that fit, on the logarithms.
    density_exponent, cycle_exponent
        ``a`` and ``b`` of ``runtime = c rho^a t_cycle^b`` (T*: 2 and -1).
    r2_free
        Coefficient of determination of the second fit, on the logarithms.
    points
        Number of settings fitted.
    """

    exponent: float
    prefactor_s: float
    r2: float
    density_exponent: float
    cycle_exponent: float
    r2_free: float
    points: int


def _r2(y: NDArray[np.float64], fitted: NDArray[np.float64]) -> float:
    total = float(np.sum((y - y.mean()) ** 2))
    return 1.0 - float(np.sum((y - fitted) ** 2)) / total if total > 0.0 else 1.0


def fit_t_star(density_per_mm: ArrayLike, cycle_s: ArrayLike, runtime_s: ArrayLike) -> TStarFit:
    """Fit runtimes against ``T* = rho^2 / t_cycle`` (Heide 2025, Eq. 1).

    Parameters
    ----------
    density_per_mm
        Dexel density of each setting, 1/mm.
    cycle_s
        Cycle time of each setting, s.
    runtime_s
        Runtime of each setting over the same process, s (> 0).

    Returns
    -------
    TStarFit
        Exponents, prefactor and R^2 of the two log-log fits.

    Raises
    ------
    ConfigError
        On arrays of different lengths, non-positive or non-finite values, or settings that do
        not vary both density and cycle time (the free fit needs at least two of each and three
        settings).
    """
    rho, cycle, runtime = (
        np.asarray(v, dtype=np.float64).ravel() for v in (density_per_mm, cycle_s, runtime_s)
    )
    if not rho.size == cycle.size == runtime.size:
        raise ConfigError(
            f"{rho.size} densities, {cycle.size} cycle times and {runtime.size} runtimes; "
            "give one of each per setting"
        )
    values = np.concatenate([rho, cycle, runtime])
    if not np.all(np.isfinite(values)) or np.any(values <= 0.0):
        raise ConfigError("densities, cycle times and runtimes must be finite and > 0")
    if rho.size < 3 or np.unique(rho).size < 2 or np.unique(cycle).size < 2:
        raise ConfigError(
            f"{rho.size} settings with {np.unique(rho).size} densities and "
            f"{np.unique(cycle).size} cycle times; give at least 3 settings, 2 of each"
        )
    y = np.log(runtime)
    x = np.log(t_star(rho, cycle))
    design = np.column_stack([x, np.ones_like(x)])
    (k, c), *_ = np.linalg.lstsq(design, y, rcond=None)
    free = np.column_stack([np.log(rho), np.log(cycle), np.ones_like(x)])
    (a, b, c_free), *_ = np.linalg.lstsq(free, y, rcond=None)
    return TStarFit(
        exponent=float(k),
        prefactor_s=float(np.exp(c)),
        r2=_r2(y, design @ np.array([k, c])),
        density_exponent=float(a),
        cycle_exponent=float(b),
        r2_free=_r2(y, free @ np.array([a, b, c_free])),
        points=int(rho.size),
    )
