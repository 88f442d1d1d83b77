"""The 3D view's height map equals the dexel stock's tops after a slot of known depth."""

import json
import math

import numpy as np
import pytest

from cnctwin.errors import InputError
from cnctwin.geometry import Cutter, DexelStock, cut, height_map
from cnctwin.web.stock import stock_view

#: A 40 x 30 x 10 mm block (top at z = 0) at 4 rays/mm; a 6 mm end mill slots 2 mm deep
#: along x at y = 15 from x = 8 to x = 32.
DEPTH_MM, RADIUS_MM, Y_SLOT, X_FROM, X_TO = 2.0, 3.0, 15.0, 8.0, 32.0


@pytest.fixture(scope="module")
def slotted() -> tuple[DexelStock, Cutter]:
    stock = DexelStock.box((0, 0, -10), (40, 30, 0), density_per_mm=4)
    cutter = Cutter.flat(diameter_mm=2 * RADIUS_MM, flute_length_mm=20.0, flutes=3)
    previous = None
    for x in np.arange(X_FROM, X_TO + 1e-9, 0.05):  # steps far below the 0.25 mm pitch
        position = np.array((x, Y_SLOT, -DEPTH_MM))
        cut(stock, cutter, position, previous, 0.05, 0.001)
        previous = position
    return stock, cutter


def expected_top(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Closed form: the slot (a stadium of radius R around the path) is DEPTH deep."""
    dx = np.clip(x, X_FROM, X_TO) - x
    inside = np.hypot(dx, y - Y_SLOT) < RADIUS_MM
    return np.where(inside, -DEPTH_MM, 0.0)


def test_full_resolution_heights_are_the_slot(slotted) -> None:
    stock, _ = slotted
    hmap = height_map(stock, max_cells=400)
    assert hmap.step == 1
    assert hmap.z_mm.shape == (120, 160)
    np.testing.assert_allclose(hmap.x_mm, (np.arange(160) + 0.5) * 0.25)
    np.testing.assert_allclose(hmap.y_mm, (np.arange(120) + 0.5) * 0.25)
    x, y = np.meshgrid(hmap.x_mm, hmap.y_mm)
    expected = expected_top(x, y)
    # Rays within 0.06 mm of the slot's edge depend on where the discrete steps fell.
    dx = np.clip(x, X_FROM, X_TO) - x
    clear = np.abs(np.hypot(dx, y - Y_SLOT) - RADIUS_MM) > 0.06
    np.testing.assert_allclose(hmap.z_mm[clear], expected[clear], atol=1e-5)
    assert np.count_nonzero(np.isclose(hmap.z_mm[clear], -DEPTH_MM)) > 1000
    # The removed volume agrees with the map: depth x slot area.
    slot_area = 2 * RADIUS_MM * (X_TO - X_FROM) + math.pi * RADIUS_MM**2
    removed = np.sum(-hmap.z_mm) * 0.25 * 0.25
    assert removed == pytest.approx(DEPTH_MM * slot_area, rel=0.01)


def test_decimated_cells_show_the_lowest_top(slotted) -> None:
    stock, _ = slotted
    full = height_map(stock, max_cells=400).z_mm
    coarse = height_map(stock, max_cells=50)
    assert coarse.step == 4  # ceil(160 / 50)
    assert coarse.z_mm.shape == (30, 40)
    blocks = full.reshape(30, 4, 40, 4).min(axis=(1, 3))
    np.testing.assert_array_equal(coarse.z_mm, blocks)
    np.testing.assert_allclose(coarse.x_mm, (np.arange(40) * 4 + 2) * 0.25)


def test_json_view_carries_tool_and_heights(slotted) -> None:
    stock, cutter = slotted
    view = json.loads(json.dumps(stock_view(stock, (32.0, 15.0, -2.0), cutter, max_cells=80)))
    assert view["step"] == 2
    assert view["box_mm"] == [[0.0, 0.0, -10.0], [40.0, 30.0, 0.0]]
    assert view["tool"] == {
        "x_mm": 32.0,
        "y_mm": 15.0,
        "z_mm": -2.0,
        "radius_mm": 3.0,
        "length_mm": 20.0,
    }
    z = np.array(view["z_mm"], dtype=float)
    assert z.shape == (60, 80)
    assert z.min() == pytest.approx(-DEPTH_MM, abs=1e-3) and z.max() == pytest.approx(0.0)
    # The colour scale's span: the slot's floor to the uncut top, not the 10 mm block.
    lo, hi = view["z_range_mm"]
    assert lo == pytest.approx(-DEPTH_MM, abs=1e-3) and hi == pytest.approx(0.0)


def test_empty_rays_are_holes_and_bad_sizes_refused() -> None:
    stock = DexelStock.box((0, 0, 0), (4, 4, 1), density_per_mm=1)
    counts = np.ones(16, dtype=np.int32)
    counts[5] = 0
    stock.load("z", counts, np.tile([0.0, 1.0], (15, 1)))
    view = stock_view(stock, max_cells=4)
    assert view["z_mm"][1][1] is None and view["z_mm"][0][0] == 1.0 and view["tool"] is None
    assert view["z_range_mm"] == [1.0, 1.0]
    stock.load("z", np.zeros(16, dtype=np.int32), np.zeros((0, 2)))
    assert stock_view(stock, max_cells=4)["z_range_mm"] is None  # no material left
    with pytest.raises(InputError, match="max_cells=1"):
        height_map(stock, max_cells=1)
