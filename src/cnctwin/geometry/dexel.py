"""Tri-dexel stock: material as intervals along rays in x, y and z.

Units: mm for lengths (names end in ``_mm``), mm^2 and mm^3 for areas and volumes, dexels per mm
for densities.

Grid
----
A :class:`DexelGrid` covers an axis-aligned box from ``origin_mm`` with ``shape = (nx, ny, nz)``
cells of pitch ``pitch_mm = (px, py, pz)``; for a box, ``n = round(size * density)`` per axis (at
least 1) and ``pitch = size / n``, so the box is represented exactly and the pitch is within half
a cell of ``1 / density``. Rays run through cell centres, in three families (the multi-dexel model
of Heide 2025, Sec. 2.2, after Boess et al.):

======  ============================  ================  ==================
family  ray along, at                 ray index         cell area
======  ============================  ================  ==================
``z``   z, at (x_i, y_j)              ``j * nx + i``     ``px * py``
``x``   x, at (y_j, z_k)              ``k * ny + j``     ``py * pz``
``y``   y, at (x_i, z_k)              ``k * nx + i``     ``px * pz``
======  ============================  ================  ==================

with ``x_i = (i + 1/2) px`` etc. relative to the origin. Each family alone represents the whole
solid; the stock's volume is the mean of the three families' volumes.

Layout (flat arrays, numba-friendly)
------------------------------------
Each family keeps, per ray, its material as sorted, disjoint, non-empty intervals ``[lo, hi]``
(float32, mm, along the ray, relative to the origin, so that float32 keeps ~1e-5 mm at 200 mm):

* ``rows`` (float32, ``(n_rays * capacity + heap rows, 2)``): interval rows ``(lo, hi)``. The
  first ``n_rays * capacity`` rows are the inline blocks, ``capacity`` rows per ray in ray
  order; the rest is the overflow heap;
* ``count`` (int32, one per ray): number of intervals;
* ``start`` (int32, one per ray): the ray's first row, ``ray * capacity`` while inline;
* ``block`` (int32, one per ray): the capacity of the ray's block;
* ``heap_top`` (int64[1]): the first free row of the heap.

A ray that outgrows its block moves to a new block of twice the capacity at the heap's top (its old
block is left unused). When the heap is full, a kernel stops before touching the ray and reports it;
the Python side copies the rows into an array with a heap four times as large (the first time at
least twice the inline rows) and runs the kernel again (cuts are idempotent). The unused blocks
stay: a ray's unused blocks hold fewer rows than its block in use, since each block doubles the
last. Material is never dropped: a ray holds any number of intervals. One ``rows`` array (not inline
and heap apart) keeps the kernels free of array aliasing, which costs numba a reference count per
access.

Memory is ``n_rays * (8 capacity + 12)`` bytes per family plus the heap, which starts with a
quarter of the inline rows (room for a quarter of the rays to double their capacity before the
first growth, which copies every used row): a 200 x 200 x 50 mm stock at 10 /mm with capacity 2
takes 192 MB (183 MiB; :meth:`DexelStock.estimate_nbytes`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from cnctwin.errors import ConfigError, DataError, InputError
from cnctwin.geometry._dexel_kernels import Family, fill, total_length
from cnctwin.memory import check_memory

__all__ = ["AXES", "Axis", "DexelGrid", "DexelStock"]

logger = logging.getLogger(__name__)

#: A ray family, named by the axis its rays run along.
Axis = Literal["x", "y", "z"]
#: The three families in the order the kernels take them.
AXES: tuple[Axis, Axis, Axis] = ("z", "x", "y")

_AXIS_INDEX = {"x": 0, "y": 1, "z": 2}
# For each family: (ray axis, first transverse axis, second transverse axis), axis indices 0-2.
_FAMILY_AXES = {"z": (2, 0, 1), "x": (0, 1, 2), "y": (1, 0, 2)}
_INITIAL_HEAP_ROWS = 1024
#: A new family's heap holds at least this fraction of its inline rows: room for a quarter of
#: the rays to double their capacity before the first (costly: a copy of every row) growth.
_INITIAL_HEAP_FRACTION = 0.25
_BYTES_PER_RAY_FIXED = 12  # count, start, block (int32 each)
_MAX_ROWS = 2**31 - 1  # rows of one family: ``start`` is int32
#: A full heap grows to this many times its size, and at least to this many times the inline
#: rows: few growths (each copies every used row of the family) over a long cut.
_HEAP_GROWTH = 4
_FIRST_GROWTH_INLINE = 2


@dataclass(frozen=True, slots=True)
class DexelGrid:
    """The cells of a tri-dexel stock.

    Attributes
    ----------
    origin_mm
        Lower corner (x, y, z) of the grid in machine coordinates, mm.
    shape
        Cells ``(nx, ny, nz)``, each >= 1.
    pitch_mm
        Cell size ``(px, py, pz)`` in mm, each > 0.
    """

    origin_mm: tuple[float, float, float]
    shape: tuple[int, int, int]
    pitch_mm: tuple[float, float, float]

    @classmethod
    def from_box(
        cls,
        min_mm: Sequence[float],
        max_mm: Sequence[float],
        density_per_mm: float,
    ) -> DexelGrid:
        """The grid of a box from ``min_mm`` to ``max_mm`` (mm) at ``density_per_mm`` rays per mm.

        Raises
        ------
        InputError
            On a box that is not strictly ordered or not finite, or a density that is not
            finite and > 0.
        """
        lo = _vec3(min_mm, "min_mm")
        hi = _vec3(max_mm, "max_mm")
        if not (math.isfinite(density_per_mm) and density_per_mm > 0.0):
            raise InputError(
                f"density_per_mm={density_per_mm!r}; give a finite dexel density > 0 per mm"
            )
        shape = []
        pitch = []
        for axis, a, b in zip("xyz", lo, hi, strict=True):
            if not b > a:
                raise InputError(f"box {axis} from {a} to {b} mm; max_mm must exceed min_mm")
            n = max(1, round((b - a) * density_per_mm))
            shape.append(int(n))
            pitch.append((b - a) / n)
        return cls(lo, (shape[0], shape[1], shape[2]), (pitch[0], pitch[1], pitch[2]))

    @property
    def size_mm(self) -> tuple[float, float, float]:
        """Extent of the grid along x, y, z in mm."""
        return (
            self.shape[0] * self.pitch_mm[0],
            self.shape[1] * self.pitch_mm[1],
            self.shape[2] * self.pitch_mm[2],
        )

    def n_rays(self, axis: Axis) -> int:
        """Number of rays in the family along ``axis``."""
        _, a, b = _family_axes(axis)
        return self.shape[a] * self.shape[b]

    def cell_area_mm2(self, axis: Axis) -> float:
        """Cross-section in mm^2 that one ray of the family along ``axis`` stands for."""
        _, a, b = _family_axes(axis)
        return self.pitch_mm[a] * self.pitch_mm[b]

    def ray_coordinates_mm(self, axis: Axis) -> np.ndarray:
        """Transverse machine coordinates (mm) of every ray of a family, in ray-index order.

        Returns
        -------
        numpy.ndarray
            ``(n_rays, 2)``: for ``z`` rays (x, y), for ``x`` rays (y, z), for ``y`` rays (x, z).
            This is what a ray caster (an STL loader) needs to fill :meth:`DexelStock.load`.
        """
        _, a, b = _family_axes(axis)
        ua = self.origin_mm[a] + (np.arange(self.shape[a]) + 0.5) * self.pitch_mm[a]
        ub = self.origin_mm[b] + (np.arange(self.shape[b]) + 0.5) * self.pitch_mm[b]
        grid_a, grid_b = np.meshgrid(ua, ub, indexing="xy")
        return np.column_stack([grid_a.ravel(), grid_b.ravel()])


class _Family:
    """The arrays of one ray family (see the module notes for the layout)."""

    __slots__ = ("block", "count", "heap_top", "rows", "start")

    def __init__(self, n_rays: int, capacity: int, heap_rows: int = 0) -> None:
        heap_rows = max(heap_rows, _initial_heap_rows(n_rays, capacity))
        self.count = np.zeros(n_rays, dtype=np.int32)
        self.start = np.arange(0, n_rays * capacity, capacity, dtype=np.int32)
        self.block = np.full(n_rays, capacity, dtype=np.int32)
        self.rows = np.zeros((n_rays * capacity + heap_rows, 2), dtype=np.float32)
        self.heap_top = np.array([n_rays * capacity], dtype=np.int64)

    def arrays(self) -> Family:
        """The arrays as the kernels take them."""
        return Family(
            count=self.count,
            start=self.start,
            block=self.block,
            rows=self.rows,
            heap_top=self.heap_top,
        )

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in self.arrays())

    def grown_heap_rows(self, capacity: int) -> int:
        """Heap rows after the next :meth:`grow_heap`."""
        return max(
            _HEAP_GROWTH * (self.rows.shape[0] - self.count.shape[0] * capacity),
            _FIRST_GROWTH_INLINE * self.count.shape[0] * capacity,
            _INITIAL_HEAP_ROWS,
        )

    def grow_heap(self, capacity: int) -> None:
        """Copy the rows into an array with a heap :data:`_HEAP_GROWTH` times as large (the
        first time at least :data:`_FIRST_GROWTH_INLINE` times the inline rows).

        Dead blocks (those rays left for larger ones) are kept: a ray's dead blocks have
        fewer rows than its live one (each block doubles), and a plain copy of the used rows
        is several times faster than compacting the live blocks ray by ray.
        """
        heap_base = self.count.shape[0] * capacity
        used = int(self.heap_top[0])
        heap_rows = self.grown_heap_rows(capacity)
        rows = np.empty((heap_base + heap_rows, 2), dtype=np.float32)
        rows[:used] = self.rows[:used]
        self.rows = rows
        logger.debug("dexel heap grown to %d rows (%d used)", heap_rows, used - heap_base)


class DexelStock:
    """A tri-dexel stock: the workpiece's material as intervals along rays in x, y and z.

    Parameters
    ----------
    grid
        The cells (see :class:`DexelGrid`).
    capacity
        Intervals each ray stores inline, >= 1 (more go to the overflow heap).

    Notes
    -----
    A new stock holds no material: fill it with :meth:`box` or :meth:`load`. Cut it with
    :func:`cnctwin.geometry.cut` (or :func:`cnctwin.geometry.removal.remove`).
    """

    def __init__(self, grid: DexelGrid, capacity: int = 2) -> None:
        if isinstance(capacity, bool) or not isinstance(capacity, int) or capacity < 1:
            raise InputError(f"capacity={capacity!r}; give an integer >= 1 intervals per ray")
        _check_size(grid, capacity)
        self.grid = grid
        self.capacity = capacity
        self._families = {axis: _Family(grid.n_rays(axis), capacity) for axis in AXES}
        #: Identity of the last cut (cutter, tip position in grid coordinates, mm), which lets
        #: the next cut skip the part of the envelope that the last one emptied.
        self.last_cut: tuple[object, tuple[float, float, float]] | None = None
        #: Incremented whenever a family's arrays are replaced (see :meth:`family_arrays`).
        self.version = 0

    @classmethod
    def box(
        cls,
        min_mm: Sequence[float],
        max_mm: Sequence[float],
        density_per_mm: float,
        capacity: int = 2,
    ) -> DexelStock:
        """A full block from ``min_mm`` to ``max_mm`` (machine coordinates, mm).

        Parameters
        ----------
        min_mm, max_mm
            Opposite corners in mm.
        density_per_mm
            Rays per mm along each axis (Heide 2025's dexel density rho_xyz), > 0.
        capacity
            Intervals stored inline per ray, >= 1.
        """
        stock = cls(DexelGrid.from_box(min_mm, max_mm, density_per_mm), capacity)
        for axis in AXES:
            ray, _, _ = _family_axes(axis)
            fam = stock._families[axis]
            fam.count[:] = 1
            inline = fam.rows[: fam.count.shape[0] * capacity].reshape(-1, capacity, 2)
            inline[:, 0, 0] = 0.0
            inline[:, 0, 1] = np.float32(stock.grid.size_mm[ray])
        return stock

    @staticmethod
    def estimate_nbytes(
        min_mm: Sequence[float],
        max_mm: Sequence[float],
        density_per_mm: float,
        capacity: int = 2,
    ) -> int:
        """Bytes a fresh :meth:`box` stock takes: ``n_rays (8 capacity + 12)`` per family plus
        the initial heap (8 bytes a row, a quarter of the inline rows, at least 1024)."""
        return _grid_nbytes(DexelGrid.from_box(min_mm, max_mm, density_per_mm), capacity)

    @property
    def nbytes(self) -> int:
        """Bytes held by the stock's arrays."""
        return sum(fam.nbytes for fam in self._families.values())

    def family_arrays(self, axis: Axis) -> Family:
        """The arrays of a family as the kernels take them (see the module notes): count,
        start, block, rows, heap_top (a NamedTuple of these fields). They are replaced (and
        :attr:`version` changes) when the heap grows or the family is loaded."""
        return self._families[_check_axis(axis)].arrays()

    def grow_heap(self, axis: Axis) -> None:
        """Enlarge a family's overflow heap (called when a kernel reports it full).

        Raises
        ------
        ConfigError
            When the grown stock would exceed the memory limit (:mod:`cnctwin.memory`)
            or the family's int32 row index: the cut has split the rays into more intervals
            than fit.
        """
        fam = self._families[_check_axis(axis)]
        rows = fam.count.shape[0] * self.capacity + fam.grown_heap_rows(self.capacity)
        what = f"growing the {axis} rays' heap of a dexel stock to {rows:.3g} rows"
        advice = "use a lower density or a smaller stock (the cut splits its rays)"
        if rows > _MAX_ROWS:
            raise ConfigError(f"{what}, more than one family can index ({_MAX_ROWS}): {advice}")
        check_memory(what, self.nbytes + 8.0 * (rows - fam.rows.shape[0]), lambda _: advice)
        fam.grow_heap(self.capacity)
        self.version += 1

    def load(self, axis: Axis, counts: np.ndarray, intervals_mm: np.ndarray) -> None:
        """Replace a family's material.

        Parameters
        ----------
        axis
            The family: ``"x"``, ``"y"`` or ``"z"``.
        counts
            ``(n_rays,)`` number of intervals of each ray, in ray-index order (see
            :meth:`DexelGrid.ray_coordinates_mm`), each >= 0.
        intervals_mm
            ``(sum(counts), 2)`` intervals ``(start, end)`` along the ray in machine coordinates
            (mm), ray after ray, each ray's sorted, disjoint (``start`` > the previous ``end``)
            and non-empty (``start < end``). Parts outside the grid are clipped away.

        Raises
        ------
        DataError
            On arrays of the wrong shape or intervals that are not sorted, disjoint, non-empty.
        """
        axis = _check_axis(axis)
        n_rays = self.grid.n_rays(axis)
        counts = np.asarray(counts)
        iv = np.asarray(intervals_mm, dtype=np.float64)
        if counts.shape != (n_rays,) or (counts.size and counts.min() < 0):
            raise DataError(
                f"counts of shape {counts.shape}; give {n_rays} counts >= 0, one per {axis} ray"
            )
        total = int(counts.sum())
        if iv.shape != (total, 2):
            raise DataError(f"intervals_mm of shape {iv.shape}; give ({total}, 2) for {axis} rays")
        if not np.all(np.isfinite(iv)) or np.any(iv[:, 0] >= iv[:, 1]):
            raise DataError(f"{axis} intervals must be finite with start < end")
        first = np.cumsum(counts) - counts
        follows = np.ones(total, dtype=bool)
        follows[first[counts > 0]] = False
        if np.any(iv[1:, 0][follows[1:]] <= iv[:-1, 1][follows[1:]]):
            raise DataError(f"{axis} intervals of a ray must be sorted and disjoint")
        ray, _, _ = _family_axes(axis)
        local = np.clip(iv - self.grid.origin_mm[ray], 0.0, self.grid.size_mm[ray]).astype(
            np.float32
        )
        keep = local[:, 0] < local[:, 1]
        if not keep.all():  # drop the intervals that lie outside the grid
            ray_of = np.repeat(np.arange(n_rays), counts)
            counts = np.bincount(ray_of[keep], minlength=n_rays)
            local = local[keep]
        heap_rows = _heap_rows_needed(counts.astype(np.int64), self.capacity)
        fam = _Family(n_rays, self.capacity, 2 * heap_rows)
        fill(counts.astype(np.int32), local, self.capacity, tuple(fam.arrays()))
        self._families[axis] = fam
        self.last_cut = None
        self.version += 1

    def volume_mm3(self, axis: Axis | None = None) -> float:
        """Material volume in mm^3: of one family, or (``None``) the mean of the three."""
        if axis is None:
            return sum(self.volume_mm3(a) for a in AXES) / 3.0
        fam = self._families[_check_axis(axis)]
        length = total_length(tuple(fam.arrays()))
        return float(length) * self.grid.cell_area_mm2(axis)

    def ray_intervals_mm(self, axis: Axis, u: int, v: int) -> np.ndarray:
        """The intervals ``(n, 2)`` of one ray in machine coordinates (mm).

        ``(u, v)`` are the ray's cell indices on its transverse axes in x, y, z order:
        ``(i, j)`` for a ``z`` ray, ``(j, k)`` for ``x``, ``(i, k)`` for ``y``.
        """
        axis = _check_axis(axis)
        ray, a, b = _family_axes(axis)
        if not (0 <= u < self.grid.shape[a] and 0 <= v < self.grid.shape[b]):
            raise InputError(
                f"ray ({u}, {v}) of the {axis} family; give indices below "
                f"({self.grid.shape[a]}, {self.grid.shape[b]})"
            )
        index = v * self.grid.shape[a] + u
        fam = self._families[axis]
        first = int(fam.start[index])
        rows = fam.rows[first : first + int(fam.count[index])]
        return rows.astype(np.float64) + self.grid.origin_mm[ray]

    def interval_counts(self, axis: Axis) -> np.ndarray:
        """Number of intervals of every ray of a family (a copy, ray-index order)."""
        return self._families[_check_axis(axis)].count.copy()

    def overflow_rays(self, axis: Axis) -> int:
        """How many rays of a family keep their intervals in the overflow heap."""
        fam = self._families[_check_axis(axis)]
        return int(np.count_nonzero(fam.start >= fam.count.shape[0] * self.capacity))


def _vec3(value: Sequence[float], name: str) -> tuple[float, float, float]:
    try:
        vec = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise InputError(f"{name}={value!r}; give three numbers (x, y, z) in mm") from None
    if len(vec) != 3 or not all(math.isfinite(v) for v in vec):
        raise InputError(f"{name}={value!r}; give three finite numbers (x, y, z) in mm")
    return (vec[0], vec[1], vec[2])


def _check_axis(axis: str) -> Axis:
    if axis not in _FAMILY_AXES:
        raise InputError(f"axis={axis!r}; give 'x', 'y' or 'z'")
    return axis  # type: ignore[return-value]


def _family_axes(axis: str) -> tuple[int, int, int]:
    return _FAMILY_AXES[_check_axis(axis)]


def _grid_nbytes(grid: DexelGrid, capacity: int) -> int:
    """Bytes of a fresh stock on ``grid`` (see :meth:`DexelStock.estimate_nbytes`)."""
    per_ray = 8 * capacity + _BYTES_PER_RAY_FIXED
    return sum(
        grid.n_rays(axis) * per_ray + _initial_heap_rows(grid.n_rays(axis), capacity) * 8 + 8
        for axis in AXES
    )


def _check_size(grid: DexelGrid, capacity: int) -> None:
    """Refuse a grid whose stock exceeds the memory limit or a family's int32 row index.

    Raises
    ------
    ConfigError
        Naming the grid, its rays and the largest density that fits.
    """
    rays = sum(grid.n_rays(axis) for axis in AXES)
    size = " x ".join(f"{s:g}" for s in grid.size_mm)
    density = 1.0 / max(grid.pitch_mm)
    what = f"a dexel stock of {size} mm at {density:.3g} /mm is {rays:.3g} rays"

    def remedy(fraction: float) -> str:
        return (
            f"at most {rays * fraction:.3g} rays fit: use a density <= "
            f"{density * math.sqrt(fraction):.3g} /mm or a smaller stock"
        )

    check_memory(what, float(_grid_nbytes(grid, capacity)), remedy)
    rows = max(
        grid.n_rays(axis) * capacity + _initial_heap_rows(grid.n_rays(axis), capacity)
        for axis in AXES
    )
    if rows > _MAX_ROWS:
        raise ConfigError(
            f"{what}, more than one family can index ({_MAX_ROWS} rows): "
            + remedy(_MAX_ROWS / rows)
        )


def _initial_heap_rows(n_rays: int, capacity: int) -> int:
    return max(_INITIAL_HEAP_ROWS, int(_INITIAL_HEAP_FRACTION * n_rays * capacity))


def _heap_rows_needed(counts: np.ndarray, capacity: int) -> int:
    over = counts[counts > capacity]
    if over.size == 0:
        return 0
    caps = np.maximum(2 * capacity, 2 ** np.ceil(np.log2(over)).astype(np.int64))
    return int(caps.sum())
