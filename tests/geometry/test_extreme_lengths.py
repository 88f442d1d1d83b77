"""Regression: a fluted length or tool position beyond the int64 range in grid cells.

``flute_length_mm = 1e308`` segfaulted ``cnctwin simulate``/``run``: the kernels converted
``(tip + length) / pitch`` to an integer, which is undefined beyond the int64 range (numba gives
INT64_MIN), and the difference of two such levels wrapped to a huge slice count.
"""

from __future__ import annotations

import math

import pytest

from cnctwin.geometry import Cutter, DexelStock, cut


def _plunge(flute_length_mm: float) -> list[float]:
    cutter = Cutter.flat(diameter_mm=10.0, flute_length_mm=flute_length_mm, flutes=3)
    stock = DexelStock.box((0.0, 0.0, -5.0), (20.0, 20.0, 0.0), density_per_mm=2.0)
    previous = None
    result = []
    # The first tips lie above the stock: their lowest level is far above slice 0.
    for z in (5.0, 1.0, -1.0, -2.0):
        engagement = cut(stock, cutter, (10.0, 10.0, z), previous, 0.05, 0.0125)
        previous = (10.0, 10.0, z)
        result += [engagement.removed_volume_mm3, engagement.ap_mm]
    return result


@pytest.mark.parametrize("length_mm", [1e19, 1e200, 1e308])
def test_huge_flute_length_cuts_as_a_long_one(length_mm: float) -> None:
    # Any fluted length longer than the stock is tall cuts the same material.
    assert _plunge(length_mm) == pytest.approx(_plunge(50.0))


@pytest.mark.parametrize("far_mm", [1e19, -1e19, 1e300, -1e300])
def test_far_away_tip_removes_nothing(far_mm: float) -> None:
    cutter = Cutter.flat(diameter_mm=10.0, flute_length_mm=20.0, flutes=3)
    stock = DexelStock.box((0.0, 0.0, -5.0), (20.0, 20.0, 0.0), density_per_mm=2.0)
    for tip in ((far_mm, 10.0, -1.0), (10.0, far_mm, -1.0), (10.0, 10.0, far_mm)):
        assert cut(stock, cutter, tip, None, 0.05, 0.0125).removed_volume_mm3 == 0.0


def test_tip_far_below_with_longer_flutes_cuts_through() -> None:
    cutter = Cutter.flat(diameter_mm=10.0, flute_length_mm=1e300, flutes=3)
    stock = DexelStock.box((0.0, 0.0, -5.0), (20.0, 20.0, 0.0), density_per_mm=2.0)
    removed = cut(stock, cutter, (10.0, 10.0, -1e250), None, 0.05, 0.0125).removed_volume_mm3
    # A cylinder of radius 5 mm through the 5 mm stock, to the grid's resolution.
    assert removed == pytest.approx(math.pi * 25.0 * 5.0, rel=0.1)
