"""Immersion intervals: the cutter-workpiece contact as the force model integrates it, the
angular intervals of contact of each axial slice.

Frame and angles (Altintas 2012, ch. 2): x is the feed direction, z the tool axis pointing
from the tip to the spindle, y = z x x (to the left of the feed, seen from the spindle). The
spindle turns clockwise seen from the spindle (M3). A tooth's immersion angle phi is measured
clockwise from +y, so a tooth at phi sits at ``r (sin phi, cos phi)`` and moves along
``(cos phi, -sin phi)``; it removes material only for 0 < phi < pi, where the chip thickness
``h = f_z sin(phi) sin(kappa)`` is positive. Up-milling enters at phi = 0 (material on the +y
side), down-milling exits at phi = pi (material on the -y side), a slot spans 0..pi.

An :class:`ImmersionIntervals` holds, for each axial slice between heights ``z_bounds_m``, any
number of angular intervals ``[entry, exit]`` in which the slice is in contact with the
workpiece: from analytic widths and depths (:meth:`ImmersionIntervals.from_depths`), from given
entry and exit angles (:meth:`ImmersionIntervals.from_angles`), or from a material-removal
simulation (:meth:`ImmersionIntervals.from_slices`, which the dexel engagement of one step,
:class:`cnctwin.geometry.Engagement`, feeds through
:func:`cnctwin.simulation.signals.immersion_intervals`). Parts of an interval outside 0..pi cut
nothing. SI units: heights in m, angles in rad.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cnctwin.errors import InputError
from cnctwin.geometry import Cutter

__all__ = ["ImmersionIntervals", "immersion_angles"]

_TWO_PI = 2.0 * math.pi


def immersion_angles(diameter_m: float, width_m: float, down_milling: bool) -> tuple[float, float]:
    """Entry and exit angles (rad) of a cylindrical cutter at radial depth ``width_m``.

    Altintas 2012, ch. 2: up-milling ``(0, arccos(1 - 2 ae / D))``, down-milling
    ``(pi - arccos(1 - 2 ae / D), pi)``; a slot (``ae = D``) spans ``(0, pi)``.

    Parameters
    ----------
    diameter_m
        Cutter diameter D in m, > 0.
    width_m
        Radial depth of cut (width of cut) ae in m, 0 < ae <= D.
    down_milling
        True for down- (climb) milling, False for up- (conventional) milling.
    """
    _check_width(diameter_m, width_m)
    sweep = math.acos(max(-1.0, 1.0 - 2.0 * width_m / diameter_m))
    return (math.pi - sweep, math.pi) if down_milling else (0.0, sweep)


@dataclass(frozen=True)
class ImmersionIntervals:
    """Contact (immersion) intervals per axial slice, for the force model.

    Attributes
    ----------
    z_bounds_m
        Increasing heights above the tool tip in m bounding the n slices (n + 1 values).
    offsets
        Intervals of slice k are ``entry_rad[offsets[k]:offsets[k+1]]`` (n + 1 int64).
    entry_rad, exit_rad
        Interval bounds in rad, ``0 <= entry < exit <= 2 pi``.
    """

    z_bounds_m: np.ndarray
    offsets: np.ndarray
    entry_rad: np.ndarray
    exit_rad: np.ndarray

    @property
    def n_slices(self) -> int:
        """Number of axial slices."""
        return int(self.z_bounds_m.size - 1)

    @property
    def depth_m(self) -> float:
        """Axial extent from the lowest to the highest slice bound, in m."""
        return float(self.z_bounds_m[-1] - self.z_bounds_m[0])

    @classmethod
    def from_intervals(
        cls,
        z_bounds_m: Sequence[float] | np.ndarray,
        intervals: Sequence[Sequence[tuple[float, float]]],
    ) -> ImmersionIntervals:
        """Immersion intervals given per slice.

        Parameters
        ----------
        z_bounds_m
            n + 1 increasing heights above the tool tip in m, >= 0.
        intervals
            n sequences of ``(entry_rad, exit_rad)`` with ``entry < exit <= entry + 2 pi``,
            angles as in the module notes; an interval crossing 2 pi is split in two, and
            overlapping intervals of a slice are merged.
        """
        z = np.asarray(z_bounds_m, dtype=np.float64)
        if z.ndim != 1 or z.size < 2 or not np.all(np.isfinite(z)):
            raise InputError("z_bounds_m must be at least two finite heights in m")
        if z[0] < 0.0 or np.any(np.diff(z) <= 0.0):
            raise InputError(f"z_bounds_m from {z[0]!r}; give increasing heights >= 0 m")
        if len(intervals) != z.size - 1:
            raise InputError(
                f"{len(intervals)} interval lists for {z.size - 1} slices; give one per slice"
            )
        entry: list[float] = []
        exit_: list[float] = []
        offsets = [0]
        for pairs in intervals:
            pieces: list[tuple[float, float]] = []
            for a, b in pairs:
                a, b = float(a), float(b)
                if not (math.isfinite(a) and math.isfinite(b) and a < b <= a + _TWO_PI + 1e-12):
                    raise InputError(
                        f"contact interval ({a!r}, {b!r}) rad; give entry < exit <= entry + 2 pi"
                    )
                start = a % _TWO_PI
                end = start + min(b - a, _TWO_PI)
                if end <= _TWO_PI:
                    pieces.append((start, end))
                else:
                    pieces += [(start, _TWO_PI), (0.0, end - _TWO_PI)]
            # Sorted and merged: the force kernel counts each angle of a slice once.
            for start, end in sorted(pieces):
                if entry[offsets[-1] :] and start <= exit_[-1]:
                    exit_[-1] = max(exit_[-1], end)
                else:
                    entry.append(start)
                    exit_.append(end)
            offsets.append(len(entry))
        return cls(
            z_bounds_m=z,
            offsets=np.asarray(offsets, dtype=np.int64),
            entry_rad=np.asarray(entry, dtype=np.float64),
            exit_rad=np.asarray(exit_, dtype=np.float64),
        )

    @classmethod
    def from_slices(
        cls,
        heights_m: np.ndarray,
        thickness_m: np.ndarray,
        interval_slice: np.ndarray,
        entry_rad: np.ndarray,
        exit_rad: np.ndarray,
    ) -> ImmersionIntervals:
        """Immersion intervals from a table of slices and intervals, such as a dexel simulation
        gives.

        Slice i stands for heights ``heights_m[i] -+ thickness_m[i] / 2`` above the tip
        (clipped at the tip); the slices must not overlap, and gaps between them become slices
        without contact. :class:`cnctwin.geometry.engagement.Engagement` gives these arrays
        (``slice_height_mm``, ``slice_dz_mm``, ``interval_slice``, ``interval_start_rad``,
        ``interval_end_rad``) in the same angle frame; convert its mm to m.

        Parameters
        ----------
        heights_m, thickness_m
            (m,) centre heights above the tool tip and thicknesses of the slices, in m.
        interval_slice
            (q,) index of the slice of each interval.
        entry_rad, exit_rad
            (q,) interval bounds in rad, as for :meth:`from_intervals`.
        """
        heights = np.asarray(heights_m, dtype=np.float64)
        thickness = np.asarray(thickness_m, dtype=np.float64)
        owner = np.asarray(interval_slice, dtype=np.int64)
        starts = np.asarray(entry_rad, dtype=np.float64)
        ends = np.asarray(exit_rad, dtype=np.float64)
        if heights.ndim != 1 or thickness.shape != heights.shape or heights.size == 0:
            raise InputError("heights_m and thickness_m must be two 1-D arrays of equal size > 0")
        if not (owner.shape == starts.shape == ends.shape and owner.ndim == 1):
            raise InputError("interval_slice, entry_rad and exit_rad must be 1-D of equal size")
        if np.any((owner < 0) | (owner >= heights.size)):
            raise InputError(f"interval_slice outside 0..{heights.size - 1}")
        if not np.all(np.isfinite(heights) & np.isfinite(thickness) & (thickness > 0.0)):
            raise InputError("slice heights must be finite and thicknesses finite and > 0 m")
        order = np.argsort(heights)
        lows = np.maximum(heights[order] - thickness[order] / 2.0, 0.0)
        highs = heights[order] + thickness[order] / 2.0
        tolerance = 1e-9 * float(highs[-1])
        if np.any(lows[1:] < highs[:-1] - tolerance):
            raise InputError("slices overlap; give disjoint slices (height -+ thickness / 2)")
        bounds = [float(lows[0])]
        intervals: list[list[tuple[float, float]]] = []
        for rank, index in enumerate(order):
            if lows[rank] > bounds[-1] + tolerance:
                bounds.append(float(lows[rank]))  # a gap: a slice without contact
                intervals.append([])
            bounds.append(float(highs[rank]))
            mine = owner == index
            intervals.append(list(zip(starts[mine].tolist(), ends[mine].tolist(), strict=True)))
        return cls.from_intervals(bounds, intervals)

    @classmethod
    def from_angles(
        cls, entry_rad: float, exit_rad: float, depth_m: float, slices: int = 50
    ) -> ImmersionIntervals:
        """The same interval ``[entry_rad, exit_rad]`` on ``slices`` equal slices of ``depth_m``.

        Parameters
        ----------
        entry_rad, exit_rad
            Entry and exit angles in rad, ``entry < exit``.
        depth_m
            Axial depth of cut ap in m, > 0, measured from the tool tip.
        slices
            Number of axial slices, >= 1.
        """
        z = _depth_bounds(depth_m, slices)
        return cls.from_intervals(z, [[(entry_rad, exit_rad)]] * slices)

    @classmethod
    def from_depths(
        cls,
        cutter: Cutter,
        width_m: float,
        depth_m: float,
        down_milling: bool = False,
        slices: int = 50,
    ) -> ImmersionIntervals:
        """Immersion intervals of a straight cut, radial depth ``width_m``, axial ``depth_m``.

        The material is the band of width ``ae`` next to the cutter's side at full radius
        (``R - ae <= y <= R`` when up-milling, ``-R <= y <= -R + ae`` when down-milling),
        from the tip up to ``ap``. A slice of local radius ``r`` (smaller on a ball or corner)
        touches it where ``r cos(phi)`` lies in the band, 0 <= phi <= pi.

        Parameters
        ----------
        cutter
            The cutter (its SI views are read).
        width_m
            Radial depth ae in m, 0 < ae <= D.
        depth_m
            Axial depth ap in m, > 0.
        down_milling
            True for down- (climb) milling, False for up- (conventional) milling.
        slices
            Number of equal axial slices, >= 1.
        """
        _check_width(cutter.diameter_m, width_m)
        z = _depth_bounds(depth_m, slices)
        radius = cutter.radius_m
        local = cutter.slices(z).radius_m
        if down_milling:
            lo, hi = -radius, -radius + width_m
        else:
            lo, hi = radius - width_m, radius
        intervals: list[list[tuple[float, float]]] = []
        for r in local:
            a = math.acos(max(-1.0, min(1.0, hi / r)))
            b = math.acos(max(-1.0, min(1.0, lo / r)))
            intervals.append([(a, b)] if b > a else [])
        return cls.from_intervals(z, intervals)


def _check_width(diameter_m: float, width_m: float) -> None:
    if not (math.isfinite(width_m) and 0.0 < width_m <= diameter_m * (1.0 + 1e-12)):
        raise InputError(f"width of cut {width_m!r} m; give 0 < ae <= D ({diameter_m!r} m)")


def _depth_bounds(depth_m: float, slices: int) -> np.ndarray:
    if not (math.isfinite(depth_m) and depth_m > 0.0):
        raise InputError(f"depth of cut {depth_m!r} m; give a finite ap > 0 m")
    if isinstance(slices, bool) or not isinstance(slices, (int, np.integer)) or slices < 1:
        raise InputError(f"slices={slices!r}; give an integer >= 1")
    return np.linspace(0.0, depth_m, int(slices) + 1)
