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


@pytest.mark.parametrize("flutes", [0, -1, MAX_FLUTES + 1, 10**9, 2.0, True])
def test_cutter_refuses_a_flute_count_out_of_range(flutes: object) -> None:
    with pytest.raises(CnctwinError, match="flutes="):
        Cutter.flat(10.0, 20.0, flutes=flutes)  # type: ignore[arg-type]


@pytest.mark.parametrize("diameter", [math.nan, math.inf, -1.0, 0.0])
def test_cutter_refuses_a_diameter_that_is_not_finite_and_positive(diameter: float) -> None:
    with pytest.raises(CnctwinError, match="diameter_mm="):
        Cutter.flat(diameter, 20.0)


@pytest.mark.parametrize(
    ("fields", "fragment"),
    [({"runout_mm": -1e-3}, "runout_mm="), ({"runout_angle_rad": math.nan}, "runout_angle_rad=")],
)
def test_cutter_refuses_a_bad_runout(fields: dict[str, float], fragment: str) -> None:
    with pytest.raises(CnctwinError, match=fragment):
        Cutter("flat", 10.0, 20.0, **fields)  # type: ignore[arg-type]


def test_the_largest_flute_count_is_accepted() -> None:
    cutter = Cutter.flat(100.0, 20.0, flutes=MAX_FLUTES)
    assert cutter.flutes == MAX_FLUTES
    # One radius offset per tooth for the force model, all 0 without runout.
    assert cutter.tooth_radius_offsets_m().tolist() == [0.0] * MAX_FLUTES
