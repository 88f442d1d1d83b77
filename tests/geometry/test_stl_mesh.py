"""The written stock.stl, read back by the format's specification (struct, and a text parser for
ASCII): a closed 2-manifold (every edge in exactly two triangles, walked both ways), enclosing
the volume of stocks whose volume is known in closed form within the resolution's bound."""

from __future__ import annotations

import struct
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from cnctwin.errors import InputError
from cnctwin.geometry import DexelStock
from cnctwin.geometry.mesh import MIN_THICKNESS_MM, mesh_step, stock_mesh
from cnctwin.geometry.stl import write_stl

Vertex = tuple[float, float, float]


def read_binary(path: Path) -> list[tuple[Vertex, Vertex, Vertex]]:
    """Triangles of a binary STL: 80-byte header, uint32 count, 50-byte records."""
    data = path.read_bytes()
    (count,) = struct.unpack_from("<I", data, 80)
    assert len(data) == 84 + 50 * count
    triangles = []
    for k in range(count):
        v = struct.unpack_from("<12fH", data, 84 + 50 * k)[3:12]
        triangles.append((v[0:3], v[3:6], v[6:9]))
    return triangles


def read_ascii(path: Path) -> list[tuple[Vertex, Vertex, Vertex]]:
    """Triangles of an ASCII STL (the ``vertex x y z`` lines, three a facet), as float32."""
    lines = path.read_text().split("\n")
    assert lines[0].startswith("solid ") and lines[-2].startswith("endsolid ")
    points = [
        tuple(float(np.float32(w)) for w in line.split()[1:])
        for line in lines
        if line.startswith("vertex ")
    ]
    assert lines.count("outer loop") * 3 == len(points)
    return [(points[k], points[k + 1], points[k + 2]) for k in range(0, len(points), 3)]


def divergence_volume(triangles: list[tuple[Vertex, Vertex, Vertex]]) -> float:
    """Sum of a . (b x c) / 6 over the triangles (Gauss's theorem for a closed surface)."""
    a, b, c = (np.array([t[i] for t in triangles], dtype=np.float64) for i in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def edge_problems(triangles: list[tuple[Vertex, Vertex, Vertex]]) -> list[object]:
    """Directed edges that do not occur exactly once with their reverse exactly once."""
    directed = Counter((t[i], t[(i + 1) % 3]) for t in triangles for i in range(3))
    return [e for e, n in directed.items() if n != 1 or directed.get((e[1], e[0])) != 1]


def pocketed_stock() -> tuple[DexelStock, float, float]:
    """A 20 x 12 x 10 mm block (4 dexels/mm) with a 8 x 4 mm pocket 3 mm deep and a 2 x 2 mm
    hole cut through; returns the stock, its closed-form volume and the pocket's and hole's wall
    area (perimeter x height), mm^2."""
    stock = DexelStock.box((-5.0, 2.0, -10.0), (15.0, 14.0, 0.0), density_per_mm=4)
    xy = stock.grid.ray_coordinates_mm("z")
    x, y = xy[:, 0], xy[:, 1]
    pocket = (x > 0.0) & (x < 8.0) & (y > 6.0) & (y < 10.0)
    hole = (x > 10.0) & (x < 12.0) & (y > 4.0) & (y < 6.0)
    counts = np.where(hole, 0, 1)
    top = np.where(pocket, -3.0, 0.0)[~hole]
    stock.load("z", counts, np.column_stack([np.full(top.size, -10.0), top]))
    volume = 20 * 12 * 10 - 8 * 4 * 3 - 2 * 2 * 10
    walls = 2 * (8 + 4) * 3 + 2 * (2 + 2) * 10
    return stock, volume, walls


@pytest.mark.parametrize("resolution_mm", [None, 0.5, 1.0, 1.5])
def test_binary_file_is_a_closed_manifold_of_the_stock_volume(
    tmp_path: Path, resolution_mm: float | None
) -> None:
    stock, volume, walls = pocketed_stock()
    write_stl(tmp_path / "s.stl", stock_mesh(stock, resolution_mm), "stock")
    triangles = read_binary(tmp_path / "s.stl")
    assert edge_problems(triangles) == []
    # The dexels hold the closed form exactly (the pocket's edges lie between rays).
    assert stock.volume_mm3("z") == pytest.approx(volume, rel=1e-9)
    resolution = 0.25 * mesh_step(stock, resolution_mm)
    bound = walls * resolution + 2 * 2 * MIN_THICKNESS_MM
    assert abs(divergence_volume(triangles) - volume) <= bound
    # The outline is the block's, and the bottom its floor.
    points = np.array(triangles).reshape(-1, 3)
    assert points.min(axis=0) == pytest.approx([-5.0, 2.0, -10.0])
    assert points.max(axis=0) == pytest.approx([15.0, 14.0, 0.0])


def test_a_plain_block_is_exact_and_its_triangle_count_follows_the_resolution(
    tmp_path: Path,
) -> None:
    stock = DexelStock.box((0.0, 0.0, -30.0), (120.0, 80.0, 0.0), density_per_mm=10)
    for resolution_mm, cells in ((0.5, (240, 160)), (2.0, (60, 40)), (0.01, (1200, 800))):
        tris = stock_mesh(stock, resolution_mm)
        nx, ny = cells
        assert len(tris) == 2 * (nx + 1) * (ny + 1) + 6 * (nx + ny + 2)
    write_stl(tmp_path / "b.stl", stock_mesh(stock, 0.5), "block")
    triangles = read_binary(tmp_path / "b.stl")
    assert divergence_volume(triangles) == pytest.approx(120 * 80 * 30, rel=1e-6)
    # 84 + 50 bytes a triangle: 4.0 MB at 0.5 mm (the dexel-pitch mesh of old: 192 MB).
    assert (tmp_path / "b.stl").stat().st_size == 84 + 50 * 80014


def test_ascii_file_holds_the_same_triangles(tmp_path: Path) -> None:
    stock, _, _ = pocketed_stock()
    tris = stock_mesh(stock, 1.0)
    write_stl(tmp_path / "b.stl", tris, "pocket")
    write_stl(tmp_path / "a.stl", tris, "pocket  with\nspaces", binary=False)
    assert read_ascii(tmp_path / "a.stl") == read_binary(tmp_path / "b.stl")
    assert (tmp_path / "a.stl").read_text().startswith("solid pocket with spaces\n")


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_bad_resolution_is_refused(bad: float) -> None:
    stock = DexelStock.box((0.0, 0.0, -1.0), (2.0, 2.0, 0.0), density_per_mm=2)
    with pytest.raises(InputError, match=r"STL resolution .* mm; give a finite resolution > 0"):
        stock_mesh(stock, bad)
