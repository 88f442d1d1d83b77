"""The stock's surface mesh: outward, and enclosing the z dexels' volume (manifold and file
checks: test_stl_mesh.py)."""

from __future__ import annotations

import numpy as np
import pytest

from cnctwin.geometry import Cutter, DexelStock, cut
from cnctwin.geometry.mesh import mesh_volume_mm3, stock_mesh


def test_box_mesh_is_the_box() -> None:
    stock = DexelStock.box((-5.0, 2.0, -10.0), (15.0, 12.0, 0.0), density_per_mm=2)
    tris = stock_mesh(stock)
    assert mesh_volume_mm3(tris) == pytest.approx(20 * 10 * 10, rel=1e-6)
    assert tris[..., 0].min() == -5.0 and tris[..., 1].max() == 12.0
    # Every normal of the top points up, of the floor down, of a side away from the block.
    normals = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    centres = tris.mean(axis=1)
    outward = centres - np.array([5.0, 7.0, -5.0])
    assert np.all(np.einsum("ij,ij->i", normals, outward) > 0)


@pytest.mark.parametrize("resolution_mm", [None, 1.0])
def test_cut_stock_mesh_volume_matches_the_dexels(resolution_mm: float | None) -> None:
    stock = DexelStock.box((0.0, 0.0, -10.0), (20.0, 10.0, 0.0), density_per_mm=4)
    cutter = Cutter.flat(diameter_mm=6.0, flute_length_mm=20.0, flutes=2)
    previous = None
    for x in np.linspace(-3.0, 23.0, 200):
        position = np.array([x, 5.0, -3.0])
        cut(stock, cutter, position, previous, 0.05, 0.0125)
        previous = position
    tris = stock_mesh(stock, resolution_mm)
    # A slot through the block: the heights vary along y only, where the trapezoid rule through
    # the cell centres keeps each cell's volume exactly.
    assert mesh_volume_mm3(tris) == pytest.approx(stock.volume_mm3("z"), rel=1e-6)
    # The slot (6 mm wide, 3 mm deep, 20 mm long) by its closed form, within the dexel blur.
    assert stock.volume_mm3("z") == pytest.approx(20 * 10 * 10 - 6 * 3 * 20, rel=2e-3)
