"""Reader of tables of measured cuts: a CSV with a header row and one row per cut.

Each column holds one quantity of the cut, named with its unit (``ap_mm``, ``spindle_rpm``,
``fz_mm``, ``vibration_g``, ``ra_um``, ...); the values are read as they are, in those units.
Read by the roughness fit (:mod:`cnctwin.quality.roughness`) and the process-damping
calibration (:mod:`cnctwin.dynamics.process_damping`).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

from cnctwin.errors import DataError

__all__ = ["read_columns"]


def read_columns(path: Path, names: list[str]) -> dict[str, list[float]]:
    """Read the named columns of a CSV with a header row, each value a number > 0.

    Other columns are ignored; blank lines are skipped.

    Parameters
    ----------
    path
        The CSV file.
    names
        Columns to read.

    Returns
    -------
    dict
        The values of each column, in file order.

    Raises
    ------
    cnctwin.errors.DataError
        ``"FILE: ..."`` for an empty file, a missing or repeated column, no data rows;
        ``"FILE:LINE: ..."`` for a row with too few cells, a value that is not a number or
        not > 0.
    """
    try:
        with path.open(newline="", encoding="utf-8-sig") as handle:
            rows = list(csv.reader(handle))
    except UnicodeDecodeError as err:
        raise DataError(f"{path}: not a UTF-8 text file ({err.reason})") from None
    numbered = [
        (line, row) for line, row in enumerate(rows, start=1) if any(c.strip() for c in row)
    ]
    if not numbered:
        raise DataError(f"{path}: empty; give a header row, then one row per cut")
    header_line, header = numbered[0]
    header = [cell.strip() for cell in header]
    repeated = sorted({name for name in header if header.count(name) > 1 and name in names})
    if repeated:
        raise DataError(f"{path}:{header_line}: column {repeated[0]!r} appears more than once")
    missing = [name for name in names if name not in header]
    if missing:
        raise DataError(
            f"{path}:{header_line}: no column {', '.join(map(repr, missing))} "
            f"(the header has {', '.join(header)})"
        )
    index = {name: header.index(name) for name in names}
    columns: dict[str, list[float]] = {name: [] for name in names}
    for line, row in numbered[1:]:
        for name, i in index.items():
            if i >= len(row):
                raise DataError(
                    f"{path}:{line}: {len(row)} cells, no value for column {name!r} (cell {i + 1})"
                )
            text = row[i].strip()
            try:
                value = float(text)
            except ValueError:
                raise DataError(f"{path}:{line}: column {name}: {text!r} is not a number") from None
            if not (math.isfinite(value) and value > 0):
                raise DataError(
                    f"{path}:{line}: column {name}: {text!r}; the power law needs values > 0"
                )
            columns[name].append(value)
    if not columns[names[0]]:
        raise DataError(f"{path}: no data rows after the header")
    return columns
