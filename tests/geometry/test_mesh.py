"""The stock's surface mesh: closed, outward, and enclosing exactly the z dexels' volume."""

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
    # A box of 40 x 20 columns: 2 triangles per top, bottom and outer side cell.
    assert len(tris) == 2 * (2 * 40 * 20) + 2 * 2 * (40 + 20)


def test_cut_stock_mesh_volume_matches_the_dexels() -> None:
    stock = DexelStock.box((0.0, 0.0, -10.0), (20.0, 10.0, 0.0), density_per_mm=4)
    cutter = Cutter.flat(diameter_mm=6.0, flute_length_mm=20.0, flutes=2)
    previous = None
    for x in np.linspace(-3.0, 23.0, 200):
        position = np.array([x, 5.0, -3.0])
        cut(stock, cutter, position, previous, 0.05, 0.0125)
        previous = position
    tris = stock_mesh(stock)
    assert mesh_volume_mm3(tris) == pytest.approx(stock.volume_mm3("z"), rel=1e-6)
    # A closed surface: the edge vectors of all triangles cancel (T-junctions included).
    edges = np.concatenate(
        [tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 1], tris[:, 0] - tris[:, 2]]
    )
    assert np.allclose(edges.sum(axis=0), 0.0, atol=1e-3)
