"""Binary STL files, read back with :mod:`struct` (the format's own layout, not numpy's)."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from cnctwin.errors import InputError
from cnctwin.geometry import DexelStock
from cnctwin.geometry.mesh import stock_mesh
from cnctwin.geometry.stl import write_stl


def read_stl(path: Path) -> tuple[bytes, list[tuple[tuple[float, ...], tuple[float, ...]]]]:
    """Header and (normal, nine vertex coordinates) per triangle of a binary STL file."""
    data = path.read_bytes()
    (count,) = struct.unpack_from("<I", data, 80)
    assert len(data) == 84 + 50 * count
    rows = []
    for k in range(count):
        values = struct.unpack_from("<12fH", data, 84 + 50 * k)
        assert values[12] == 0
        rows.append((values[:3], values[3:12]))
    return data[:80], rows


def test_normals_are_the_right_hand_unit_normals(tmp_path: Path) -> None:
    # Counter-clockwise in the xy plane seen from +z: normal +z; clockwise: -z; the 3-4-5
    # triangle in the xz plane: (v1 - v0) x (v2 - v0) = (3, 0, 0) x (0, 0, 4) = (0, -12, 0).
    triangles = [
        [[0, 0, 0], [2, 0, 0], [0, 2, 0]],
        [[0, 0, 1], [0, 2, 1], [2, 0, 1]],
        [[1, 1, 1], [4, 1, 1], [1, 1, 5]],
        [[0, 0, 0], [1, 1, 1], [2, 2, 2]],  # degenerate: a zero normal
    ]
    write_stl(tmp_path / "t.stl", triangles, "four triangles")
    header, rows = read_stl(tmp_path / "t.stl")
    assert header == b"four triangles".ljust(80)
    assert [normal for normal, _ in rows] == [(0, 0, 1), (0, 0, -1), (0, -1, 0), (0, 0, 0)]
    assert rows[2][1] == (1, 1, 1, 4, 1, 1, 1, 1, 5)


def test_stock_file_encloses_the_stock_volume(tmp_path: Path) -> None:
    stock = DexelStock.box((-5.0, 2.0, -10.0), (15.0, 12.0, 0.0), density_per_mm=1)
    write_stl(tmp_path / "stock.stl", stock_mesh(stock), "stock")
    _, rows = read_stl(tmp_path / "stock.stl")
    # Divergence theorem on the file's triangles: V = sum of v0 . (v1 x v2) / 6.
    volume = 0.0
    for _, v in rows:
        (ax, ay, az), (bx, by, bz), (cx, cy, cz) = v[:3], v[3:6], v[6:]
        volume += (
            ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
        ) / 6
    assert volume == pytest.approx(20 * 10 * 10, rel=1e-6)


def test_header_is_cut_to_80_ascii_bytes(tmp_path: Path) -> None:
    write_stl(tmp_path / "h.stl", [[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], "é" + "x" * 100)
    header, rows = read_stl(tmp_path / "h.stl")
    assert header == b"?" + b"x" * 79 and len(rows) == 1


@pytest.mark.parametrize("shape", [(3, 3), (2, 4, 3), (2, 3, 2)])
def test_wrong_shape_is_refused(tmp_path: Path, shape: tuple[int, ...]) -> None:
    with pytest.raises(InputError, match=r"triangles of shape .*; give \(n, 3, 3\)"):
        write_stl(tmp_path / "x.stl", np.zeros(shape))
