"""Reader of measured signals: one sampled column (vibration, force, ...) of a CSV over time.

The CSV has a header row, a time column (s) and one or more signal columns, sampled at a fixed
rate; the signal keeps the file's unit. Read for chatter detection
(:func:`cnctwin.dynamics.chatter_detection.detect_chatter`).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from cnctwin.errors import DataError

__all__ = ["TIME_NAMES", "read_signal_csv"]

#: Names taken for the time column when ``--time-column`` is not given (case-insensitive).
TIME_NAMES = ("t_s", "time_s", "time", "t")
_UNIFORM = 1e-3  # largest relative deviation of a sampling interval from the mean


def read_signal_csv(
    path: Path, column: str | None, time_column: str | None
) -> tuple[np.ndarray, float, str]:
    """Read one signal column and the sampling rate from a CSV with a header row.

    Parameters
    ----------
    path
        The CSV file.
    column
        Signal column; ``None``: the first column that is not the time column.
    time_column
        Time column (s); ``None``: the first of :data:`TIME_NAMES` present.

    Returns
    -------
    tuple
        The samples, the sampling rate in Hz and the signal column's name.

    Raises
    ------
    cnctwin.errors.DataError
        One line naming the file (and line) for a missing column, a cell that is not a
        number, fewer than 16 rows, or a time column that is not evenly increasing.
    """
    try:
        with path.open(newline="", encoding="utf-8-sig") as handle:
            rows = [row for row in csv.reader(handle) if any(cell.strip() for cell in row)]
    except UnicodeDecodeError as err:
        raise DataError(f"{path}: not a UTF-8 text file ({err.reason})") from None
    if not rows:
        raise DataError(f"{path}: empty; give a header row with a time column, then samples")
    header = [cell.strip() for cell in rows[0]]
    lowered = [name.lower() for name in header]
    if time_column is None:
        found = [name for name in TIME_NAMES if name in lowered]
        if not found:
            raise DataError(
                f"{path}: no time column among {header}; name one t_s, time_s, time or t, "
                "or give --time-column"
            )
        t_index = lowered.index(found[0])
    elif time_column in header:
        t_index = header.index(time_column)
    else:
        raise DataError(f"{path}: no column {time_column!r} (--time-column); columns: {header}")
    if column is None:
        others = [i for i in range(len(header)) if i != t_index]
        if not others:
            raise DataError(f"{path}: only a time column; add a signal column")
        s_index = others[0]
    elif column in header:
        s_index = header.index(column)
    else:
        raise DataError(f"{path}: no column {column!r} (--column); columns: {header}")
    data = np.empty((len(rows) - 1, 2))
    for line, row in enumerate(rows[1:], start=2):
        for j, index in enumerate((t_index, s_index)):
            try:
                data[line - 2, j] = float(row[index])
            except (IndexError, ValueError):
                cell = row[index] if index < len(row) else ""
                raise DataError(
                    f"{path}:{line}: column {header[index]!r} is {cell!r}; give a number"
                ) from None
    if data.shape[0] < 16:
        raise DataError(f"{path}: {data.shape[0]} samples; give at least 16")
    steps = np.diff(data[:, 0])
    mean = float(steps.mean())
    if not (mean > 0.0 and np.all(np.abs(steps - mean) <= _UNIFORM * mean)):
        raise DataError(
            f"{path}: column {header[t_index]!r} is not evenly increasing (steps "
            f"{steps.min():.6g} ... {steps.max():.6g} s); resample to a fixed rate"
        )
    if not np.all(np.isfinite(data[:, 1])):
        raise DataError(f"{path}: column {header[s_index]!r} holds a value that is not finite")
    return data[:, 1].copy(), 1.0 / mean, header[s_index]
