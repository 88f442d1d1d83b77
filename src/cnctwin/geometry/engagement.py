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
p_z/2]``, the lowest one down to the tip when the tip lies less than a pitch below its level;
a tip further down is below the grid's lowest level and that slice ends at the grid's bottom
(:func:`slice_low_mm`).

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

from cnctwin.errors import InputError
from cnctwin.geometry._engagement_kernels import (
    N_OUT,
    O_ABOVE,
    O_AE,
    O_AP,
    O_BOTTOM,
    O_CONTACT,
    O_FDX,
    O_FDY,
    O_FEED,
    O_HMAX,
    O_HMEAN,
    O_MRR,
    O_REMOVED,
    OUT_FULL,
    PathOutputs,
    path,
)
from cnctwin.geometry._removal_kernels import DONE, SLICE_TIP_PITCHES, plain
from cnctwin.geometry._workspace import (
    Workspace,
    grow_for,
    last_tip,
    parameters,
    workspace,
    xyz_mm,
)
from cnctwin.geometry.cutter import Cutter
from cnctwin.geometry.dexel import DexelStock

__all__ = ["Engagement", "EngagementPath", "cut", "cut_path", "slice_low_mm"]

_WIDEN_PITCHES = 0.5  # widen intervals by this many pitches (over r) on each side


def slice_low_mm(slice_height_mm: np.ndarray, pitch_z_mm: float) -> np.ndarray:
    """Lowest height above the tip (mm) of the tool that each slice stands for, from the
    slices' heights above the tip (mm, :attr:`Engagement.slice_height_mm`) and the grid's z
    pitch (mm, > 0): 0 (down to the tip) for a slice less than a pitch above the tip, else
    half a pitch below its height (module notes, "Intervals"). A slice's top is this plus its
    ``slice_dz_mm``."""
    h = np.asarray(slice_height_mm, dtype=np.float64)
    return np.where(h < SLICE_TIP_PITCHES * pitch_z_mm, 0.0, h - 0.5 * pitch_z_mm)


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
    InputError
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
    arrays = outputs.arrays
    m, q = int(arrays.slice_offsets[1]), int(arrays.interval_offsets[1])
    row = arrays.out[0].tolist()
    slices = arrays.slices[:, :m].copy()
    angles = arrays.intervals[:, :q].copy()
    return Engagement(
        contact=row[O_CONTACT] > 0.0,
        removed_volume_mm3=row[O_REMOVED],
        mrr_mm3_s=row[O_MRR],
        ae_mm=row[O_AE],
        ap_mm=row[O_AP],
        feed_mm_min=row[O_FEED],
        feed_dir=(row[O_FDX], row[O_FDY]),
        h_mean_mm=row[O_HMEAN],
        h_max_mm=row[O_HMAX],
        slice_height_mm=slices[0],
        slice_dz_mm=slices[1],
        slice_radius_mm=slices[2],
        interval_slice=arrays.interval_slice[:q].copy(),
        interval_start_rad=angles[0],
        interval_end_rad=angles[1],
        bottom_contact=row[O_BOTTOM] > 0.0,
        above_flutes=row[O_ABOVE] > 0.0,
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
    InputError
        On positions that are not an (n, 3) array of finite numbers, feeds per tooth that are
        negative, not finite or of another length, or a cycle time that is not finite and > 0.
    """
    tips = np.asarray(positions_mm, dtype=np.float64)
    if tips.ndim != 2 or tips.shape[1] != 3 or not np.all(np.isfinite(tips)):
        raise InputError(
            f"positions_mm of shape {tips.shape}; give an (n, 3) array of finite tool tips, mm"
        )
    fz = np.broadcast_to(np.asarray(feed_per_tooth_mm, dtype=np.float64), (len(tips),))
    if fz.size and not (np.all(np.isfinite(fz)) and fz.min() >= 0.0):
        raise InputError("feed_per_tooth_mm: give finite feeds per tooth >= 0 mm")
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
    arrays = outputs.arrays
    out = arrays.out
    m, q = int(arrays.slice_offsets[-1]), int(arrays.interval_offsets[-1])
    return EngagementPath(
        contact=out[:, O_CONTACT] > 0.0,
        removed_volume_mm3=out[:, O_REMOVED],
        mrr_mm3_s=out[:, O_MRR],
        ae_mm=out[:, O_AE],
        ap_mm=out[:, O_AP],
        feed_mm_min=out[:, O_FEED],
        feed_dir=out[:, O_FDX : O_FDY + 1],
        h_mean_mm=out[:, O_HMEAN],
        h_max_mm=out[:, O_HMAX],
        bottom_contact=out[:, O_BOTTOM] > 0.0,
        above_flutes=out[:, O_ABOVE] > 0.0,
        slice_offsets=arrays.slice_offsets,
        slice_height_mm=arrays.slices[0, :m],
        slice_dz_mm=arrays.slices[1, :m],
        slice_radius_mm=arrays.slices[2, :m],
        interval_offsets=arrays.interval_offsets,
        interval_slice=arrays.interval_slice[:q],
        interval_start_rad=arrays.intervals[0, :q],
        interval_end_rad=arrays.intervals[1, :q],
    )


class _Outputs:
    """The output buffers of :func:`~cnctwin.geometry._engagement_kernels.path` for ``n``
    positions (:class:`~cnctwin.geometry._engagement_kernels.PathOutputs`: a row of ``N_OUT``
    values per position, and the slices and intervals of all positions one after the other);
    and its small input arrays (kept with the buffers of :func:`cut`, which fills them at every
    call instead of allocating them: a few microseconds a position)."""

    __slots__ = ("arrays", "fz", "kernel_arrays", "old_tip", "prev", "state", "tip")

    def __init__(self, n: int, ws: Workspace) -> None:
        # The inputs of one position (cut) and the small arrays of every call (see _run).
        self.tip = np.zeros((1, 3))
        self.fz = np.zeros(1)
        self.state = np.zeros(4, dtype=np.int64)
        self.prev = np.zeros(3)
        self.old_tip = np.zeros(3)
        # Room for one position's most slices and intervals, and for four of each a position.
        n_slices = max(4 * n, ws.work.slices.shape[1])
        n_intervals = max(4 * n, ws.work.interval_slice.shape[0])
        self._set(
            PathOutputs(
                out=np.empty((n, N_OUT)),
                slice_offsets=np.zeros(n + 1, dtype=np.int64),
                slices=np.empty((3, n_slices)),
                interval_offsets=np.zeros(n + 1, dtype=np.int64),
                interval_slice=np.empty(n_intervals, dtype=np.int64),
                intervals=np.empty((2, n_intervals)),
            )
        )

    def _set(self, arrays: PathOutputs) -> None:
        self.arrays = arrays
        #: ``plain(arrays)``, as the kernel takes them.
        self.kernel_arrays = plain(arrays)

    def grow(self) -> None:
        """Double the room for slices and intervals, keeping what is written."""
        a = self.arrays
        self._set(
            a._replace(
                slices=_grown(a.slices),
                interval_slice=_grown(a.interval_slice),
                intervals=_grown(a.intervals),
            )
        )


def _check_feed_and_cycle(feed_per_tooth_mm: float, cycle_s: float) -> None:
    if not (math.isfinite(feed_per_tooth_mm) and feed_per_tooth_mm >= 0.0):
        raise InputError(
            f"feed_per_tooth_mm={feed_per_tooth_mm!r}; give a finite feed per tooth >= 0 mm"
        )
    if not (math.isfinite(cycle_s) and cycle_s > 0.0):
        raise InputError(f"cycle_s={cycle_s!r}; give a finite cycle time > 0 s")


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
    """Cut at every tip (grid coordinates, mm) with the path kernel into ``outputs``, growing
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
        status = path(
            prm, ints, tips, fz, cycle_s, state, prev, old_tip, ws.cut_arrays(stock), ws.acc,
            widen_mm, ws.engage_work(), outputs.kernel_arrays,
        )  # fmt: skip
        if status == DONE:
            break
        if status == OUT_FULL:
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
