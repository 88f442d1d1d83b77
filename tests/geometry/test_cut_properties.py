"""Invariants of cutting and engagement on random paths and cutters (hypothesis).

Angles lie in [0, 2 pi] as sorted, disjoint, non-empty intervals per slice; ae <= D;
ap <= flute length; removed volumes are >= 0 and add up to the stock's loss in every family.
Derandomized and without an example database, so CI runs the same examples every time.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from cnctwin.geometry import Cutter, DexelStock, cut


def _cutter(kind: str, d: float, frac: float, length: float) -> Cutter:
    if kind == "flat":
        return Cutter.flat(d, length)
    if kind == "ball":
        return Cutter.ball(d, max(length, d / 2))
    if kind == "bull":
        return Cutter.bull(d, frac * d / 2, max(length, d / 2))
    if kind == "conical":  # tip angle from 18 to 162 degrees
        angle = math.pi * (0.1 + 0.8 * frac)
        return Cutter.conical(d, max(length, 0.5 * d / math.tan(0.5 * angle)), tip_angle_rad=angle)
    return Cutter.snub(d, frac * d, length)  # a cone over the whole length


cutters = st.builds(
    _cutter,
    st.sampled_from(["flat", "ball", "bull", "conical", "snub"]),
    st.floats(1.0, 8.0),
    st.floats(0.1, 0.9),
    st.floats(1.0, 10.0),
)
points = st.tuples(st.floats(-4.0, 16.0), st.floats(-4.0, 16.0), st.floats(-8.0, 1.0))


@settings(deadline=None, max_examples=150, derandomize=True, database=None)
@given(
    cutter=cutters,
    path=st.lists(points, min_size=1, max_size=6),
    density=st.sampled_from([3.0, 5.0, 7.5]),
    capacity=st.integers(1, 3),
    substeps=st.integers(1, 8),
)
def test_cut_invariants(
    cutter: Cutter,
    path: list[tuple[float, float, float]],
    density: float,
    capacity: int,
    substeps: int,
) -> None:
    stock = DexelStock.box((0.0, 0.0, -6.0), (12.0, 12.0, 0.0), density, capacity)
    before = [stock.volume_mm3(axis) for axis in "xyz"]
    total = 0.0
    previous = None
    for a, b in zip(path, path[1:] + path[-1:], strict=True):
        for t in np.linspace(0.0, 1.0, substeps, endpoint=False):
            position = tuple(float(u + t * (v - u)) for u, v in zip(a, b, strict=True))
            e = cut(stock, cutter, position, previous, 0.05, 0.0125)
            previous = position
            assert e.removed_volume_mm3 >= 0.0 and e.mrr_mm3_s >= 0.0
            assert 0.0 <= e.ae_mm <= cutter.diameter_mm
            assert 0.0 <= e.ap_mm <= cutter.flute_length_mm
            assert e.contact == (e.removed_volume_mm3 > 0.0)
            assert 0.0 <= e.h_mean_mm <= e.h_max_mm + 1e-15 <= 0.05 + 1e-15
            assert np.all(e.slice_radius_mm > 0.0)
            assert np.all(e.slice_radius_mm <= cutter.radius_mm + 1e-12)
            assert np.all((e.slice_height_mm >= 0.0) & (e.slice_dz_mm >= 0.0))
            starts, ends = e.interval_start_rad, e.interval_end_rad
            assert np.all((starts >= 0.0) & (starts < ends) & (ends <= 2 * math.pi))
            for index in range(len(e.slice_height_mm)):
                iv = np.array(e.slice_intervals(index))
                assert len(iv) > 0
                assert np.all(iv[1:, 0] > iv[:-1, 1])  # sorted, disjoint
            total += e.removed_volume_mm3
    lost = [b - stock.volume_mm3(axis) for b, axis in zip(before, "xyz", strict=True)]
    assert all(loss >= -1e-9 for loss in lost)
    assert math.isclose(total, sum(lost) / 3.0, rel_tol=1e-9, abs_tol=1e-9)
