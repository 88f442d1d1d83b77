"""The tri-dexel stock: grid, layout, overflow heap, memory, and interval subtraction."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnctwin.errors import DataError, InputError
from cnctwin.geometry import DexelGrid, DexelStock
from cnctwin.geometry._dexel_kernels import subtract_interval

GIB = 2**30


def test_box_grid_represents_the_box_exactly() -> None:
    grid = DexelGrid.from_box((-5.0, 0.0, -10.0), (15.0, 7.25, 0.0), 4.0)
    assert grid.shape == (80, 29, 40)
    assert grid.size_mm == pytest.approx((20.0, 7.25, 10.0))
    assert grid.pitch_mm[1] == pytest.approx(0.25)
    stock = DexelStock.box((-5.0, 0.0, -10.0), (15.0, 7.25, 0.0), 4.0)
    for axis in ("x", "y", "z"):
        assert stock.volume_mm3(axis) == pytest.approx(20.0 * 7.25 * 10.0, rel=1e-6)
    np.testing.assert_allclose(stock.ray_intervals_mm("z", 3, 4), [[-10.0, 0.0]])
    np.testing.assert_allclose(stock.ray_intervals_mm("x", 0, 0), [[-5.0, 15.0]])
    coords = grid.ray_coordinates_mm("y")
    assert coords.shape == (80 * 40, 2)
    np.testing.assert_allclose(coords[81], [-5.0 + 1.5 * 0.25, -10.0 + 1.5 * 0.25])


def test_invalid_boxes_are_rejected() -> None:
    with pytest.raises(InputError, match="max_mm must exceed min_mm"):
        DexelGrid.from_box((0, 0, 0), (1, 0, 1), 10)
    with pytest.raises(InputError, match="density_per_mm=0"):
        DexelGrid.from_box((0, 0, 0), (1, 1, 1), 0)
    with pytest.raises(InputError, match="capacity=0"):
        DexelStock(DexelGrid.from_box((0, 0, 0), (1, 1, 1), 1), capacity=0)
    with pytest.raises(InputError, match="axis='w'"):
        DexelStock.box((0, 0, 0), (1, 1, 1), 1).volume_mm3("w")  # type: ignore[arg-type]


def test_memory_of_a_200_x_200_x_50_stock_at_10_per_mm_is_under_1_gib() -> None:
    low, high = (0.0, 0.0, -50.0), (200.0, 200.0, 0.0)
    estimate = DexelStock.estimate_nbytes(low, high, 10.0)
    # 2000 x 2000 z rays, 2000 x 500 x and y rays, 28 bytes each at capacity 2, and heaps of
    # a quarter of each family's 2 rows a ray, 8 bytes a row (+ 8 for its top).
    assert estimate == 6_000_000 * 28 + 6_000_000 // 2 * 8 + 3 * 8
    assert estimate < GIB
    tracemalloc.start()
    try:
        stock = DexelStock.box(low, high, 10.0)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert stock.nbytes == estimate
    assert peak < 1.1 * estimate < GIB


def test_load_round_trip_and_overflow_to_the_heap() -> None:
    stock = DexelStock(DexelGrid.from_box((0, 0, 0), (4, 2, 4), 1.0), capacity=2)
    counts = np.array([0, 1, 3, 5, 2, 0, 0, 1])
    intervals = []
    for n in counts:
        intervals += [(0.1 + 0.7 * q, 0.4 + 0.7 * q) for q in range(n)]
    stock.load("z", counts, np.array(intervals))
    assert stock.interval_counts("z").tolist() == counts.tolist()
    assert stock.overflow_rays("z") == 2  # the rays with 3 and 5 intervals
    np.testing.assert_allclose(stock.ray_intervals_mm("z", 3, 0), intervals[4:9], atol=1e-6)
    assert stock.volume_mm3("z") == pytest.approx(0.3 * counts.sum(), rel=1e-6)


def test_load_clips_to_the_grid_and_drops_what_lies_outside() -> None:
    stock = DexelStock(DexelGrid.from_box((0, 0, 0), (2, 1, 1), 1.0))
    stock.load("z", np.array([3, 1]), np.array([[-2.0, -1.0], [-0.5, 0.25], [0.5, 3.0], [2, 3]]))
    assert stock.interval_counts("z").tolist() == [2, 0]
    np.testing.assert_allclose(stock.ray_intervals_mm("z", 0, 0), [[0.0, 0.25], [0.5, 1.0]])


@pytest.mark.parametrize(
    ("counts", "intervals", "fragment"),
    [
        ([1, 1], [[0.0, 1.0], [0.0, 1.0]], "give 8 counts"),
        ([1] * 8, [[0.0, 1.0]], r"give \(8, 2\)"),
        ([2] + [0] * 7, [[0.0, 0.5], [0.4, 0.8]], "sorted and disjoint"),
        ([1] + [0] * 7, [[0.5, 0.5]], "start < end"),
    ],
)
def test_load_rejects_bad_intervals(counts: list, intervals: list, fragment: str) -> None:
    stock = DexelStock(DexelGrid.from_box((0, 0, 0), (4, 2, 1), 1.0))
    with pytest.raises(DataError, match=fragment):
        stock.load("z", np.array(counts), np.array(intervals))


def _reference_subtract(
    intervals: list[tuple[float, float]], a: float, b: float
) -> tuple[list[tuple[float, float]], float]:
    """Interval difference in plain Python: what remains of `intervals` minus [a, b] (a cut of
    zero length removes nothing, not even a point)."""
    if not a < b:
        return list(intervals), 0.0
    kept = []
    removed = 0.0
    for lo, hi in intervals:
        removed += max(0.0, min(hi, b) - max(lo, a))
        if lo < a:
            kept.append((lo, min(hi, a)))
        if hi > b:
            kept.append((max(lo, b), hi))
    return [(lo, hi) for lo, hi in kept if hi > lo], removed


def _ray_stock(intervals: list[tuple[float, float]], capacity: int) -> DexelStock:
    """A stock with one x ray holding `intervals` (float32-exact values)."""
    stock = DexelStock(DexelGrid.from_box((0, 0, 0), (64, 1, 1), 1.0), capacity=capacity)
    stock.load(
        "x", np.array([len(intervals)]), np.array(intervals, dtype=np.float64).reshape(-1, 2)
    )
    return stock


@settings(deadline=None, max_examples=150, derandomize=True, database=None)
@given(
    edges=st.lists(st.integers(0, 64), min_size=0, max_size=20, unique=True),
    cut=st.tuples(st.integers(-2, 66), st.integers(-2, 66)),
    capacity=st.integers(1, 3),
    hint=st.integers(0, 12),
)
def test_subtract_interval_matches_the_reference(
    edges: list[int], cut: tuple[int, int], capacity: int, hint: int
) -> None:
    edges = sorted(edges)[: len(edges) // 2 * 2]
    intervals = [(float(edges[q]), float(edges[q + 1])) for q in range(0, len(edges), 2)]
    a, b = float(min(cut)), float(max(cut))
    stock = _ray_stock(intervals, capacity)
    status = 1
    while status == 1:  # grow the heap until the split fits, as the kernels' callers do
        status, removed, lo_in, hi_in, cut_lo, cut_hi, _ = subtract_interval(
            0, np.float32(a), np.float32(b), hint, stock.family_arrays("x")
        )
        if status == 1:
            stock.grow_heap("x")
    expected, expected_removed = _reference_subtract(intervals, a, b)
    assert stock.ray_intervals_mm("x", 0, 0).tolist() == [list(iv) for iv in expected]
    assert removed == pytest.approx(expected_removed)
    assert lo_in == (removed > 0 and any(lo < a < hi for lo, hi in intervals))
    assert hi_in == (removed > 0 and any(lo < b < hi for lo, hi in intervals))
    if removed > 0:
        pieces = [(max(lo, a), min(hi, b)) for lo, hi in intervals if min(hi, b) > max(lo, a)]
        assert (cut_lo, cut_hi) == (pieces[0][0], pieces[-1][1])


def test_a_full_heap_grows_and_keeps_every_interval() -> None:
    # Split one ray 40 times at capacity 1: it moves through heap blocks of 2, 4, ... 64 rows.
    stock = _ray_stock([(0.0, 64.0)], capacity=1)
    for q in range(40):
        status = 1
        while status == 1:
            status = subtract_interval(
                0, np.float32(1.0 + 1.5 * q), np.float32(1.5 + 1.5 * q), 0,
                stock.family_arrays("x"),
            )[0]  # fmt: skip
            if status == 1:
                stock.grow_heap("x")
    got = stock.ray_intervals_mm("x", 0, 0)
    assert len(got) == 41 and stock.overflow_rays("x") == 1
    assert stock.volume_mm3("x") == pytest.approx(64.0 - 40 * 0.5)
