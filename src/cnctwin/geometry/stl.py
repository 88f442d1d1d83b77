"""Binary STL files of triangle meshes (such as :func:`cnctwin.geometry.mesh.stock_mesh`).

The binary STL layout: an 80-byte header, the triangle count as a little-endian uint32, then
50 bytes a triangle: the unit normal and the three vertices as little-endian float32 (x, y, z
each) and a uint16 attribute (0). Units: those of the vertices (mm for the stock).

The ASCII layout (``binary=False``), for tools that read only text: ``solid NAME``, then per
triangle ``facet normal nx ny nz`` / ``outer loop`` / three ``vertex x y z`` / ``endloop`` /
``endfacet``, and ``endsolid NAME``; numbers as float32 printed to 9 significant digits (which
read back to the same float32). About five times the binary file's size.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from cnctwin.errors import InputError

__all__ = ["STL_HEADER_BYTES", "write_stl"]

#: Length of the header of a binary STL file, bytes.
STL_HEADER_BYTES = 80
_RECORD = np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])


def write_stl(path: Path, triangles: ArrayLike, header: str = "", *, binary: bool = True) -> None:
    """Write ``triangles`` ((n, 3, 3): triangle, vertex, x/y/z; mm) as an STL file.

    Each normal is the unit vector of ``(v1 - v0) x (v2 - v0)`` (counter-clockwise vertices
    seen from outside, the STL convention); a degenerate triangle gets a zero normal.
    ``header`` is written as ASCII (other characters as ``?``), cut or padded to 80 bytes (in
    a text file: the solid's name, on one line). ``binary=False`` writes the ASCII format.

    Raises
    ------
    cnctwin.errors.InputError
        If ``triangles`` is not of shape (n, 3, 3).
    OSError
        If the file cannot be written.
    """
    tri = np.asarray(triangles, dtype=np.float32)
    if tri.ndim != 3 or tri.shape[1:] != (3, 3):
        raise InputError(f"triangles of shape {tri.shape}; give (n, 3, 3) vertices in mm")
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    lengths = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.divide(normals, lengths, out=np.zeros_like(normals), where=lengths > 0)
    if not binary:
        name = " ".join(header.encode("ascii", "replace").decode().split())
        rows = np.concatenate([normals[:, None, :], tri], axis=1).reshape(len(tri), 12)
        facet = (
            "facet normal {:.9g} {:.9g} {:.9g}\nouter loop\n"
            + "vertex {:.9g} {:.9g} {:.9g}\n" * 3
            + "endloop\nendfacet\n"
        )
        with Path(path).open("w", encoding="ascii") as text_file:
            text_file.write(f"solid {name}\n")
            text_file.writelines(facet.format(*row) for row in rows.tolist())
            text_file.write(f"endsolid {name}\n")
        return
    data = np.zeros(len(tri), dtype=_RECORD)
    data["n"] = normals
    data["v"] = tri
    text = header[:STL_HEADER_BYTES].ljust(STL_HEADER_BYTES)
    with Path(path).open("wb") as handle:
        handle.write(text.encode("ascii", "replace"))
        handle.write(np.array(len(tri), dtype="<u4").tobytes())
        handle.write(data.tobytes())
