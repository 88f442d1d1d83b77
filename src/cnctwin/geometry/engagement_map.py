"""Engagement maps: engagement precomputed along a toolpath, looked up from the live tool position.

Ward 2021 (Sec. 3.2, "lookahead and lookup functions") computes the cutter-workpiece engagement
before machining at the program's cutter locations, indexed along the toolpath; while the
machine cuts, the twin compares the measured tool position with the map's locations in a window
that starts where the tool was last found and reaches a lookahead ahead, and reads the
engagement of the nearest one. The window is what tells two visits of the same point apart
(a crossing, a second pass, a spring pass): only the visit ahead of the last match is searched.

Units: mm (names end in ``_mm``), mm^2, rad; the path parameter ``s`` is the path length in mm
from the program's first position, rapids included.

Building
--------
:meth:`EngagementMap.build` runs the program once through a stock (the discrete-position cut of
:func:`cnctwin.geometry.cut`) at locations a fixed path length ``step_mm`` apart: every move,
rapid or feed, is sampled at one speed and dwells are dropped, so that location ``k`` sits at
``s = k step_mm`` and the map does not depend on the programmed feeds. Per location it keeps
the tool tip, source line, tool, whether the move is a rapid, the width and depth of cut, the
removed volume per mm of path ``cut_area_mm2`` (MRR = ``cut_area_mm2`` x path speed), the chip
thickness per unit feed per tooth (``h = f_z x h_mean_per_fz``; with ``f_z = 1`` the engagement
kernel returns exactly this ratio), the hull of the contact within the cutting half ``[0, pi]``
(``entry_rad``, ``exit_rad``; NaN without), the feed direction of the angle frame, and the
contact intervals per axial band: consecutive grid slices of the engagement with identical
intervals merged into bands at most ``band_mm`` high (:class:`MapSlices`).

Lookup
------
``lookup(position, hint_s_mm)`` measures the distance from the position to the polyline through
the map's locations, piece by piece, from the hint's point on the path (never before it) to the
pieces that start within ``lookahead_mm`` ahead. Among them it takes the first run of
consecutive pieces, in path order, whose distance is within ``tie_mm`` of the window's smallest,
and the nearest point in that run: a point the path visits twice inside the window is matched
to the earlier visit, and a run started by the slow tool at the window's start does not hold the
match back. When that point is farther than ``tolerance_mm``, a global search (a k-d tree over
all locations) resynchronises on the locations within the tolerance, preferring those at or
after the hint, with the same rule; when none is within the tolerance the match says the tool is
off the path. Between two locations the width and depth of cut and the cut area are linear in
``s``, as are the chip thickness ratios and angles when both locations are in contact; the
rest (contact, line, tool, intervals) comes from the nearer location.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from enum import IntEnum
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from cnctwin.errors import ConfigError, DataError, InputError, NCError
from cnctwin.geometry._workspace import xyz_mm
from cnctwin.geometry.cutter import Cutter
from cnctwin.geometry.dexel import DexelStock
from cnctwin.geometry.engagement import Engagement, cut
from cnctwin.memory import check_memory
from cnctwin.nc import MotionKind, Segment, TrajectorySampler

__all__ = [
    "EngagementMap",
    "MapCursor",
    "MapMatch",
    "MapSlices",
    "MatchStatus",
    "load_engagement_map",
    "save_engagement_map",
]

logger = logging.getLogger(__name__)

#: Version of the .npz layout written by :func:`save_engagement_map`.
FORMAT_VERSION = 1
#: Default lookahead window, mm of path ahead of the last match.
LOOKAHEAD_MM = 25.0
#: Default distance beyond which the window resynchronises, mm.
TOLERANCE_MM = 0.5
#: Default distance within which two candidates count as equally near, mm.
TIE_MM = 0.05

_TWO_PI = 2.0 * math.pi
#: Memory a location takes while a map is built, bytes, checked against the work limit
#: (measured: about 200 B a location in the finished map, the writer's lists several times
#: that; rounded up).
_LOCATION_BYTES = 1000
_CHORD_SLACK = 1e-6  # relative: a chord longer than the step (plus this) is a jump, not a path

# Columns of the per-location scalar table (float64, one row per location).
_AE, _AP, _AREA, _HMEAN, _HMAX, _ENTRY, _EXIT = range(7)
_CONTACT, _LINE, _TOOL, _RAPID, _FX, _FY, _BOTTOM, _ABOVE = range(7, 15)
_N_COLUMNS = 15
_COLUMN_NAMES = (
    "ae_mm",
    "ap_mm",
    "cut_area_mm2",
    "h_mean_per_fz",
    "h_max_per_fz",
    "entry_rad",
    "exit_rad",
    "contact",
    "line",
    "tool",
    "rapid",
    "feed_dir_x",
    "feed_dir_y",
    "bottom_contact",
    "above_flutes",
)
_ARRAYS = (
    "s_mm",
    "tcp_mm",
    "table",
    "band_ptr",
    "band_lo_mm",
    "band_hi_mm",
    "interval_ptr",
    "interval_start_rad",
    "interval_end_rad",
)


class MatchStatus(IntEnum):
    """How a lookup found the tool on the path."""

    #: Inside the lookahead window, within the tolerance.
    TRACKING = 0
    #: Not in the window (or no hint): found by a global search, within the tolerance.
    RESYNCED = 1
    #: Nowhere within the tolerance: the engagement is zero; the match names the nearest
    #: location for diagnosis.
    OFF_PATH = 2


class MapSlices(NamedTuple):
    """Contact intervals of one map location, per axial band, in the layout of
    :class:`cnctwin.geometry.Engagement` (so that
    :meth:`cnctwin.mechanics.Engagement.from_slices` takes them, converted to m).

    Attributes
    ----------
    slice_height_mm
        (m,) centre of each band above the tool tip, mm.
    slice_dz_mm
        (m,) height of each band, mm (bands are disjoint; gaps are bands without contact).
    interval_slice
        (q,) index of each interval's band.
    interval_start_rad, interval_end_rad
        (q,) contact intervals ``[start, end)`` in rad, ``0 <= start < end <= 2 pi``, in the
        angle frame of :mod:`cnctwin.geometry.engagement` (relative to ``feed_dir``).
    """

    slice_height_mm: np.ndarray
    slice_dz_mm: np.ndarray
    interval_slice: np.ndarray
    interval_start_rad: np.ndarray
    interval_end_rad: np.ndarray


class MapMatch(NamedTuple):
    """Result of a lookup: where the tool is on the path and the engagement there.

    Attributes
    ----------
    status
        :class:`MatchStatus`.
    s_mm
        Matched path parameter, mm along the program.
    distance_mm
        Distance from the looked-up position to the matched point of the path, mm.
    location
        Map location at or before the match (the match lies between ``location`` and
        ``location + 1``).
    fraction
        Position between the two locations, in [0, 1).
    nearest
        The nearer of the two locations: the one whose intervals :meth:`EngagementMap.slices`
        gives.
    line
        Source line of the NC program at ``nearest``.
    tool
        Tool number at ``nearest``.
    rapid
        The move at ``nearest`` is a rapid.
    contact
        The tool is in contact with the material.
    ae_mm, ap_mm
        Width and depth of cut, mm.
    cut_area_mm2
        Volume removed per mm of path, mm^2 (MRR in mm^3/s = this x path speed in mm/s).
    h_mean_per_fz, h_max_per_fz
        Mean and largest uncut chip thickness per unit feed per tooth (mm/mm): the chip
        thickness in mm is this times the live feed per tooth in mm.
    entry_rad, exit_rad
        Hull of the contact within the cutting half ``[0, pi]`` over all bands, rad; NaN without
        contact there.
    feed_dir
        Unit feed direction (x, y) of the angle frame.
    bottom_contact
        The flat bottom face cut (moving down).
    above_flutes
        Material at the top of the fluted length.
    """

    status: MatchStatus
    s_mm: float
    distance_mm: float
    location: int
    fraction: float
    nearest: int
    line: int
    tool: int
    rapid: bool
    contact: bool
    ae_mm: float
    ap_mm: float
    cut_area_mm2: float
    h_mean_per_fz: float
    h_max_per_fz: float
    entry_rad: float
    exit_rad: float
    feed_dir: tuple[float, float]
    bottom_contact: bool
    above_flutes: bool


@dataclass(frozen=True, eq=False)
class EngagementMap:
    """Engagement at the cutter locations of a program, indexed by path length (Ward 2021,
    Sec. 3.2). Build one with :meth:`build`; look it up with :meth:`lookup` or a
    :class:`MapCursor`.

    Attributes
    ----------
    step_mm
        Path length between consecutive locations, mm.
    pitch_mm
        Dexel pitch (x, y, z) of the stock the map was built on, mm.
    s_mm
        (n,) path parameter of each location, mm (``k step_mm``).
    tcp_mm
        (n, 3) tool tip of each location, machine coordinates, mm.
    table
        (n, 15) per-location values, float64, columns in the order of ``COLUMNS``: ae_mm,
        ap_mm, cut_area_mm2 (mm^2), h_mean_per_fz, h_max_per_fz (mm/mm), entry_rad, exit_rad
        (rad, NaN without contact in [0, pi]), contact (0/1), line, tool, rapid (0/1),
        feed_dir_x, feed_dir_y, bottom_contact (0/1), above_flutes (0/1). :meth:`column`
        reads one by name.
    band_ptr
        (n + 1,) int64: the bands of location ``i`` are ``band_ptr[i]:band_ptr[i + 1]``.
    band_lo_mm, band_hi_mm
        Bounds of each band above the tool tip, mm (float32).
    interval_ptr
        (bands + 1,) int64: the intervals of band ``b`` are ``interval_ptr[b]:interval_ptr[b+1]``.
    interval_start_rad, interval_end_rad
        Contact intervals, rad (float32).

    Raises
    ------
    DataError
        When the arrays are inconsistent (a corrupt file).
    """

    step_mm: float
    pitch_mm: tuple[float, float, float]
    s_mm: np.ndarray
    tcp_mm: np.ndarray
    table: np.ndarray
    band_ptr: np.ndarray
    band_lo_mm: np.ndarray
    band_hi_mm: np.ndarray
    interval_ptr: np.ndarray
    interval_start_rad: np.ndarray
    interval_end_rad: np.ndarray

    #: Names of the columns of :attr:`table`.
    COLUMNS = _COLUMN_NAMES

    def __post_init__(self) -> None:
        n = self.s_mm.shape[0] if self.s_mm.ndim == 1 else -1
        bands = self.band_lo_mm.shape[0] if self.band_lo_mm.ndim == 1 else -1
        intervals = self.interval_start_rad.shape[0] if self.interval_start_rad.ndim == 1 else -1
        problems = []
        if n < 1:
            problems.append(f"s_mm of shape {self.s_mm.shape}; need (n,) with n >= 1")
        elif not (np.all(np.isfinite(self.s_mm)) and np.all(np.diff(self.s_mm) > 0.0)):
            problems.append("s_mm is not finite and strictly increasing")
        if self.tcp_mm.shape != (n, 3) or self.table.shape != (n, _N_COLUMNS):
            problems.append(
                f"tcp_mm {self.tcp_mm.shape} and table {self.table.shape} for {n} locations; "
                f"need ({n}, 3) and ({n}, {_N_COLUMNS})"
            )
        if self.band_ptr.shape != (n + 1,) or self.band_hi_mm.shape != (bands,):
            problems.append(f"band arrays do not fit {n} locations and {bands} bands")
        elif (
            self.band_ptr[0] != 0
            or self.band_ptr[-1] != bands
            or np.any(np.diff(self.band_ptr) < 0)
        ):
            problems.append("band_ptr is not a non-decreasing index from 0 to the band count")
        if self.interval_ptr.shape != (bands + 1,) or self.interval_end_rad.shape != (intervals,):
            problems.append(f"interval arrays do not fit {bands} bands and {intervals} intervals")
        elif (
            self.interval_ptr[0] != 0
            or self.interval_ptr[-1] != intervals
            or np.any(np.diff(self.interval_ptr) < 0)
        ):
            problems.append("interval_ptr is not a non-decreasing index from 0 to the count")
        if not (math.isfinite(self.step_mm) and self.step_mm > 0.0):
            problems.append(f"step_mm={self.step_mm!r}; need a finite step > 0 mm")
        if problems:
            raise DataError("engagement map: " + "; ".join(problems))

    # -- building ---------------------------------------------------------------------------

    @classmethod
    def build(
        cls,
        segments: Iterable[Segment],
        stock: DexelStock,
        cutters: Mapping[int, Cutter],
        *,
        step_mm: float = 0.1,
        band_mm: float = 0.5,
    ) -> EngagementMap:
        """Run a program through the stock and record the engagement every ``step_mm`` of path.

        Parameters
        ----------
        segments
            The interpreted program (consumed lazily), e.g. ``Interpreter(setup).run_file(p)``.
        stock
            The stock before the program, cut in place (pass a fresh one).
        cutters
            Geometry of every tool the program uses, by tool number.
        step_mm
            Path length between locations, mm, > 0. Keep it near the dexel pitch: contact
            reaches ``step / (2 r)`` rad past a wall the tool has just left (discrete
            positions, Heide 2025, Sec. 2.2), and the lookup interpolates between locations.
        band_mm
            Highest band of merged slices with identical intervals, mm, > 0: a force model's
            helix lag is resolved to this height.

        Returns
        -------
        EngagementMap
            One location per ``step_mm`` of the program's path; the last lies within one step
            of the program's end.

        Raises
        ------
        InputError
            On a step or band height that is not finite and > 0 (a program without motion:
            :class:`ConfigError`).
        NCError
            When the program moves a tool that has no geometry, naming the tool and the line.
        """
        for name, value in (("step_mm", step_mm), ("band_mm", band_mm)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
                raise InputError(f"{name}={value!r}; give a finite length > 0 mm")
        # One path speed for every move and one sample per second: s_k = k * step_mm.
        speed_mm_min = 60.0 * step_mm
        sampler = TrajectorySampler(
            _constant_speed(segments, speed_mm_min), rapid_mm_min=speed_mm_min, cycle_s=1.0
        )
        writer = _MapWriter(step_mm, band_mm, stock.grid.pitch_mm[2])
        previous: np.ndarray | None = None
        previous_tool = -1
        rapid = int(MotionKind.RAPID)
        locations = 0
        for chunk in sampler:
            locations += chunk.t_s.size

            def remedy(fraction: float, n: int = locations) -> str:
                return (
                    f"at most {n * fraction:.3g} locations fit: use a step of at least "
                    f"{step_mm / fraction:.3g} mm or a shorter program"
                )

            check_memory(
                f"an engagement map {step_mm:g} mm a location is more than {locations:.3g} "
                "locations",
                float(locations) * _LOCATION_BYTES,
                remedy,
            )
            writer.add_path(chunk.t_s * step_mm, chunk.tcp_mm)
            for i in range(chunk.t_s.size):
                tool = int(chunk.tool[i])
                cutter = cutters.get(tool)
                if cutter is None:
                    raise NCError(
                        f"tool T{tool} has no geometry; give the map builder a Cutter for it",
                        line=int(chunk.line[i]),
                    )
                if tool != previous_tool:
                    previous = None
                    previous_tool = tool
                position = chunk.tcp_mm[i]
                # f_z = 1 mm gives the chip thickness per unit feed per tooth; cycle 1 s.
                engagement = cut(stock, cutter, position, previous, 1.0, 1.0)
                previous = position
                writer.add(
                    engagement, cutter, int(chunk.line[i]), tool, int(chunk.kind[i]) == rapid
                )
        emap = writer.finish(stock.grid.pitch_mm)
        logger.info(
            "engagement map: %d locations over %.1f mm of path, %d in contact, %d bands",
            len(emap), emap.length_mm, int(emap.table[:, _CONTACT].sum()), emap.band_lo_mm.size,
        )  # fmt: skip
        return emap

    # -- reading ----------------------------------------------------------------------------

    def __len__(self) -> int:
        return int(self.s_mm.shape[0])

    @property
    def length_mm(self) -> float:
        """Path parameter of the last location, mm."""
        return float(self.s_mm[-1])

    def column(self, name: str) -> np.ndarray:
        """One column of :attr:`table` by name (see ``COLUMNS``), a read-only view.

        Raises
        ------
        InputError
            On a name that is not a column.
        """
        try:
            k = _COLUMN_NAMES.index(name)
        except ValueError:
            raise InputError(f"column {name!r}; give one of {', '.join(_COLUMN_NAMES)}") from None
        view = self.table[:, k]
        view.flags.writeable = False
        return view

    def slices(self, index: int) -> MapSlices:
        """The contact intervals of location ``index`` per axial band (:class:`MapSlices`).

        Raises
        ------
        InputError
            On an index outside ``0 .. len - 1``.
        """
        if not 0 <= index < len(self):
            raise InputError(f"index={index!r}; give a location in 0..{len(self) - 1}")
        b0, b1 = int(self.band_ptr[index]), int(self.band_ptr[index + 1])
        lo = self.band_lo_mm[b0:b1].astype(np.float64)
        hi = self.band_hi_mm[b0:b1].astype(np.float64)
        q0, q1 = int(self.interval_ptr[b0]), int(self.interval_ptr[b1])
        owner = np.repeat(np.arange(b1 - b0), np.diff(self.interval_ptr[b0 : b1 + 1]))
        starts = np.clip(self.interval_start_rad[q0:q1].astype(np.float64), 0.0, _TWO_PI)
        ends = np.clip(self.interval_end_rad[q0:q1].astype(np.float64), 0.0, _TWO_PI)
        return MapSlices(0.5 * (lo + hi), hi - lo, owner, starts, ends)

    # -- lookup -----------------------------------------------------------------------------

    def lookup(
        self,
        position_mm: np.ndarray | tuple[float, float, float],
        hint_s_mm: float | None = None,
        *,
        lookahead_mm: float = LOOKAHEAD_MM,
        tolerance_mm: float = TOLERANCE_MM,
        tie_mm: float = TIE_MM,
    ) -> MapMatch:
        """The engagement at a measured tool-tip position (Ward 2021, Sec. 3.2).

        Parameters
        ----------
        position_mm
            Tool tip (x, y, z) in machine coordinates, mm (the machine's axis positions less
            the tool offset).
        hint_s_mm
            Path parameter of the last match, mm: the window starts there and never looks
            behind it. ``None`` searches the whole path (the earliest visit wins).
        lookahead_mm
            Length of path ahead of the hint that the window covers, mm, > 0: more than the
            tool travels between two lookups.
        tolerance_mm
            Largest distance from the path that counts as on it, mm, > 0; beyond it the lookup
            searches globally, then reports :attr:`MatchStatus.OFF_PATH`.
        tie_mm
            Distances within this of the smallest count as equally near (the earlier visit
            wins), mm, >= 0: more than the noise of the position.

        Returns
        -------
        MapMatch
            The match and its engagement.

        Raises
        ------
        InputError
            On a position that is not three finite numbers or a window parameter out of range.
        """
        _check_window(lookahead_mm, tolerance_mm, tie_mm)
        if hint_s_mm is not None and not math.isfinite(hint_s_mm):
            raise InputError(f"hint_s_mm={hint_s_mm!r}; give a finite path parameter in mm")
        x, y, z = xyz_mm(position_mm, "position_mm")
        return self._lookup(x, y, z, hint_s_mm, lookahead_mm, tolerance_mm, tie_mm)

    def _lookup(
        self,
        x: float,
        y: float,
        z: float,
        hint: float | None,
        lookahead: float,
        tolerance: float,
        tie: float,
    ) -> MapMatch:
        if hint is not None:
            j, u, d = _window_match(
                self.tcp_mm, self.s_mm, self._joined, x, y, z, hint, hint + lookahead, tie
            )
            if d <= tolerance:
                return self._match(MatchStatus.TRACKING, j, u, d)
        return self._resync(x, y, z, -math.inf if hint is None else hint, tolerance, tie)

    def warm_up(self) -> None:
        """Build the global search's k-d tree and compile (or load) the lookup kernels now,
        so that the first lookups (a live cycle's) do not pay for them (about 0.1 s with
        numba's cache, over 1 s without, on the 2-core sandbox)."""
        if len(self) == 0:
            return
        x, y, z = (float(v) for v in self.tcp_mm[0])
        s = float(self.s_mm[0])
        self._lookup(x, y, z, None, LOOKAHEAD_MM, TOLERANCE_MM, TIE_MM)  # global search
        self._lookup(x, y, z, s, LOOKAHEAD_MM, TOLERANCE_MM, TIE_MM)  # window

    @cached_property
    def _joined(self) -> np.ndarray:
        """(n,) bool: location i joins i + 1 by a piece of path (not a jump, not the end)."""
        joined = np.zeros(len(self), dtype=np.bool_)
        if len(self) > 1:
            chord = np.linalg.norm(np.diff(self.tcp_mm, axis=0), axis=1)
            same_tool = self.table[1:, _TOOL] == self.table[:-1, _TOOL]
            limit = self.step_mm * (1.0 + _CHORD_SLACK) + 1e-9
            joined[:-1] = same_tool & (chord <= limit) & (np.diff(self.s_mm) > 0.0)
        return joined

    @cached_property
    def _tree(self) -> Any:
        """k-d tree over the locations, for the global search (scipy.spatial is imported here:
        it would add ~0.2 s to importing :mod:`cnctwin.geometry`)."""
        from scipy.spatial import cKDTree

        return cKDTree(self.tcp_mm)

    def _resync(
        self, x: float, y: float, z: float, hint: float, tolerance: float, tie: float
    ) -> MapMatch:
        """Global search within the tolerance, preferring matches at or after ``hint``."""
        near = self._tree.query_ball_point((x, y, z), tolerance + self.step_mm)
        if near:
            points = np.asarray(near, dtype=np.int64)
            pieces = np.unique(np.concatenate([points - 1, points]))
            pieces = pieces[pieces >= 0]
            dist = np.empty(pieces.size)
            frac = np.empty(pieces.size)
            _piece_distances(self.tcp_mm, self._joined, pieces, x, y, z, dist, frac)
            s_at = self.s_mm[pieces] + frac * self.step_mm
            inside = dist <= tolerance
            ahead = inside & (s_at >= hint)
            pick = ahead if ahead.any() else inside
            if pick.any():
                k = _first_run(pieces, dist, pick, tie)
                return self._match(MatchStatus.RESYNCED, int(pieces[k]), frac[k], dist[k])
        d, i = self._tree.query((x, y, z))
        return self._off_path(int(i), float(d))

    def _match(self, status: MatchStatus, j: int, u: float, d: float) -> MapMatch:
        """Interpolated engagement between location j and j + 1 at fraction u."""
        a = self.table[j].tolist()
        s = float(self.s_mm[j])
        row = a
        near = j
        w = 0.0
        if u > 0.0 and self._joined[j]:
            b = self.table[j + 1].tolist()
            w = float(u)
            s += w * (float(self.s_mm[j + 1]) - s)
            if w >= 0.5:
                row = b
                near = j + 1
            if a[_CONTACT] > 0.0 and b[_CONTACT] > 0.0:
                # Both in contact: the continuous values are linear in s (the angles only when
                # both have contact within [0, pi]).
                last = _CONTACT if not math.isnan(a[_ENTRY] + b[_ENTRY]) else _ENTRY
                row = row.copy()
                row[:last] = [p + w * (q - p) for p, q in zip(a[:last], b[:last], strict=True)]
        return MapMatch(
            status=status,
            s_mm=s,
            distance_mm=float(d),
            location=j,
            fraction=w,
            nearest=near,
            line=int(row[_LINE]),
            tool=int(row[_TOOL]),
            rapid=row[_RAPID] > 0.0,
            contact=row[_CONTACT] > 0.0,
            ae_mm=row[_AE],
            ap_mm=row[_AP],
            cut_area_mm2=row[_AREA],
            h_mean_per_fz=row[_HMEAN],
            h_max_per_fz=row[_HMAX],
            entry_rad=row[_ENTRY],
            exit_rad=row[_EXIT],
            feed_dir=(row[_FX], row[_FY]),
            bottom_contact=row[_BOTTOM] > 0.0,
            above_flutes=row[_ABOVE] > 0.0,
        )

    def _off_path(self, i: int, d: float) -> MapMatch:
        """No engagement: the tool is farther than the tolerance from the whole path."""
        row = self.table[i]
        return MapMatch(
            status=MatchStatus.OFF_PATH,
            s_mm=float(self.s_mm[i]),
            distance_mm=d,
            location=i,
            fraction=0.0,
            nearest=i,
            line=int(row[_LINE]),
            tool=int(row[_TOOL]),
            rapid=bool(row[_RAPID] > 0.0),
            contact=False,
            ae_mm=0.0,
            ap_mm=0.0,
            cut_area_mm2=0.0,
            h_mean_per_fz=0.0,
            h_max_per_fz=0.0,
            entry_rad=math.nan,
            exit_rad=math.nan,
            feed_dir=(float(row[_FX]), float(row[_FY])),
            bottom_contact=False,
            above_flutes=False,
        )


class MapCursor:
    """The lookahead window's state: follows the tool along an :class:`EngagementMap`.

    Parameters
    ----------
    engagement_map
        The map.
    lookahead_mm, tolerance_mm, tie_mm
        Window parameters in mm, as for :meth:`EngagementMap.lookup`.
    s_mm
        Path parameter to start from, mm; ``None`` (the default) makes the first lookup a
        global search.

    Raises
    ------
    InputError
        On a window parameter out of range.

    Notes
    -----
    While tracking, the window only moves forward: each match lies at or after the last one.
    A resynchronisation may move it anywhere (its status says so); an off-path lookup leaves it
    where it was.
    """

    __slots__ = ("_hint", "_lookahead", "_map", "_tie", "_tolerance")

    def __init__(
        self,
        engagement_map: EngagementMap,
        *,
        lookahead_mm: float = LOOKAHEAD_MM,
        tolerance_mm: float = TOLERANCE_MM,
        tie_mm: float = TIE_MM,
        s_mm: float | None = None,
    ) -> None:
        _check_window(lookahead_mm, tolerance_mm, tie_mm)
        self._map = engagement_map
        self._lookahead = float(lookahead_mm)
        self._tolerance = float(tolerance_mm)
        self._tie = float(tie_mm)
        self._hint: float | None = None
        self.reset(s_mm)

    @property
    def s_mm(self) -> float | None:
        """Path parameter of the last match, mm (``None`` before the first)."""
        return self._hint

    def reset(self, s_mm: float | None = None) -> None:
        """Restart the window at ``s_mm`` (mm), or make the next lookup a global search.

        Raises
        ------
        InputError
            On a path parameter that is not finite.
        """
        if s_mm is not None and not math.isfinite(s_mm):
            raise InputError(f"s_mm={s_mm!r}; give a finite path parameter in mm or None")
        self._hint = None if s_mm is None else float(s_mm)

    def lookup(self, position_mm: np.ndarray | tuple[float, float, float]) -> MapMatch:
        """Match a measured tool-tip position (mm) and advance the window (see the class).

        Raises
        ------
        InputError
            On a position that is not three finite numbers.
        """
        x, y, z = xyz_mm(position_mm, "position_mm")
        match = self._map._lookup(x, y, z, self._hint, self._lookahead, self._tolerance, self._tie)
        if match.status != MatchStatus.OFF_PATH:
            self._hint = match.s_mm
        return match


def save_engagement_map(engagement_map: EngagementMap, path: str | os.PathLike[str]) -> None:
    """Write a map to an uncompressed ``.npz`` file at exactly ``path``."""
    arrays = {name: getattr(engagement_map, name) for name in _ARRAYS}
    with open(path, "wb") as handle:
        np.savez(
            handle,
            format_version=np.int64(FORMAT_VERSION),
            step_mm=np.float64(engagement_map.step_mm),
            pitch_mm=np.asarray(engagement_map.pitch_mm, dtype=np.float64),
            **arrays,
        )


def load_engagement_map(path: str | os.PathLike[str]) -> EngagementMap:
    """Read a map written by :func:`save_engagement_map`.

    Raises
    ------
    DataError
        When the file cannot be read, is not an engagement map of this format version, or its
        arrays are inconsistent.
    """
    try:
        with np.load(path, allow_pickle=False) as data:
            fields: dict[str, Any] = {name: data[name] for name in _ARRAYS}
            version = int(data["format_version"])
            step = float(data["step_mm"])
            pitch = data["pitch_mm"].tolist()
    except (OSError, ValueError, KeyError) as err:
        raise DataError(f"{os.fspath(path)}: not a readable engagement map ({err})") from None
    if version != FORMAT_VERSION:
        raise DataError(
            f"{os.fspath(path)}: engagement map format {version}; this version reads "
            f"{FORMAT_VERSION}"
        )
    return EngagementMap(step_mm=step, pitch_mm=(pitch[0], pitch[1], pitch[2]), **fields)


class _MapWriter:
    """Collects the locations of a map while it is built (:meth:`EngagementMap.build`)."""

    def __init__(self, step_mm: float, band_mm: float, pz_mm: float) -> None:
        self.step_mm = float(step_mm)
        self.band_mm = float(band_mm)
        self.pz_mm = float(pz_mm)
        self.s_parts: list[np.ndarray] = []
        self.tcp_parts: list[np.ndarray] = []
        self.rows: list[list[float]] = []
        self.band_counts: list[int] = []
        self.lo_parts: list[np.ndarray] = []
        self.hi_parts: list[np.ndarray] = []
        self.interval_counts: list[np.ndarray] = []
        self.start_parts: list[np.ndarray] = []
        self.end_parts: list[np.ndarray] = []

    def add_path(self, s_mm: np.ndarray, tcp_mm: np.ndarray) -> None:
        """Path parameters (mm) and tool tips (mm) of the next locations."""
        self.s_parts.append(s_mm)
        self.tcp_parts.append(tcp_mm.copy())

    def add(self, e: Engagement, cutter: Cutter, line: int, tool: int, rapid: bool) -> None:
        """The engagement of the next location (cut with f_z = 1 mm)."""
        row = [0.0] * _N_COLUMNS
        row[_LINE] = float(line)
        row[_TOOL] = float(tool)
        row[_RAPID] = float(rapid)
        row[_FX], row[_FY] = e.feed_dir
        row[_ENTRY] = row[_EXIT] = math.nan
        self.rows.append(row)
        if not e.contact:
            self.band_counts.append(0)
            return
        m = e.slice_height_mm.size
        q = e.interval_start_rad.size
        lo, hi, starts, ends, hull = np.empty(m), np.empty(m), np.empty(q), np.empty(q), np.empty(2)
        ptr = np.empty(m + 1, dtype=np.int64)
        nb, nq = _bands(
            e.slice_height_mm, e.slice_dz_mm, e.interval_slice, e.interval_start_rad,
            e.interval_end_rad, self.pz_mm, cutter.flute_length_mm, self.band_mm, lo, hi, ptr,
            starts, ends, hull,
        )  # fmt: skip
        self.band_counts.append(nb)
        self.lo_parts.append(lo[:nb])
        self.hi_parts.append(hi[:nb])
        self.interval_counts.append(np.diff(ptr[: nb + 1]))
        self.start_parts.append(starts[:nq])
        self.end_parts.append(ends[:nq])
        row[_CONTACT] = 1.0
        row[_AE] = e.ae_mm
        row[_AP] = e.ap_mm
        row[_AREA] = e.removed_volume_mm3 / self.step_mm
        row[_HMEAN] = e.h_mean_mm
        row[_HMAX] = e.h_max_mm
        row[_ENTRY], row[_EXIT] = hull.tolist()
        row[_BOTTOM] = float(e.bottom_contact)
        row[_ABOVE] = float(e.above_flutes)

    def finish(self, pitch_mm: tuple[float, float, float]) -> EngagementMap:
        """The map of the locations added so far.

        Raises
        ------
        ConfigError
            When there are none (a program without motion).
        """
        if not self.rows:
            raise ConfigError("the program has no motion; an engagement map needs a path")
        per_band = (
            np.concatenate(self.interval_counts)
            if self.interval_counts
            else np.zeros(0, dtype=np.int64)
        )
        return EngagementMap(
            step_mm=self.step_mm,
            pitch_mm=pitch_mm,
            s_mm=np.concatenate(self.s_parts),
            tcp_mm=np.concatenate(self.tcp_parts),
            table=np.array(self.rows, dtype=np.float64),
            band_ptr=_pointers(np.asarray(self.band_counts, dtype=np.int64)),
            band_lo_mm=_concat32(self.lo_parts),
            band_hi_mm=_concat32(self.hi_parts),
            interval_ptr=_pointers(per_band),
            interval_start_rad=_concat32(self.start_parts),
            interval_end_rad=_concat32(self.end_parts),
        )


# -- helpers --------------------------------------------------------------------------------


def _check_window(lookahead_mm: float, tolerance_mm: float, tie_mm: float) -> None:
    if not (math.isfinite(lookahead_mm) and lookahead_mm > 0.0):
        raise InputError(f"lookahead_mm={lookahead_mm!r}; give a finite length > 0 mm")
    if not (math.isfinite(tolerance_mm) and tolerance_mm > 0.0):
        raise InputError(f"tolerance_mm={tolerance_mm!r}; give a finite distance > 0 mm")
    if not (math.isfinite(tie_mm) and tie_mm >= 0.0):
        raise InputError(f"tie_mm={tie_mm!r}; give a finite distance >= 0 mm")


def _constant_speed(segments: Iterable[Segment], speed_mm_min: float) -> Iterator[Segment]:
    """The program's moves at one feed (rapids keep theirs: the sampler's rapid rate), no dwells."""
    for segment in segments:
        if segment.kind == MotionKind.DWELL:
            continue
        if segment.kind == MotionKind.RAPID:
            yield segment
        else:
            yield dataclasses.replace(segment, feed_mm_min=speed_mm_min)


def _pointers(counts: np.ndarray) -> np.ndarray:
    out = np.zeros(counts.size + 1, dtype=np.int64)
    np.cumsum(counts, out=out[1:])
    return out


def _concat32(parts: list[np.ndarray]) -> np.ndarray:
    return np.concatenate(parts).astype(np.float32) if parts else np.zeros(0, np.float32)


def _first_run(pieces: np.ndarray, dist: np.ndarray, pick: np.ndarray, tie: float) -> int:
    """Index of the nearest candidate in the first run of consecutive pieces (in path order)
    whose distance is within ``tie`` of the smallest picked distance."""
    limit = float(dist[pick].min()) + tie
    good = pick & (dist <= limit)
    first = int(np.argmax(good))
    best = first
    k = first + 1
    while k < pieces.size and good[k] and pieces[k] == pieces[k - 1] + 1:
        if dist[k] < dist[best]:
            best = k
        k += 1
    return best


@njit(cache=True)
def _piece_distance(
    points: np.ndarray, joined: np.ndarray, j: int, lo: float, x: float, y: float, z: float
) -> tuple[float, float]:  # pragma: no cover - numba
    """(distance, fraction) from (x, y, z) to piece j: the segment from location j to j + 1
    from fraction ``lo`` on, or location j alone when it does not join the next."""
    ax = points[j, 0]
    ay = points[j, 1]
    az = points[j, 2]
    u = 0.0
    if joined[j]:
        dx = points[j + 1, 0] - ax
        dy = points[j + 1, 1] - ay
        dz = points[j + 1, 2] - az
        length2 = dx * dx + dy * dy + dz * dz
        u = lo
        if length2 > 0.0:
            u = ((x - ax) * dx + (y - ay) * dy + (z - az) * dz) / length2
            u = min(max(u, lo), 1.0)
        ax += u * dx
        ay += u * dy
        az += u * dz
    return math.sqrt((x - ax) ** 2 + (y - ay) ** 2 + (z - az) ** 2), u


@njit(cache=True)
def _window_match(
    points: np.ndarray,
    s: np.ndarray,
    joined: np.ndarray,
    x: float,
    y: float,
    z: float,
    hint: float,
    s_end: float,
    tie: float,
) -> tuple[int, float, float]:  # pragma: no cover - numba
    """Best (piece, fraction, distance) in the window from path parameter ``hint`` (never
    before it) to the last piece starting at or before ``s_end``: the nearest point of the
    first run of consecutive pieces whose distance is within ``tie`` of the window's smallest."""
    n = points.shape[0]
    j0 = int(np.searchsorted(s, hint, side="right")) - 1
    u0 = 0.0
    if j0 < 0:
        j0 = 0
    elif j0 >= n - 1:
        j0 = n - 1
    elif not joined[j0]:
        if hint > s[j0]:
            j0 += 1  # the hint lies in a jump (a tool change): start after it
    else:
        u0 = (hint - s[j0]) / (s[j0 + 1] - s[j0])
    j1 = j0 + 1
    while j1 < n and s[j1] <= s_end:
        j1 += 1
    smallest = math.inf
    for j in range(j0, j1):
        d, _ = _piece_distance(points, joined, j, u0 if j == j0 else 0.0, x, y, z)
        smallest = min(smallest, d)
    limit = smallest + tie
    best = j0
    best_u = u0
    best_d = math.inf
    started = False
    for j in range(j0, j1):
        d, u = _piece_distance(points, joined, j, u0 if j == j0 else 0.0, x, y, z)
        if d <= limit:
            started = True
            if d < best_d:
                best, best_u, best_d = j, u, d
        elif started:
            break
    return best, best_u, best_d


@njit(cache=True)
def _piece_distances(
    points: np.ndarray,
    joined: np.ndarray,
    pieces: np.ndarray,
    x: float,
    y: float,
    z: float,
    dist: np.ndarray,
    frac: np.ndarray,
) -> None:  # pragma: no cover - numba
    """Distances and fractions of the given pieces (see :func:`_piece_distance`)."""
    for k in range(pieces.size):
        dist[k], frac[k] = _piece_distance(points, joined, pieces[k], 0.0, x, y, z)


@njit(cache=True)
def _bands(
    height: np.ndarray,
    dz: np.ndarray,
    iv_slice: np.ndarray,
    iv_start: np.ndarray,
    iv_end: np.ndarray,
    pz: float,
    flute_length: float,
    band_mm: float,
    lo: np.ndarray,
    hi: np.ndarray,
    ptr: np.ndarray,
    starts: np.ndarray,
    ends: np.ndarray,
    hull: np.ndarray,
) -> tuple[int, int]:  # pragma: no cover - numba
    """Merge an engagement's slices into bands; returns (bands, intervals).

    Slice k of :func:`cnctwin.geometry.cut` samples the envelope at ``height[k]`` above the tip
    and stands for ``[hi - dz[k], hi]`` with ``hi = min(height[k] + pz / 2, flute_length)``
    (mm). Consecutive, touching slices with identical intervals join one band while it stays
    at most ``band_mm`` high. ``hull`` gets the (entry, exit) hull of the intervals clipped to
    [0, pi], NaN when none reaches into it.
    """
    m = height.size
    q = iv_slice.size
    nb = 0
    nq = 0
    iv = 0
    prev_first = 0
    prev_count = -1
    entry = math.inf
    exit_ = -math.inf
    for k in range(m):
        first = iv
        while iv < q and iv_slice[iv] == k:
            iv += 1
        count = iv - first
        top = min(height[k] + 0.5 * pz, flute_length)
        bottom = top - dz[k]
        same = (
            nb > 0
            and count == prev_count
            and abs(bottom - hi[nb - 1]) <= 1e-6
            and top - lo[nb - 1] <= band_mm + 1e-9
        )
        if same:
            for r in range(count):
                if (
                    iv_start[first + r] != iv_start[prev_first + r]
                    or iv_end[first + r] != iv_end[prev_first + r]
                ):
                    same = False
                    break
        if same:
            hi[nb - 1] = top
        else:
            lo[nb] = bottom
            hi[nb] = top
            ptr[nb] = nq
            for r in range(count):
                a = iv_start[first + r]
                b = iv_end[first + r]
                starts[nq] = a
                ends[nq] = b
                nq += 1
                if a < math.pi:
                    entry = min(entry, max(a, 0.0))
                    exit_ = max(exit_, min(b, math.pi))
            nb += 1
        prev_first = first
        prev_count = count
    ptr[nb] = nq
    if entry <= exit_:
        hull[0] = entry
        hull[1] = exit_
    else:
        hull[0] = math.nan
        hull[1] = math.nan
    return nb, nq
