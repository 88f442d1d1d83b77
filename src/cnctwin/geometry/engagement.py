"""Cutter-workpiece engagement of one cut, from the dexels it actually removed.

Units: mm (names end in ``_mm``), mm^3, mm^3/s, mm/min for the feed (as the NC layer), s, rad.

Angle frame
-----------
Angles follow the mechanistic milling convention (Altintas, *Manufacturing Automation*, 2nd ed.,
2012, Sec. 2.2): with ``f`` the unit feed direction in the xy plane and ``n = (-f_y, f_x)`` its
left normal, a point of the tool's periphery at angle ``phi`` sits at ``r (sin(phi) f +
cos(phi) n)`` from the axis, so ``phi`` runs clockwise seen from above (+z), the sense of an M3
spindle: ``phi = 0`` on the left of the feed, ``pi/2`` ahead, ``pi`` on the right. The uncut chip
thickness is ``h = f_z sin(phi) sin(kappa)`` (``kappa`` from
:meth:`~cnctwin.geometry.cutter.Cutter.sin_kappa_at`, 1 on a cylinder). A full slot engages
``[0, pi]``; up milling (material on the left) ``[0, phi_e]`` and down milling (material on the
right) ``[pi - phi_e, pi]``, with ``phi_e = arccos(1 - 2 a_e / D)``.

Intervals
---------
The contact of a cut (see :mod:`cnctwin.geometry.removal`) is sampled where the grid's rays
cross the envelope, at most ``sqrt(2) p / r`` apart (pitch ``p``, slice radius ``r``), and
comes as arcs. Per slice, arcs closer than ``1.5 sqrt(2) p / r`` join one interval; so do arcs
up to ``2.5 sqrt(2) p / r`` apart whose gap spans one of the directions at 45 degrees to the
grid's axes, where the x rays' contact points end and the y rays' begin (the last of one family
and the first of the other each lie up to ``sqrt(2) p`` from that direction). Each interval is
widened by ``p / (2 r)`` on both sides (half a sample spacing: the unbiased estimate of where
contact ends between two samples). Intervals are half-open ``[start, end)`` with
``0 <= start < end <= 2 pi``, sorted, disjoint; a contact region across ``phi = 0`` is split
into ``[0, e)`` and ``[s, 2 pi)``. Slices are the grid's z levels inside the fluted length;
slice ``k`` samples the envelope at its level ``z_k`` and stands for ``[z_k - p_z/2, z_k +
p_z/2]`` (the lowest one down to the tip).

Discrete positions (Heide 2025, Sec. 2.2) let contact reach ``s / (2 r)`` past a wall the tool
has just left (step ``s``), and a ball or bull nose leaves cusps ``s^2 / (8 R)`` high between
positions, which the next position removes behind its axis in the lowest slices: contact in
``(pi, 2 pi)``, where the chip thickness is 0.

Widths
------
``ae`` is the extent of the removed material along the feed normal ``n`` and ``ap`` its extent
along z: the removed dexels' ends (along z exact to float32 for z rays; x and y rays stand for
their level's slab, clipped to the tip and the fluted length). Material thinner than twice the
cusps the discrete positions leave on a wall (:mod:`cnctwin.geometry.removal`, "Thin
material") is removed and counted in the volume but is not a cut: it does not widen ``ae`` or
``ap``, and is a contact only as the thin edge of a region that is cut; a step that only removes
such material has ``contact`` true, no intervals, ``ae = ap = 0``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from cnctwin.errors import ConfigError
from cnctwin.geometry.cutter import Cutter
from cnctwin.geometry.dexel import DexelStock

# numba caches the kernels below by this file's content alone, with the removal kernels they
# call compiled in: a change to those kernels needs a change here too, or a stale cache runs
# the old code (removal kernels revised: cell indices clamped, 2026-11).
from cnctwin.geometry.removal import (
    _DONE,
    A_ABOVE,
    A_ARCS,
    A_BOTTOM,
    A_LEN_X,
    A_LEN_Y,
    A_LEN_Z,
    A_NMAX,
    A_NMIN,
    A_ZMAX,
    A_ZMIN,
    I_K0,
    I_NSLICES,
    P_FX,
    P_FY,
    P_GAP,
    P_INNER,
    P_L,
    P_PX,
    P_PY,
    P_PZ,
    P_R,
    P_RC,
    P_SLOPE,
    P_TZ,
    Workspace,
    _cut,
    grow_for,
    kernel,
    last_tip,
    parameters,
    place,
    reset_accumulators,
    workspace,
    xyz_mm,
)

__all__ = ["Engagement", "EngagementPath", "cut", "cut_path"]

TWO_PI = 2.0 * math.pi
_WIDEN_PITCHES = 0.5  # widen intervals by this many pitches (over r) on each side
_MIN_FEED_MOVE_MM = 1e-9  # a horizontal displacement below this leaves the feed direction +x
#: Across the 45-degree boundary between the x and the y rays' contact points, arcs of one
#: contact region may lie one more sample spacing (sqrt(2) pitches) apart than within a family:
#: up to sqrt(2) p before the boundary in one family and sqrt(2) p after it in the other.
_ACROSS_PITCHES = math.sqrt(2.0)
# Columns of the per-position output of _path.
_O_CONTACT, _O_REMOVED, _O_MRR, _O_AE, _O_AP, _O_FEED, _O_FDX, _O_FDY = range(8)
_O_HMEAN, _O_HMAX, _O_BOTTOM, _O_ABOVE = range(8, 12)
_N_OUT = 12
_OUT_FULL = 3  # kernel status: the output buffers of slices or intervals are full


class Engagement(NamedTuple):
    """Engagement of one cut (one sampled tool position).

    Attributes
    ----------
    contact
        Whether the tool removed material.
    removed_volume_mm3
        Volume removed by this cut, mm^3 (mean of the three dexel families), >= 0.
    mrr_mm3_s
        Material removal rate ``removed_volume_mm3 / cycle_s``, mm^3/s.
    ae_mm
        Radial depth (width) of cut: extent of the removed material along the feed normal, mm,
        in [0, D].
    ap_mm
        Axial depth of cut: extent of the removed material along z, mm, in [0, flute length].
    feed_mm_min
        Feed velocity reconstructed from the tip's displacement since the previous position,
        ``|p - p_prev| / cycle_s``, mm/min (Heide 2025, Sec. 2.3); NaN without a previous
        position.
    feed_dir
        Unit feed direction (x, y) of the angle frame: the horizontal displacement, or (1, 0)
        when the tip did not move horizontally.
    h_mean_mm
        Mean uncut chip thickness over the engaged tool surface, ``integral of
        f_z max(sin phi, 0) sin kappa dphi dz / integral of dphi dz``, mm (for a flat end mill
        ``f_z (cos phi_st - cos phi_ex) / (phi_ex - phi_st)``, Martellotti); 0 without contact.
    h_max_mm
        Largest uncut chip thickness ``f_z sin(phi) sin(kappa)`` over the engagement, mm.
    slice_height_mm
        (m,) heights above the tip (mm) where the slices with contact sample the envelope.
    slice_dz_mm
        (m,) height of tool each slice stands for, mm.
    slice_radius_mm
        (m,) envelope radius at each slice's height, mm.
    interval_slice
        (q,) index into the slice arrays of each contact interval.
    interval_start_rad, interval_end_rad
        (q,) contact intervals ``[start, end)`` in rad, ``0 <= start < end <= 2 pi``, sorted
        and disjoint within a slice (see the module notes).
    bottom_contact
        The flat bottom face of a flat or bull-nose end mill cut material while moving down (a
        plunge or ramp; the first cut of a stock counts as moving down). Bottom-face contacts
        are not part of the intervals.
    above_flutes
        Material at the top of the fluted length inside the footprint: the shank would hit it.
    """

    contact: bool
    removed_volume_mm3: float
    mrr_mm3_s: float
    ae_mm: float
    ap_mm: float
    feed_mm_min: float
    feed_dir: tuple[float, float]
    h_mean_mm: float
    h_max_mm: float
    slice_height_mm: np.ndarray
    slice_dz_mm: np.ndarray
    slice_radius_mm: np.ndarray
    interval_slice: np.ndarray
    interval_start_rad: np.ndarray
    interval_end_rad: np.ndarray
    bottom_contact: bool
    above_flutes: bool

    def slice_intervals(self, index: int) -> list[tuple[float, float]]:
        """The contact intervals ``(start, end)`` in rad of slice ``index``."""
        sel = self.interval_slice == index
        return list(
            zip(
                self.interval_start_rad[sel].tolist(),
                self.interval_end_rad[sel].tolist(),
                strict=True,
            )
        )


class EngagementPath(NamedTuple):
    """Engagement of consecutive cuts along a path: one row per tool position.

    The scalar fields are arrays with one value per position, as the fields of the same name
    of :class:`Engagement` (same units). Slices and intervals of all positions are stored one
    position after the other: position ``i`` owns slices ``slice_offsets[i]`` to
    ``slice_offsets[i + 1]`` and intervals ``interval_offsets[i]`` to
    ``interval_offsets[i + 1]``; :meth:`engagement` gives one position's :class:`Engagement`.

    Attributes
    ----------
    contact, bottom_contact, above_flutes
        (n,) bool.
    removed_volume_mm3, mrr_mm3_s, ae_mm, ap_mm, feed_mm_min, h_mean_mm, h_max_mm
        (n,) float64.
    feed_dir
        (n, 2) unit feed directions.
    slice_offsets, interval_offsets
        (n + 1,) int64 offsets into the slice and interval arrays.
    slice_height_mm, slice_dz_mm, slice_radius_mm
        Slices of every position, mm.
    interval_slice
        Index of each interval's slice among its position's slices.
    interval_start_rad, interval_end_rad
        Contact intervals, rad.
    """

    contact: np.ndarray
    removed_volume_mm3: np.ndarray
    mrr_mm3_s: np.ndarray
    ae_mm: np.ndarray
    ap_mm: np.ndarray
    feed_mm_min: np.ndarray
    feed_dir: np.ndarray
    h_mean_mm: np.ndarray
    h_max_mm: np.ndarray
    bottom_contact: np.ndarray
    above_flutes: np.ndarray
    slice_offsets: np.ndarray
    slice_height_mm: np.ndarray
    slice_dz_mm: np.ndarray
    slice_radius_mm: np.ndarray
    interval_offsets: np.ndarray
    interval_slice: np.ndarray
    interval_start_rad: np.ndarray
    interval_end_rad: np.ndarray

    def engagement(self, index: int) -> Engagement:
        """The :class:`Engagement` of position ``index`` (arrays are views into this path)."""
        i = int(index)
        s0, s1 = int(self.slice_offsets[i]), int(self.slice_offsets[i + 1])
        c0, c1 = int(self.interval_offsets[i]), int(self.interval_offsets[i + 1])
        return Engagement(
            contact=bool(self.contact[i]),
            removed_volume_mm3=float(self.removed_volume_mm3[i]),
            mrr_mm3_s=float(self.mrr_mm3_s[i]),
            ae_mm=float(self.ae_mm[i]),
            ap_mm=float(self.ap_mm[i]),
            feed_mm_min=float(self.feed_mm_min[i]),
            feed_dir=(float(self.feed_dir[i, 0]), float(self.feed_dir[i, 1])),
            h_mean_mm=float(self.h_mean_mm[i]),
            h_max_mm=float(self.h_max_mm[i]),
            slice_height_mm=self.slice_height_mm[s0:s1],
            slice_dz_mm=self.slice_dz_mm[s0:s1],
            slice_radius_mm=self.slice_radius_mm[s0:s1],
            interval_slice=self.interval_slice[c0:c1],
            interval_start_rad=self.interval_start_rad[c0:c1],
            interval_end_rad=self.interval_end_rad[c0:c1],
            bottom_contact=bool(self.bottom_contact[i]),
            above_flutes=bool(self.above_flutes[i]),
        )


def cut(
    stock: DexelStock,
    cutter: Cutter,
    position_mm: np.ndarray | tuple[float, float, float],
    previous_position_mm: np.ndarray | tuple[float, float, float] | None,
    feed_per_tooth_mm: float,
    cycle_s: float,
) -> Engagement:
    """One simulation step: cut the stock at a tool position and return the engagement.

    Parameters
    ----------
    stock
        The stock, changed in place.
    cutter
        The cutter (axis +z).
    position_mm
        Tool tip (x, y, z) in machine coordinates, mm (``SampleChunk.tcp_mm``).
    previous_position_mm
        Tool tip at the previous step, mm; ``None`` for the first step.
    feed_per_tooth_mm
        Feed per tooth ``f_z`` in mm for the chip thickness, finite and >= 0.
    cycle_s
        Time between the two positions in s, > 0.

    Returns
    -------
    Engagement
        ae, ap, contact intervals, chip thickness, MRR and the reconstructed feed.

    Raises
    ------
    ConfigError
        On a position that is not three finite numbers, a negative or non-finite feed per
        tooth, or a cycle time that is not finite and > 0.

    Notes
    -----
    Discrete-position material removal (Heide 2025, Sec. 2.2;
    :func:`cnctwin.geometry.removal.remove`) followed by the engagement of the removed dexels
    (Heide 2025, Fig. 5, steps 2-3), in one compiled call. A simulation loop::

        stock = DexelStock.box((0, 0, -30), (100, 100, 0), density_per_mm=10)
        previous = None
        for position in chunk.tcp_mm:
            engagement = cut(stock, cutter, position, previous, 0.05, 0.0125)
            previous = position

    :func:`cut_path` does the same for many positions in one call, without the Python
    overhead of a call per position.
    """
    _check_feed_and_cycle(feed_per_tooth_mm, cycle_s)
    tip = xyz_mm(position_mm, "position_mm")
    previous = (
        None
        if previous_position_mm is None
        else xyz_mm(previous_position_mm, "previous_position_mm")
    )
    ws = workspace(stock)
    outputs = ws.outputs
    if not isinstance(outputs, _Outputs):
        outputs = ws.outputs = _Outputs(1, ws)
    # The tip in grid coordinates and the feed, in the buffers kept for one position.
    ox, oy, oz = ws.grid[:3]
    outputs.tip[0, 0], outputs.tip[0, 1], outputs.tip[0, 2] = tip[0] - ox, tip[1] - oy, tip[2] - oz
    outputs.fz[0] = feed_per_tooth_mm
    _run(stock, ws, cutter, outputs.tip, previous, outputs.fz, cycle_s, outputs)
    m, q = int(outputs.slice_offsets[1]), int(outputs.interval_offsets[1])
    row = outputs.out[0].tolist()
    slices = outputs.slices[:, :m].copy()
    angles = outputs.intervals[:, :q].copy()
    return Engagement(
        contact=row[_O_CONTACT] > 0.0,
        removed_volume_mm3=row[_O_REMOVED],
        mrr_mm3_s=row[_O_MRR],
        ae_mm=row[_O_AE],
        ap_mm=row[_O_AP],
        feed_mm_min=row[_O_FEED],
        feed_dir=(row[_O_FDX], row[_O_FDY]),
        h_mean_mm=row[_O_HMEAN],
        h_max_mm=row[_O_HMAX],
        slice_height_mm=slices[0],
        slice_dz_mm=slices[1],
        slice_radius_mm=slices[2],
        interval_slice=outputs.interval_slice[:q].copy(),
        interval_start_rad=angles[0],
        interval_end_rad=angles[1],
        bottom_contact=row[_O_BOTTOM] > 0.0,
        above_flutes=row[_O_ABOVE] > 0.0,
    )


def cut_path(
    stock: DexelStock,
    cutter: Cutter,
    positions_mm: np.ndarray,
    previous_position_mm: np.ndarray | tuple[float, float, float] | None,
    feed_per_tooth_mm: float | np.ndarray,
    cycle_s: float,
) -> EngagementPath:
    """Many simulation steps: cut the stock at consecutive tool positions, one compiled call.

    The same as calling :func:`cut` for every position in turn (each with the one before as
    its previous position), with the same results, without the Python overhead per position.

    Parameters
    ----------
    stock
        The stock, changed in place.
    cutter
        The cutter (axis +z).
    positions_mm
        (n, 3) tool tips in machine coordinates, mm, in the order they are cut.
    previous_position_mm
        Tool tip before the first position, mm; ``None`` if there is none.
    feed_per_tooth_mm
        Feed per tooth ``f_z`` in mm, one for all positions or (n,) one each, finite, >= 0.
    cycle_s
        Time between two positions in s, > 0.

    Returns
    -------
    EngagementPath
        The engagement at every position.

    Raises
    ------
    ConfigError
        On positions that are not an (n, 3) array of finite numbers, feeds per tooth that are
        negative, not finite or of another length, or a cycle time that is not finite and > 0.
    """
    tips = np.asarray(positions_mm, dtype=np.float64)
    if tips.ndim != 2 or tips.shape[1] != 3 or not np.all(np.isfinite(tips)):
        raise ConfigError(
            f"positions_mm of shape {tips.shape}; give an (n, 3) array of finite tool tips, mm"
        )
    fz = np.broadcast_to(np.asarray(feed_per_tooth_mm, dtype=np.float64), (len(tips),))
    if fz.size and not (np.all(np.isfinite(fz)) and fz.min() >= 0.0):
        raise ConfigError("feed_per_tooth_mm: give finite feeds per tooth >= 0 mm")
    _check_feed_and_cycle(0.0, cycle_s)
    previous = (
        None
        if previous_position_mm is None
        else xyz_mm(previous_position_mm, "previous_position_mm")
    )
    ws = workspace(stock)
    outputs = _Outputs(len(tips), ws)
    grid_tips = tips - np.array(ws.grid[:3])
    _run(stock, ws, cutter, grid_tips, previous, np.ascontiguousarray(fz), cycle_s, outputs)
    out = outputs.out
    m, q = int(outputs.slice_offsets[-1]), int(outputs.interval_offsets[-1])
    return EngagementPath(
        contact=out[:, _O_CONTACT] > 0.0,
        removed_volume_mm3=out[:, _O_REMOVED],
        mrr_mm3_s=out[:, _O_MRR],
        ae_mm=out[:, _O_AE],
        ap_mm=out[:, _O_AP],
        feed_mm_min=out[:, _O_FEED],
        feed_dir=out[:, _O_FDX : _O_FDY + 1],
        h_mean_mm=out[:, _O_HMEAN],
        h_max_mm=out[:, _O_HMAX],
        bottom_contact=out[:, _O_BOTTOM] > 0.0,
        above_flutes=out[:, _O_ABOVE] > 0.0,
        slice_offsets=outputs.slice_offsets,
        slice_height_mm=outputs.slices[0, :m],
        slice_dz_mm=outputs.slices[1, :m],
        slice_radius_mm=outputs.slices[2, :m],
        interval_offsets=outputs.interval_offsets,
        interval_slice=outputs.interval_slice[:q],
        interval_start_rad=outputs.intervals[0, :q],
        interval_end_rad=outputs.intervals[1, :q],
    )


class _Outputs:
    """The output buffers of :func:`_path` for ``n`` positions: a row of :data:`_N_OUT` values
    per position, and the slices and intervals of all positions one after the other; and its
    small input arrays (kept with the buffers of :func:`cut`, which fills them at every call
    instead of allocating them: a few microseconds a position)."""

    __slots__ = (
        "fz",
        "interval_offsets",
        "interval_slice",
        "intervals",
        "old_tip",
        "out",
        "prev",
        "slice_offsets",
        "slices",
        "state",
        "tip",
    )

    def __init__(self, n: int, ws: Workspace) -> None:
        self.out = np.empty((n, _N_OUT))
        # The inputs of one position (cut) and the small arrays of every call (see _run).
        self.tip = np.zeros((1, 3))
        self.fz = np.zeros(1)
        self.state = np.zeros(4, dtype=np.int64)
        self.prev = np.zeros(3)
        self.old_tip = np.zeros(3)
        self.slice_offsets = np.zeros(n + 1, dtype=np.int64)
        self.interval_offsets = np.zeros(n + 1, dtype=np.int64)
        # Room for one position's most slices and intervals, and for four of each a position.
        n_slices = max(4 * n, ws.slices.shape[1])
        n_intervals = max(4 * n, ws.iv_slice.shape[0])
        self.slices = np.empty((3, n_slices))
        self.interval_slice = np.empty(n_intervals, dtype=np.int64)
        self.intervals = np.empty((2, n_intervals))

    def grow(self) -> None:
        """Double the room for slices and intervals, keeping what is written."""
        self.slices = _grown(self.slices)
        self.interval_slice = _grown(self.interval_slice)
        self.intervals = _grown(self.intervals)


def _check_feed_and_cycle(feed_per_tooth_mm: float, cycle_s: float) -> None:
    if not (math.isfinite(feed_per_tooth_mm) and feed_per_tooth_mm >= 0.0):
        raise ConfigError(
            f"feed_per_tooth_mm={feed_per_tooth_mm!r}; give a finite feed per tooth >= 0 mm"
        )
    if not (math.isfinite(cycle_s) and cycle_s > 0.0):
        raise ConfigError(f"cycle_s={cycle_s!r}; give a finite cycle time > 0 s")


def _run(
    stock: DexelStock,
    ws: Workspace,
    cutter: Cutter,
    tips: np.ndarray,
    previous_mm: tuple[float, float, float] | None,
    fz: np.ndarray,
    cycle_s: float,
    outputs: _Outputs,
) -> None:
    """Cut at every tip (grid coordinates, mm) with :func:`_path` into ``outputs``, growing
    buffers as needed; record the last tip as the stock's last cut."""
    n = len(tips)
    ox, oy, oz = ws.grid[:3]
    prm, ints = parameters(ws, cutter)
    old = last_tip(stock, cutter)
    # (element by element: assigning a tuple to a slice costs more than the whole cut of a
    # small tool)
    state, prev, old_tip = outputs.state, outputs.prev, outputs.old_tip
    state[0] = state[1] = 0
    state[2] = previous_mm is not None
    state[3] = old is not None
    if previous_mm is None:
        prev[0] = prev[1] = prev[2] = 0.0
    else:
        prev[0], prev[1], prev[2] = previous_mm[0] - ox, previous_mm[1] - oy, previous_mm[2] - oz
    old_tip[0], old_tip[1], old_tip[2] = old if old is not None else (0.0, 0.0, 0.0)
    widen_mm = _WIDEN_PITCHES * max(ws.grid[3], ws.grid[4])
    while True:
        status = _path(
            prm, ints, tips, fz, cycle_s, state, prev, old_tip, *ws.cut_arrays(stock),
            ws.acc, widen_mm, ws.first, ws.order, ws.ra, ws.rb, ws.pa, ws.pb, ws.slices,
            ws.iv_slice, ws.iv_angles, ws.stats, outputs.out, outputs.slice_offsets,
            outputs.slices, outputs.interval_offsets, outputs.interval_slice, outputs.intervals,
        )  # fmt: skip
        if status == _DONE:
            break
        if status == _OUT_FULL:
            outputs.grow()
        else:
            grow_for(status, stock, ws)
    if n:
        stock.last_cut = (cutter, (float(tips[-1, 0]), float(tips[-1, 1]), float(tips[-1, 2])))


def _grown(array: np.ndarray) -> np.ndarray:
    """A copy of ``array`` twice as long along its last axis."""
    grown = np.empty((*array.shape[:-1], 2 * array.shape[-1]), dtype=array.dtype)
    grown[..., : array.shape[-1]] = array
    return grown


@njit(cache=True)
def _emit(a, b, pa, pb, npieces):
    """Append [a, b] (rad, may cross 0 or 2 pi) as pieces within [0, 2 pi]."""
    if b - a >= TWO_PI:
        pa[npieces] = 0.0
        pb[npieces] = TWO_PI
        return npieces + 1
    if a < 0.0:
        pa[npieces] = 0.0
        pb[npieces] = b
        pa[npieces + 1] = a + TWO_PI
        pb[npieces + 1] = TWO_PI
        return npieces + 2
    if b > TWO_PI:
        pa[npieces] = a
        pb[npieces] = TWO_PI
        pa[npieces + 1] = 0.0
        pb[npieces + 1] = b - TWO_PI
        return npieces + 2
    pa[npieces] = a
    pb[npieces] = b
    return npieces + 1


@njit(cache=True)
def _positive_sine(a, b):
    """(integral, maximum) of max(sin(phi), 0) over [a, b] within [0, 2 pi]."""
    if a >= math.pi:
        return 0.0, 0.0
    bb = min(b, math.pi)
    peak = 1.0 if a <= 0.5 * math.pi <= bb else max(math.sin(a), math.sin(bb))
    return math.cos(a) - math.cos(bb), peak


@njit(cache=True, inline="always")
def _joins(end, start, gap, gap_across, boundary):
    """Whether an arc ending at ``end`` and one starting at ``start`` (rad, ``start`` after
    ``end`` unwrapped) belong to one contact region: closer than ``gap``, or than
    ``gap_across`` where the gap spans a family boundary (``boundary`` modulo pi/2)."""
    space = start - end
    if space <= gap:
        return True
    if space > gap_across:
        return False
    quarter = 0.5 * math.pi
    return math.floor((start - boundary) / quarter) != math.floor((end - boundary) / quarter)


@njit(cache=True)
def _sort_pairs(a, b, m):
    """Sort the first m entries of a (and b alongside) by a: insertion sort, few entries."""
    for q in range(1, m):
        ka = a[q]
        kb = b[q]
        w = q - 1
        while w >= 0 and a[w] > ka:
            a[w + 1] = a[w]
            b[w + 1] = b[w]
            w -= 1
        a[w + 1] = ka
        b[w + 1] = kb


@kernel
def _engage(
    prm,
    ints,
    arc_slice,
    arc_lo,
    arc_hi,
    n_arcs,
    widen_mm,
    first,
    order,
    ra,
    rb,
    pa,
    pb,
    slices,
    out_slice,
    out_angles,
    stats,
):
    """Contact arcs to intervals per slice (module notes), lengths in mm, angles in rad.

    Writes the used slices' (height above the tip, dz, radius) into ``slices`` columns, the
    intervals (index of their slice among the used ones, start, end) into ``out_slice`` and
    ``out_angles``, and ``stats`` = (integral of max(sin phi, 0) sin kappa over phi and z,
    engaged area in rad mm, max of sin phi sin kappa, slices used, intervals).
    """
    first_level = ints[I_K0]
    n_slices = ints[I_NSLICES]
    tip_z, pz = prm[P_TZ], prm[P_PZ]
    for q in range(5):
        stats[q] = 0.0
    big, rc, length = prm[P_R], prm[P_RC], prm[P_L]
    inner, slope = prm[P_INNER], prm[P_SLOPE]
    # On a cone sin(kappa) = cos(theta / 2) (Cutter.sin_kappa_at).
    cone_sin_kappa = 1.0 / math.sqrt(1.0 + slope * slope)
    gap_mm = prm[P_GAP]
    pitch = max(prm[P_PX], prm[P_PY])
    # The row families' contact points meet at 45 degrees to the grid axes, at these angles
    # modulo pi/2 in the feed frame (the point at phi lies at alpha + pi/2 - phi, alpha the
    # feed direction's angle).
    boundary = math.atan2(prm[P_FY], prm[P_FX]) + 0.25 * math.pi
    for s in range(n_slices + 1):
        first[s] = 0
    for q in range(n_arcs):
        first[arc_slice[q] + 1] += 1
    for s in range(n_slices):
        first[s + 1] += first[s]
    for q in range(n_arcs):
        # Counting sort by slice; `first` is restored below.
        s = arc_slice[q]
        order[first[s]] = q
        first[s] += 1
    for s in range(n_slices - 1, 0, -1):
        first[s] = first[s - 1]
    if n_slices > 0:
        first[0] = 0
    count = 0
    used = 0
    # The previous slice with contact: index, radius, first interval, sums per mm of height.
    prev_s = -1
    prev_r = -1.0
    prev_first = 0
    prev_integral = prev_area = 0.0
    for s in range(n_slices):
        m = first[s + 1] - first[s]
        if m == 0:
            continue
        level_z = (first_level + s + 0.5) * pz
        height = level_z - tip_z
        r = big
        sin_kappa = 1.0
        if height < rc:
            w = math.sqrt(max(rc * rc - (rc - max(height, 0.0)) ** 2, 0.0))
            r = big - rc + w
            sin_kappa = w / rc
        elif slope > 0.0 and inner + height * slope < big:
            r = inner + max(height, 0.0) * slope
            sin_kappa = cone_sin_kappa
        if r <= 0.0:
            continue
        low = tip_z if s == 0 else max(level_z - 0.5 * pz, tip_z)
        dz = max(min(level_z + 0.5 * pz, tip_z + length) - low, 0.0)
        slices[0, used] = height
        slices[1, used] = dz
        slices[2, used] = r
        if r == prev_r and m == first[prev_s + 1] - first[prev_s]:
            # The same arcs as the previous slice (the cylinder of a 2.5D cut): same intervals.
            same = True
            for q in range(m):
                a = order[first[s] + q]
                b = order[first[prev_s] + q]
                if arc_lo[a] != arc_lo[b] or arc_hi[a] != arc_hi[b]:
                    same = False
                    break
            if same:
                n_prev = count - prev_first
                for q in range(n_prev):
                    out_slice[count] = used
                    out_angles[0, count] = out_angles[0, prev_first + q]
                    out_angles[1, count] = out_angles[1, prev_first + q]
                    count += 1
                prev_first = count - n_prev
                prev_s = s
                stats[0] += prev_integral * dz
                stats[1] += prev_area * dz
                used += 1
                continue
        prev_s = s
        prev_r = r
        prev_first = count
        prev_integral = prev_area = 0.0
        gap = gap_mm / r
        gap_across = gap + _ACROSS_PITCHES * pitch / r
        widen = widen_mm / r
        for q in range(m):
            ra[q] = arc_lo[order[first[s] + q]]
            rb[q] = arc_hi[order[first[s] + q]]
        _sort_pairs(ra, rb, m)
        # Join arcs closer than the gap (angles unwrapped: hi may exceed 2 pi).
        nrun = 0
        for q in range(m):
            if nrun > 0 and _joins(rb[nrun - 1], ra[q], gap, gap_across, boundary):
                rb[nrun - 1] = max(rb[nrun - 1], rb[q])
            else:
                ra[nrun] = ra[q]
                rb[nrun] = rb[q]
                nrun += 1
        lo_run = 0
        while lo_run < nrun - 1 and _joins(
            rb[nrun - 1], ra[lo_run] + TWO_PI, gap, gap_across, boundary
        ):
            # The first runs continue the last one across phi = 0 (it may reach past several).
            rb[nrun - 1] = max(rb[nrun - 1], rb[lo_run] + TWO_PI)
            lo_run += 1
        npieces = 0
        for q in range(lo_run, nrun):
            a = ra[q] - widen
            b = rb[q] + widen
            if b - a + gap >= TWO_PI:
                a = 0.0
                b = TWO_PI
            npieces = _emit(a, b, pa, pb, npieces)
        _sort_pairs(pa, pb, npieces)
        merged = 0
        for q in range(npieces):
            if merged > 0 and pa[q] <= pb[merged - 1]:
                pb[merged - 1] = max(pb[merged - 1], pb[q])
            else:
                pa[merged] = pa[q]
                pb[merged] = pb[q]
                merged += 1
        for q in range(merged):
            a = pa[q]
            b = pb[q]
            out_slice[count] = used
            out_angles[0, count] = a
            out_angles[1, count] = b
            count += 1
            integral, peak = _positive_sine(a, b)
            prev_integral += integral * sin_kappa
            prev_area += b - a
            stats[2] = max(stats[2], peak * sin_kappa)
        stats[0] += prev_integral * dz
        stats[1] += prev_area * dz
        used += 1
    stats[3] = used
    stats[4] = count


@kernel
def _path(
    prm,
    ints,
    tips,
    fz,
    cycle_s,
    state,
    prev_tip,
    old_tip,
    z_count,
    z_start,
    z_block,
    z_rows,
    z_heap_top,
    x_count,
    x_start,
    x_block,
    x_rows,
    x_heap_top,
    y_count,
    y_start,
    y_block,
    y_rows,
    y_heap_top,
    arc_slice,
    arc_lo,
    arc_hi,
    table,
    acc,
    widen_mm,
    first,
    order,
    ra,
    rb,
    pa,
    pb,
    slices,
    iv_slice,
    iv_angles,
    stats,
    out,
    slice_offsets,
    out_slices,
    interval_offsets,
    out_interval_slice,
    out_intervals,
):
    """Removal (:func:`cnctwin.geometry.removal._cut`) then engagement (:func:`_engage`) at
    every tip (``tips``, (n, 3), grid coordinates, mm) from ``state[0]`` on.

    ``state``: next position, whether its removal is partly done (a resumed call keeps its
    accumulators), whether ``prev_tip`` is the position before the first, whether ``old_tip``
    is the stock's last cut with this cutter. Writes a row of ``out`` per position and its
    slices and intervals at the offsets. Returns 0 when all are done, else the status of a
    full heap or arc buffer or ``_OUT_FULL``, with ``state`` set to resume (the caller grows
    the buffer and calls again).
    """
    n = tips.shape[0]
    px, py, pz = prm[P_PX], prm[P_PY], prm[P_PZ]
    diameter, length = 2.0 * prm[P_R], prm[P_L]
    i = state[0]
    while i < n:
        tx, ty, tz = tips[i, 0], tips[i, 1], tips[i, 2]
        has_prev = i > 0 or state[2] != 0
        if i > 0:
            qx, qy, qz = tips[i - 1, 0], tips[i - 1, 1], tips[i - 1, 2]
        else:
            qx, qy, qz = prev_tip[0], prev_tip[1], prev_tip[2]
        fx, fy = 1.0, 0.0
        feed = math.nan
        if has_prev:
            dx, dy, dz = tx - qx, ty - qy, tz - qz
            feed = math.sqrt(dx * dx + dy * dy + dz * dz) / cycle_s * 60.0
            horizontal = math.sqrt(dx * dx + dy * dy)
            if horizontal > _MIN_FEED_MOVE_MM:
                fx, fy = dx / horizontal, dy / horizontal
        if i > 0:
            reaches = place(prm, ints, tx, ty, tz, qx, qy, qz, True, fx, fy)
        else:
            reaches = place(
                prm, ints, tx, ty, tz, old_tip[0], old_tip[1], old_tip[2], state[3] != 0, fx, fy
            )
        if state[1] == 0:
            reset_accumulators(acc)
        if reaches:
            status = _cut(
                prm, ints, z_count, z_start, z_block, z_rows, z_heap_top, x_count, x_start,
                x_block, x_rows, x_heap_top, y_count, y_start, y_block, y_rows, y_heap_top,
                arc_slice, arc_lo, arc_hi, table, acc,
            )  # fmt: skip
            if status != 0:
                state[0] = i
                state[1] = 1
                return status
            _engage(
                prm, ints, arc_slice, arc_lo, arc_hi, int(acc[A_ARCS]), widen_mm, first, order,
                ra, rb, pa, pb, slices, iv_slice, iv_angles, stats,
            )  # fmt: skip
        else:
            for q in range(5):
                stats[q] = 0.0
        used = int(stats[3])
        count = int(stats[4])
        s0 = slice_offsets[i]
        c0 = interval_offsets[i]
        if s0 + used > out_slices.shape[1] or c0 + count > out_intervals.shape[1]:
            state[0] = i
            state[1] = 1
            return _OUT_FULL
        for q in range(used):
            out_slices[0, s0 + q] = slices[0, q]
            out_slices[1, s0 + q] = slices[1, q]
            out_slices[2, s0 + q] = slices[2, q]
        for q in range(count):
            out_interval_slice[c0 + q] = iv_slice[q]
            out_intervals[0, c0 + q] = iv_angles[0, q]
            out_intervals[1, c0 + q] = iv_angles[1, q]
        slice_offsets[i + 1] = s0 + used
        interval_offsets[i + 1] = c0 + count
        removed = (acc[A_LEN_Z] * px * py + acc[A_LEN_X] * py * pz + acc[A_LEN_Y] * px * pz) / 3.0
        removed = max(removed, 0.0)
        integral, area, peak = stats[0], stats[1], stats[2]
        out[i, _O_CONTACT] = 1.0 if removed > 0.0 else 0.0
        out[i, _O_REMOVED] = removed
        out[i, _O_MRR] = removed / cycle_s
        out[i, _O_AE] = min(max(acc[A_NMAX] - acc[A_NMIN], 0.0), diameter) if removed > 0 else 0.0
        out[i, _O_AP] = min(max(acc[A_ZMAX] - acc[A_ZMIN], 0.0), length) if removed > 0 else 0.0
        out[i, _O_FEED] = feed
        out[i, _O_FDX] = fx
        out[i, _O_FDY] = fy
        out[i, _O_HMEAN] = fz[i] * integral / area if area > 0.0 else 0.0
        out[i, _O_HMAX] = fz[i] * peak
        out[i, _O_BOTTOM] = acc[A_BOTTOM]
        out[i, _O_ABOVE] = acc[A_ABOVE]
        state[1] = 0
        i += 1
    state[0] = n
    return 0
