"""Cutters built in code refuse flute counts and sizes outside the configuration's ranges.

The per-tooth arrays of the force model and the dexel cutter grow with the flute count, so a
count such as 1e9 must be refused at construction (a CnctwinError), not allocated.
"""

from __future__ import annotations

import math

import pytest

from cnctwin.config.tools import MAX_FLUTES
from cnctwin.errors import CnctwinError
from cnctwin.geometry.cutter import Cutter
from cnctwin.mechanics.cutter import EndMill


@pytest.mark.parametrize("flutes", [0, -1, MAX_FLUTES + 1, 10**9, 2.0, True])
def test_geometry_cutter_refuses_a_flute_count_out_of_range(flutes: object) -> None:
    with pytest.raises(CnctwinError, match="flutes="):
        Cutter.flat(10.0, 20.0, flutes=flutes)  # type: ignore[arg-type]


@pytest.mark.parametrize("teeth", [0, -1, MAX_FLUTES + 1, 10**9, 2.0, True])
def test_end_mill_refuses_a_tooth_count_out_of_range(teeth: object) -> None:
    with pytest.raises(CnctwinError, match="teeth="):
        EndMill(0.01, teeth)  # type: ignore[arg-type]


@pytest.mark.parametrize("diameter", [math.nan, math.inf, -1.0, 0.0])
def test_cutters_refuse_a_diameter_that_is_not_finite_and_positive(diameter: float) -> None:
    with pytest.raises(CnctwinError):
        Cutter.flat(diameter, 20.0)
    with pytest.raises(CnctwinError):
        EndMill(diameter, 2)


def test_the_largest_flute_count_is_accepted() -> None:
    assert Cutter.flat(100.0, 20.0, flutes=MAX_FLUTES).flutes == MAX_FLUTES
    assert EndMill(0.1, MAX_FLUTES).teeth == MAX_FLUTES
