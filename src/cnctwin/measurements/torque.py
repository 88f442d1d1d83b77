"""Reader of recorded spindle-torque series for wear estimation (Christiand 2024).

A CSV with a header and the columns ``time_s`` (s), ``torque_nm`` (N m) and
``material_removed_mm3`` (mm^3 per step), optionally ``torque_base_nm`` (N m, the torque
without wear) and ``vb_mm`` (mm, measured flank wear); read into a
:class:`cnctwin.wear.torque_series.TorqueSeries`.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from cnctwin.errors import DataError
from cnctwin.wear import TorqueSeries

__all__ = ["TORQUE_COLUMNS", "read_torque_csv"]

#: The columns a torque series must have.
TORQUE_COLUMNS = ("time_s", "torque_nm", "material_removed_mm3")


def read_torque_csv(path: Path, default_base_nm: float) -> TorqueSeries:
    """Read a torque series: a CSV with a header and the columns ``time_s``, ``torque_nm``,
    ``material_removed_mm3`` (per step) and optionally ``torque_base_nm`` and ``vb_mm``.

    An empty ``torque_nm`` cell is a missed sample. ``default_base_nm`` (N m) is the
    torque without wear where the file has no ``torque_base_nm`` column.

    Raises
    ------
    cnctwin.errors.DataError
        ``"FILE:LINE: ..."`` for a missing column, a value that is not a number, a negative
        material removal or times that do not increase.
    """
    with path.open(newline="", encoding="utf-8") as handle:
        reader = csv.DictReader(handle)
        header = reader.fieldnames or []
        missing = [name for name in TORQUE_COLUMNS if name not in header]
        if missing:
            raise DataError(
                f"{path}:1: missing column(s) {', '.join(missing)}; the header needs "
                f"{', '.join(TORQUE_COLUMNS)} (optional: torque_base_nm, vb_mm)"
            )
        columns: dict[str, list[float]] = {name: [] for name in header}
        for row in reader:
            line = reader.line_num
            for name in header:
                text = (row.get(name) or "").strip()
                if text == "" and name in ("torque_nm", "vb_mm"):
                    columns[name].append(math.nan)
                    continue
                try:
                    value = float(text)
                except ValueError:
                    raise DataError(
                        f"{path}:{line}: column {name}: {text!r} is not a number"
                    ) from None
                if not math.isfinite(value):
                    raise DataError(f"{path}:{line}: column {name}: {text!r} is not finite")
                if name == "material_removed_mm3" and value < 0:
                    raise DataError(
                        f"{path}:{line}: material_removed_mm3 is {value:g}; it must be >= 0"
                    )
                columns[name].append(value)
    time = np.asarray(columns["time_s"])
    if time.size == 0:
        raise DataError(f"{path}: no samples after the header")
    if np.any(np.diff(time) <= 0):
        bad = int(np.argmax(np.diff(time) <= 0)) + 3
        raise DataError(f"{path}:{bad}: time_s must increase from one row to the next")
    base = (
        np.asarray(columns["torque_base_nm"])
        if "torque_base_nm" in columns
        else np.full(time.size, default_base_nm)
    )
    truth = np.asarray(columns["vb_mm"]) if "vb_mm" in columns else None
    return TorqueSeries(
        time,
        np.asarray(columns["torque_nm"]),
        np.asarray(columns["material_removed_mm3"]),
        base,
        truth,
    )
