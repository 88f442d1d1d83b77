"""Material removal: subtract the cutter's envelope at one tool position from a tri-dexel stock.

Units: mm (names end in ``_mm``), mm^3, rad.

Method
------
The discrete-position method of Heide 2025 (Sec. 2.2, after Pape): at every sampled tool-tip
position the cutting envelope (:class:`~cnctwin.geometry.cutter.Cutter`, a solid of revolution
about +z) is subtracted from every ray it crosses; the swept volume between positions is *not*
modelled, so a step longer than the dexel pitch leaves the scallops of Heide 2025's Fig. 7a.

Per ray the envelope is one interval, in closed form: along a ``z`` ray at horizontal distance
``d`` from the axis it is ``[tip + zmin(d), tip + L]``; along an ``x`` (or ``y``) ray at height
``z`` it is the chord ``c +- sqrt(r(z - tip)^2 - dv^2)`` of the local disc. The removed volume of
a family is the sum of the removed lengths times the ray's cell area, computed from the stored
float32 values, so the sum of removed volumes equals the stock's loss to rounding of the sum.

When the stock's previous cut was made with the same cutter, its envelope is already empty, so
only the part of the new envelope outside the previous one is subtracted (at most two pieces per
ray): the result is the same, the cost proportional to the new material instead of the tool's
footprint.

Contact record
--------------
Every end of a removed piece that is a point of the *new* envelope's surface lying strictly
inside material is a contact point of the cutting edges with the workpiece. Along ``x`` and
``y`` rays these points lie on the slice's circle. Each row family records the points within 45
degrees of its rays' direction, where consecutive rows' crossings are at most ``sqrt(2)``
pitches apart (the other family covers the rest as densely); contact points of neighbouring
rows join into one arc (up to ``GAP_PITCHES`` pitches apart), so that an angle is computed only
where an arc starts or ends. Corner contacts of ball and bull-nose tools, seen by the ``z``
rays, are point arcs. Arcs are recorded per axial slice (one per ``z`` level of the grid) as
angles ``phi`` in the feed frame of :mod:`cnctwin.geometry.engagement`, which merges them into
intervals. Contacts of the flat bottom face of a flat or bull-nose end mill are flagged instead
when the tool moves down, and so is material at the top of the fluted length.

Thin material
-------------
Discrete positions a step ``s`` apart leave cusps ``s^2 / (8 r)`` high on every wall a slice of
radius ``r`` cuts (two circles ``s`` apart meet that far inside their radius). A later pass
along such a wall (the next layer of a pocket, a spring pass) removes those cusp tips, which
are artefacts of the sampling, not chips: as contacts they would add arcs at ``phi = 0`` and
``pi`` on every slice up to the wall's top, and ``ap`` would jump to the wall's height. So a
removed piece is a *cut* only if it reaches at least ``THIN_CUSPS s^2 / (8 r)`` inside the new
envelope (``s`` the horizontal step from the previous cut with the same cutter), and at least a
few float32 spacings of the grid: along ``x`` and ``y`` rays the depth inside the slice's circle
of the piece's point nearest the axis; along ``z`` rays both the piece's length and the depth of
the ray inside the envelope's radius at the piece's top. Only cuts give the extents (``ae``,
``ap``), the shank flag and the ``z`` rays' corner contacts; a run of neighbouring rows' contact
points is a contact arc if any of its pieces is a cut. Material thin all along a wall thus makes
no contact, while the thin edge of a real contact (the sides of a slot, where the new material
is ``s sin(phi)`` thick; the wedge where the tool leaves the material) keeps it. With
``THIN_CUSPS = 2`` a wall left with steps up to ``sqrt(2) s`` is retraced without contact;
coarser earlier steps leave cusps that still count. The removed volume counts every piece.

Performance
-----------
Rays of consecutive levels whose new and previous disc radii agree (the cylinder of the tool)
share one table of operations (ray row, piece, and what the contact bookkeeping needs of the
row), so the per-ray work is the subtraction itself, through
:func:`~cnctwin.geometry._dexel_kernels.trim_interval` (the common case, a trimmed end, first).
The kernels (:mod:`cnctwin.geometry._removal_kernels`) run without numba's reference counting
(see its ``kernel``) and cut the row families before the z rays, whose crescent is new to the
cache at every step. A step costs about one operation per ray whose material changes: along x
and y one or two per row the tool's silhouette crosses at every level, ``rho^2`` per mm^2 of
silhouette (Boess et al., cited by Heide 2025, Eq. 1), about 7 ns each; along z the rays of
the new crescent only.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from cnctwin.geometry._removal_kernels import (
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
    DONE,
    GAP_PITCHES,
    I_K0,
    I_NSLICES,
    N_ACC,
    P_CX,
    P_CY,
    P_TZ,
    THIN_CUSPS,
    cut,
    place,
    reset_accumulators,
)
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

__all__ = ["GAP_PITCHES", "THIN_CUSPS", "ContactRecord", "Removal", "remove"]


class ContactRecord(NamedTuple):
    """Where the envelope met material in one cut.

    Attributes
    ----------
    tip_grid_mm
        Tool tip in grid coordinates (relative to the grid origin), mm.
    feed_dir
        Unit feed direction (x, y) of the angle frame.
    first_level
        Grid z level of slice 0 (the lowest level at or above the tip).
    n_slices
        Slices: grid z levels inside the fluted length and the grid.
    arc_slice, arc_lo_rad, arc_hi_rad
        (q,) contact arcs: slice, and angles ``lo`` in [0, 2 pi), ``hi`` in ``[lo, lo + pi]``
        (rad; ``hi`` may exceed 2 pi when the arc crosses phi = 0), in no particular order.
    n_extent_mm
        (lowest, highest) coordinate of removed material along the feed normal ``n`` (mm,
        from the tool axis); (inf, -inf) when nothing was removed.
    z_extent_mm
        (lowest, highest) z of removed material, grid coordinates (mm).
    bottom_contact
        The flat bottom face of a flat or bull-nose tool cut material while moving down (a
        plunge or a ramp; the first cut of a stock counts as moving down).
    above_flutes
        Material at the top of the fluted length inside the tool's footprint: the shank or
        holder would hit it.
    """

    tip_grid_mm: tuple[float, float, float]
    feed_dir: tuple[float, float]
    first_level: int
    n_slices: int
    arc_slice: np.ndarray
    arc_lo_rad: np.ndarray
    arc_hi_rad: np.ndarray
    n_extent_mm: tuple[float, float]
    z_extent_mm: tuple[float, float]
    bottom_contact: bool
    above_flutes: bool


class Removal(NamedTuple):
    """The result of subtracting one envelope.

    Attributes
    ----------
    removed_volume_mm3
        Removed volume in mm^3, the mean of the three families (as
        :meth:`DexelStock.volume_mm3`), >= 0.
    family_removed_mm3
        Removed volume of the z, x and y families in mm^3.
    contact
        Where the envelope met material.
    """

    removed_volume_mm3: float
    family_removed_mm3: tuple[float, float, float]
    contact: ContactRecord


class _Step(NamedTuple):
    """The kernel inputs of one cut (see :func:`_prepare`)."""

    prm: np.ndarray
    ints: np.ndarray
    acc: np.ndarray
    reaches: bool


def _prepare(
    stock: DexelStock,
    ws: Workspace,
    cutter: Cutter,
    tip_mm: tuple[float, float, float],
    feed_dir: tuple[float, float],
) -> _Step:
    """Kernel parameters for cutting ``stock`` with ``cutter``'s tip at ``tip_mm`` (machine
    coordinates, mm); records the cut as the stock's last."""
    origin = ws.grid[:3]
    tx, ty, tz = tip_mm[0] - origin[0], tip_mm[1] - origin[1], tip_mm[2] - origin[2]
    prm, ints = parameters(ws, cutter)
    old = last_tip(stock, cutter)
    ox, oy, oz = old if old is not None else (0.0, 0.0, 0.0)
    reaches = place(prm, ints, tx, ty, tz, ox, oy, oz, old is not None, feed_dir[0], feed_dir[1])
    acc = np.empty(N_ACC)
    reset_accumulators(acc)
    stock.last_cut = (cutter, (tx, ty, tz))
    return _Step(prm, ints, acc, bool(reaches))


def _removed_volumes_mm3(stock: DexelStock, acc: np.ndarray) -> tuple[float, float, float]:
    """Removed volume of the z, x and y families (mm^3) from a kernel's accumulators."""
    px, py, pz = stock.grid.pitch_mm
    return (
        float(acc[A_LEN_Z]) * px * py,
        float(acc[A_LEN_X]) * py * pz,
        float(acc[A_LEN_Y]) * px * pz,
    )


def remove(
    stock: DexelStock,
    cutter: Cutter,
    position_mm: np.ndarray | tuple[float, float, float],
    feed_dir: tuple[float, float] = (1.0, 0.0),
) -> Removal:
    """Subtract ``cutter``'s envelope with its tip at ``position_mm`` from ``stock``.

    Parameters
    ----------
    stock
        The stock, changed in place.
    cutter
        The cutter; its axis is +z.
    position_mm
        Tool tip (x, y, z) in machine coordinates, mm (``SampleChunk.tcp_mm``).
    feed_dir
        Unit feed direction (x, y) defining the angle frame of the contact record.

    Returns
    -------
    Removal
        Removed volume (mm^3) and the contact record.

    Raises
    ------
    ConfigError
        On a position that is not three finite numbers.

    Notes
    -----
    Discrete-position method (Heide 2025, Sec. 2.2): the envelope at this position only, not the
    volume swept since the last one. :func:`cnctwin.geometry.cut` does this and computes the
    engagement in one call.
    """
    ws = workspace(stock)
    step = _prepare(stock, ws, cutter, xyz_mm(position_mm, "position_mm"), feed_dir)
    while step.reaches:
        status = cut(step.prm, step.ints, ws.cut_arrays(stock), step.acc)
        if status == DONE:
            break
        grow_for(status, stock, ws)
    acc = step.acc
    family = _removed_volumes_mm3(stock, acc)
    n_arcs = int(acc[A_ARCS])
    record = ContactRecord(
        tip_grid_mm=(float(step.prm[P_CX]), float(step.prm[P_CY]), float(step.prm[P_TZ])),
        feed_dir=(float(feed_dir[0]), float(feed_dir[1])),
        first_level=int(step.ints[I_K0]),
        n_slices=int(step.ints[I_NSLICES]),
        arc_slice=ws.arcs.slice[:n_arcs].copy(),
        arc_lo_rad=ws.arcs.lo[:n_arcs].copy(),
        arc_hi_rad=ws.arcs.hi[:n_arcs].copy(),
        n_extent_mm=(float(acc[A_NMIN]), float(acc[A_NMAX])),
        z_extent_mm=(float(acc[A_ZMIN]), float(acc[A_ZMAX])),
        bottom_contact=bool(acc[A_BOTTOM]),
        above_flutes=bool(acc[A_ABOVE]),
    )
    return Removal((family[0] + family[1] + family[2]) / 3.0, family, record)
