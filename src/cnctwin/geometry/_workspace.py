"""The Python side of the cutting kernels (private to :mod:`cnctwin.geometry`).

Units: mm (positions in machine coordinates unless named grid coordinates), rad.

What :mod:`cnctwin.geometry.removal` and :mod:`cnctwin.geometry.engagement` share: the work
arrays kept with each stock (:class:`Workspace`), the kernel parameters of a cutter
(:func:`parameters`), the stock's last cut (:func:`last_tip`), the growth of a full buffer
(:func:`grow_for`) and the check of a tool position (:func:`xyz_mm`).
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Sequence
from typing import cast

import numpy as np

from cnctwin.errors import InputError
from cnctwin.geometry._engagement_kernels import EngageWork
from cnctwin.geometry._removal_kernels import (
    ARCS_FULL,
    GAP_PITCHES,
    I_NX,
    I_NY,
    I_NZ,
    N_ACC,
    N_INTS,
    N_PRM,
    N_TABLE,
    P_GAP,
    P_INNER,
    P_L,
    P_PX,
    P_PY,
    P_PZ,
    P_R,
    P_RC,
    P_SLOPE,
    P_SX,
    P_SY,
    P_SZ,
    P_THIN0,
    THIN_ULPS,
    Arcs,
    CutArrays,
    plain,
)
from cnctwin.geometry.cutter import Cutter
from cnctwin.geometry.dexel import AXES, DexelStock

__all__ = ["Workspace", "grow_for", "last_tip", "parameters", "workspace", "xyz_mm"]

_INITIAL_ARCS = 4096


class Workspace:
    """Work arrays of one stock.

    The growable contact-arc buffer (:class:`~cnctwin.geometry._removal_kernels.Arcs`), the
    chord table of one level group, and the engagement's work arrays
    (:class:`~cnctwin.geometry._engagement_kernels.EngageWork`), sized by the arc capacity and
    the grid's z levels.
    """

    __slots__ = (
        "_cut_arrays",
        "_version",
        "_work",
        "acc",
        "arcs",
        "grid",
        "outputs",
        "parameters",
        "table",
        "thin0",
        "work",
    )

    def __init__(self, stock: DexelStock, arcs: int = _INITIAL_ARCS) -> None:
        grid = stock.grid
        px, py, _ = grid.pitch_mm
        #: (origin x, y, z, pitch x, y, z, cells x, y, z, size x, y, z, arc gap), mm.
        self.grid = (
            *grid.origin_mm,
            *grid.pitch_mm,
            *grid.shape,
            *grid.size_mm,
            GAP_PITCHES * max(px, py),
        )
        #: The thinnest cut, mm: a few float32 spacings at the grid's far end.
        self.thin0 = THIN_ULPS * float(np.spacing(np.float32(max(grid.size_mm))))
        self.table = np.zeros((N_TABLE, 2 * max(grid.shape[0], grid.shape[1]) + 4))
        #: The accumulators of the cut in progress (kept while buffers grow).
        self.acc = np.zeros(N_ACC)
        #: The kernel parameters of each cutter used on this stock (see :func:`parameters`).
        self.parameters: dict[Cutter, tuple[np.ndarray, np.ndarray]] = {}
        #: Output buffers of one position (kept by :func:`cnctwin.geometry.engagement.cut`).
        self.outputs: object = None
        self.arcs, self.work = _sized(arcs, grid.shape[2])
        self._work = plain(self.work)
        self._version = -1
        self._cut_arrays: tuple[object, ...] = ()

    def grow_arcs(self) -> None:
        """Double the arc capacity, keeping the arcs written so far."""
        old = self.arcs
        self.arcs, self.work = _sized(2 * old.slice.shape[0], self.work.slices.shape[1] - 1)
        for new, kept in zip(self.arcs, old, strict=True):
            new[: kept.shape[0]] = kept
        self._work = plain(self.work)
        self._version = -1

    def cut_arrays(self, stock: DexelStock) -> tuple[object, ...]:
        """The arrays the removal kernel takes, ``plain(CutArrays)``: the stock's families, the
        arcs and the chord table (cached until either changes)."""
        if self._version != stock.version:
            z, x, y = (stock.family_arrays(axis) for axis in AXES)
            self._cut_arrays = plain(CutArrays(z=z, x=x, y=y, arcs=self.arcs, table=self.table))
            self._version = stock.version
        return self._cut_arrays

    def engage_work(self) -> tuple[object, ...]:
        """The engagement's work arrays, ``plain(EngageWork)``."""
        return self._work


def _sized(arcs: int, nz: int) -> tuple[Arcs, EngageWork]:
    """An arc buffer of ``arcs`` arcs and the engagement's work arrays for it and ``nz``
    levels."""
    return (
        Arcs(
            slice=np.zeros(arcs, dtype=np.int32),
            lo=np.zeros(arcs),
            hi=np.zeros(arcs),
        ),
        EngageWork(
            first=np.zeros(nz + 2, dtype=np.int64),
            order=np.zeros(arcs, dtype=np.int64),
            ra=np.zeros(arcs + 1),
            rb=np.zeros(arcs + 1),
            pa=np.zeros(2 * arcs + 4),
            pb=np.zeros(2 * arcs + 4),
            slices=np.zeros((3, nz + 1)),
            interval_slice=np.zeros(2 * arcs + 1, dtype=np.int64),
            intervals=np.zeros((2, 2 * arcs + 1)),
            stats=np.zeros(5),
        ),
    )


_WORKSPACES: weakref.WeakKeyDictionary[DexelStock, Workspace] = weakref.WeakKeyDictionary()


def workspace(stock: DexelStock) -> Workspace:
    """The stock's :class:`Workspace`."""
    ws = _WORKSPACES.get(stock)
    if ws is None:
        ws = _WORKSPACES[stock] = Workspace(stock)
    return ws


def parameters(ws: Workspace, cutter: Cutter) -> tuple[np.ndarray, np.ndarray]:
    """The kernels' parameter arrays (float64 ``P_*``, int64 ``I_*``) for ``cutter`` on the
    workspace's grid (kept in the workspace); ``place`` fills in a position."""
    cached = ws.parameters.get(cutter)
    if cached is not None:
        return cached
    ox0, oy0, oz0, px, py, pz, nx, ny, nz, sx, sy, sz, gap = ws.grid
    prm = np.zeros(N_PRM)
    prm[P_R] = 0.5 * cutter.diameter_mm
    prm[P_RC] = cutter.corner_radius_mm
    prm[P_L] = cutter.flute_length_mm
    prm[P_PX], prm[P_PY], prm[P_PZ] = px, py, pz
    prm[P_GAP] = gap
    prm[P_THIN0] = ws.thin0
    prm[P_INNER] = cutter.flat_radius_mm
    prm[P_SLOPE] = math.tan(0.5 * cutter.tip_angle_rad)
    prm[P_SX], prm[P_SY], prm[P_SZ] = sx, sy, sz
    ints = np.zeros(N_INTS, dtype=np.int64)
    ints[I_NX], ints[I_NY], ints[I_NZ] = nx, ny, nz
    ws.parameters[cutter] = (prm, ints)
    return prm, ints


def last_tip(stock: DexelStock, cutter: Cutter) -> tuple[float, float, float] | None:
    """Tip (grid coordinates, mm) of the stock's last cut if ``cutter`` made it, else None."""
    last = stock.last_cut
    if last is not None and (last[0] is cutter or last[0] == cutter):
        return last[1]
    return None


def grow_for(status: int, stock: DexelStock, ws: Workspace) -> None:
    """Make room after a kernel stopped with ``status`` (a full heap or arc buffer)."""
    if status == ARCS_FULL:
        ws.grow_arcs()
    else:
        stock.grow_heap(AXES[status // 10])


def xyz_mm(value: object, name: str) -> tuple[float, float, float]:
    """Three finite floats (x, y, z) from a sequence or array.

    Raises
    ------
    InputError
        When ``value`` is not three finite numbers; the message names ``name``.
    """
    try:
        # An array's values as Python numbers (faster to unpack than numpy scalars).
        u, v, w = (
            value.tolist() if isinstance(value, np.ndarray) else cast("Sequence[float]", value)
        )
        x, y, z = float(u), float(v), float(w)
    except (TypeError, ValueError):
        raise InputError(f"{name}={value!r}; give three finite numbers (x, y, z) mm") from None
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        raise InputError(f"{name}={value!r}; give three finite numbers (x, y, z) mm")
    return x, y, z
