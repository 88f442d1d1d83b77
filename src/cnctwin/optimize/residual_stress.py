"""Feed and spindle speed that keep the elastic MIRS within a limit (Ward 2021, Sec. 3.3, Fig. 3).

Ward's MIRS module (Fig. 3) simulates the cutting force and the elastic MIRS at the actual feed
and speed and, while the MIRS is above a reference, changes feed and speed and simulates again
until it is below. The paper does not give the update rule (its case took four iterations from
30000 rpm, 14400 mm/min to 18750 rpm, 5760 mm/min). This module replaces the iteration by a
bounded search that prefers productivity:

- on a grid of ``speeds`` spindle speeds over the allowed range (both ends included), the
  largest feed within the allowed range whose MIRS is at most the limit, by bisection (the
  MIRS must not fall as the feed rises at a fixed speed: true of the elastic model, whose
  load grows with the chip thickness);
- of these, the largest feed (the material removal rate at a fixed engagement); among feeds
  equal within the tolerance, the lower MIRS, then the higher speed.

The search takes the MIRS as a function of feed and speed, so a model that depends on the
cutting speed (a thermal load) plugs in unchanged. :class:`MillingMirs` is that function for
the project's milling force model and :class:`~cnctwin.mechanics.residual_stress.ElasticMirsModel`.

Units: mm/min, rpm, Pa (names say so).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from cnctwin.errors import ConfigError
from cnctwin.mechanics import (
    CuttingCoefficients,
    ElasticMirsModel,
    ResidualStressProfile,
    milling_surface_load,
)

__all__ = ["MillingMirs", "MirsSearch", "search_feed_speed"]

_MM = 1e-3  # m per mm


@dataclass(frozen=True)
class MillingMirs:
    """Elastic MIRS of a milling cut as a function of feed and spindle speed.

    Attributes
    ----------
    coefficients
        Cutting (Pa) and edge (N/m) coefficients of the tool-material pair.
    teeth
        Number of teeth.
    entry_rad, exit_rad
        Immersion angles of the engagement, rad.
    model
        The elastic MIRS model (material, contact length, depths).
    """

    coefficients: CuttingCoefficients
    teeth: int
    entry_rad: float
    exit_rad: float
    model: ElasticMirsModel

    def profile(self, feed_mm_min: float, spindle_rpm: float) -> ResidualStressProfile:
        """The MIRS profile at a feed (mm/min) and spindle speed (rpm)."""
        if not (math.isfinite(spindle_rpm) and spindle_rpm > 0.0):
            raise ConfigError(f"spindle speed = {spindle_rpm!r} rpm; give a value > 0")
        if not (math.isfinite(feed_mm_min) and feed_mm_min > 0.0):
            raise ConfigError(f"feed = {feed_mm_min!r} mm/min; give a value > 0")
        fz_m = feed_mm_min / (self.teeth * spindle_rpm) * _MM
        load = milling_surface_load(
            self.coefficients,
            fz_m,
            self.entry_rad,
            self.exit_rad,
            self.model.contact_length_m,
        )
        return self.model.profile(load.normal_n_m, load.tangential_n_m)

    def __call__(self, feed_mm_min: float, spindle_rpm: float) -> float:
        """The largest magnitude of the longitudinal MIRS sigma_xx, Pa."""
        return self.profile(feed_mm_min, spindle_rpm).max_abs_xx_pa


@dataclass(frozen=True)
class MirsSearch:
    """The outcome of :func:`search_feed_speed`.

    Attributes
    ----------
    feasible
        Whether some allowed feed and speed meet the limit.
    feed_mm_min, spindle_rpm
        The chosen feed (mm/min) and speed (rpm); where not feasible, the lowest feed at the
        speed of the lowest MIRS.
    mirs_pa
        Its MIRS, Pa.
    limit_pa
        The limit, Pa.
    evaluations
        MIRS evaluations spent.
    """

    feasible: bool
    feed_mm_min: float
    spindle_rpm: float
    mirs_pa: float
    limit_pa: float
    evaluations: int


def search_feed_speed(
    mirs_pa: Callable[[float, float], float],
    limit_pa: float,
    feed_range_mm_min: tuple[float, float],
    spindle_range_rpm: tuple[float, float],
    speeds: int = 9,
    feed_tolerance_mm_min: float = 1.0,
) -> MirsSearch:
    """The largest feed, and its spindle speed, whose MIRS is at most ``limit_pa``.

    Parameters
    ----------
    mirs_pa
        MIRS (Pa) of a feed (mm/min) and spindle speed (rpm); not falling as the feed rises.
    limit_pa
        The largest MIRS allowed, Pa (> 0).
    feed_range_mm_min
        Lowest and highest feed allowed, mm/min (0 < low <= high).
    spindle_range_rpm
        Lowest and highest spindle speed allowed, rpm (0 < low <= high).
    speeds
        Spindle speeds tried, spread evenly over the range (1: the highest only).
    feed_tolerance_mm_min
        Bisection stops when the feed is known to within this, mm/min (> 0).

    Returns
    -------
    MirsSearch
        The choice and whether it meets the limit.
    """
    _check_range("feed_range_mm_min", feed_range_mm_min, "mm/min")
    _check_range("spindle_range_rpm", spindle_range_rpm, "rpm")
    if not (math.isfinite(limit_pa) and limit_pa > 0.0):
        raise ConfigError(f"MIRS limit = {limit_pa!r} Pa; give a value > 0")
    if speeds < 1:
        raise ConfigError(f"speeds = {speeds!r}; give at least 1")
    if not (math.isfinite(feed_tolerance_mm_min) and feed_tolerance_mm_min > 0.0):
        raise ConfigError(f"feed tolerance = {feed_tolerance_mm_min!r} mm/min; give a value > 0")
    f_lo, f_hi = feed_range_mm_min
    n_lo, n_hi = spindle_range_rpm
    grid = (
        [n_hi] if speeds == 1 else [n_hi - (n_hi - n_lo) * i / (speeds - 1) for i in range(speeds)]
    )
    evaluations = 0
    best: tuple[float, float, float] | None = None  # feed, mirs, speed
    fallback: tuple[float, float] | None = None  # mirs at the lowest feed, speed
    for n in grid:
        low_mirs = mirs_pa(f_lo, n)
        evaluations += 1
        if fallback is None or low_mirs < fallback[0]:
            fallback = (low_mirs, n)
        if low_mirs > limit_pa:
            continue
        high_mirs = mirs_pa(f_hi, n)
        evaluations += 1
        if high_mirs <= limit_pa:
            feed, value = f_hi, high_mirs
        else:
            ok, ok_value, bad = f_lo, low_mirs, f_hi
            while bad - ok > feed_tolerance_mm_min:
                mid = 0.5 * (ok + bad)
                mid_value = mirs_pa(mid, n)
                evaluations += 1
                if mid_value <= limit_pa:
                    ok, ok_value = mid, mid_value
                else:
                    bad = mid
            feed, value = ok, ok_value
        if (
            best is None
            or feed > best[0] + feed_tolerance_mm_min
            or (abs(feed - best[0]) <= feed_tolerance_mm_min and value < best[1])
        ):
            best = (feed, value, n)
    if best is None:
        assert fallback is not None
        return MirsSearch(False, f_lo, fallback[1], fallback[0], limit_pa, evaluations)
    return MirsSearch(True, best[0], best[2], best[1], limit_pa, evaluations)


def _check_range(name: str, bounds: tuple[float, float], unit: str) -> None:
    low, high = bounds
    if not (math.isfinite(low) and math.isfinite(high) and 0.0 < low <= high):
        raise ConfigError(f"{name} = {bounds!r}; give 0 < low <= high {unit}")
