"""Benchmark of the stock's STL: size and time of the mesh and the file (issue 16, item 6).

Usage: ``python benchmarks/bench_stl.py [--quick]``. Prints a Markdown table for
docs/benchmarks.md: for the packaged demo's final stock (80 x 60 x 20 mm at 10 dexels/mm,
simulated first) and a plain 120 x 80 x 30 mm block at 10 dexels/mm, at the dexel pitch and at
0.25, 0.5 (``cnctwin simulate``'s default) and 1 mm: triangles, file size, the time to mesh and
to write the binary file, and the volume the file encloses against the dexels'. The ASCII file
is timed at 0.5 mm.

``--quick`` skips the demo (CI).
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

from cnctwin.config import load_config
from cnctwin.geometry import DexelStock, stock_mesh, write_stl
from cnctwin.simulation import simulate_program

EXAMPLES = Path(__file__).resolve().parents[1] / "src" / "cnctwin" / "examples"


def _row(name: str, stock: DexelStock, resolution_mm: float | None, folder: Path) -> str:
    path = folder / "stock.stl"
    t0 = time.perf_counter()
    triangles = stock_mesh(stock, resolution_mm)
    t1 = time.perf_counter()
    write_stl(path, triangles, name)
    t2 = time.perf_counter()
    t = triangles.astype(np.float64)  # divergence theorem: sum of v0 . (v1 x v2) / 6
    volume = float(np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6.0)
    error = volume - stock.volume_mm3("z")
    label = "dexel pitch" if resolution_mm is None else f"{resolution_mm:g} mm"
    return (
        f"| {name} | {label} | {len(triangles):,} | {path.stat().st_size / 1e6:.1f} MB "
        f"| {1e3 * (t1 - t0):.0f} ms | {1e3 * (t2 - t1):.0f} ms | {error:+.2f} mm^3 |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="skip the demo (CI)")
    args = parser.parse_args()
    stocks = [("block 120x80x30", DexelStock.box((0, 0, -30), (120, 80, 0), 10.0))]
    if not args.quick:
        cut = simulate_program(
            EXAMPLES / "demo.ngc",
            load_config(EXAMPLES / "demo.toml"),
            density_per_mm=10.0,
            cycle_s=0.0125,
        )
        stocks.insert(0, ("demo", cut.stock))
    print(f"{platform.machine()}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}")
    print()
    print("| stock | resolution | triangles | binary file | mesh | write | V_file - V_dexel |")
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name, stock in stocks:
            stock_mesh(stock, 1.0)  # first call: imports and caches
            for resolution in (None, 0.25, 0.5, 1.0):
                print(_row(name, stock, resolution, folder))
            triangles = stock_mesh(stock, 0.5)
            t0 = time.perf_counter()
            write_stl(folder / "a.stl", triangles, name, binary=False)
            size = (folder / "a.stl").stat().st_size / 1e6
            print(
                f"| {name} | 0.5 mm, ASCII | {len(triangles):,} | {size:.1f} MB | | "
                f"{1e3 * (time.perf_counter() - t0):.0f} ms | |"
            )


if __name__ == "__main__":
    main()
