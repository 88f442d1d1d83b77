"""A recorded run as CSV or Parquet files (pyarrow, imported on first use).

``PATH`` holds the measured signals as a wide table, ``time_s`` then one float64 column per
signal, null (an empty CSV cell) where a signal was not recorded at an instant; siblings
``STEM.predictions.EXT``, ``STEM.events.EXT`` and ``STEM.decisions.EXT`` hold the rest.
Floats are exact (CSV: the shortest text that reads back to the same double; NaN is ``nan``).
Parquet files carry the run's summary as JSON under the schema metadata key ``cnctwin.run``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from cnctwin import finite_json
from cnctwin.store._records import RunDetail

__all__ = ["write_run"]

#: Signal columns and, per signal, where it was recorded.
Columns = tuple[dict[str, np.ndarray], dict[str, np.ndarray]]


def _frame_table(columns: Columns) -> Any:
    import pyarrow as pa

    values, masks = columns
    arrays = [
        pa.array(column, type=pa.float64(), mask=~masks[name] if name in masks else None)
        for name, column in values.items()
    ]
    return pa.table(arrays, names=list(values))


def write_run(
    detail: RunDetail, samples: Columns, predictions: Columns, path: Path, fmt: str
) -> list[Path]:
    """Write a run's four tables next to each other.

    Parameters
    ----------
    detail
        The run (events, decisions, summary).
    samples, predictions
        Columns (``time_s`` in s first) and presence masks of measured and predicted signals.
    path
        The samples file.
    fmt
        ``"csv"`` or ``"parquet"``.

    Returns
    -------
    list of Path
        The files written: samples, predictions, events, decisions.
    """
    import pyarrow as pa
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    events, decisions = detail.events, detail.decisions
    tables = {
        "": _frame_table(samples),
        ".predictions": _frame_table(predictions),
        ".events": pa.table(
            {
                "seq": pa.array([e.seq for e in events], pa.int64()),
                "t_s": pa.array([e.t_s for e in events], pa.float64()),
                "kind": pa.array([e.kind for e in events], pa.string()),
                "message": pa.array([e.message for e in events], pa.string()),
                "data": pa.array([finite_json.dumps(e.data) for e in events], pa.string()),
            }
        ),
        ".decisions": pa.table(
            {
                "seq": pa.array([d.seq for d in decisions], pa.int64()),
                "t_s": pa.array([d.t_s for d in decisions], pa.float64()),
                "rule": pa.array([d.rule for d in decisions], pa.string()),
                "action": pa.array([d.action for d in decisions], pa.string()),
                "value": pa.array([d.value for d in decisions], pa.float64()),
                "reason": pa.array([d.reason for d in decisions], pa.string()),
                "accepted": pa.array([d.accepted for d in decisions], pa.bool_()),
                "readback": pa.array([d.readback for d in decisions], pa.float64()),
            }
        ),
    }
    metadata = {"cnctwin.run": finite_json.dumps(detail.summary.to_dict())}
    written = []
    for infix, table in tables.items():
        target = path if not infix else path.with_name(f"{path.stem}{infix}.{fmt}")
        if fmt == "csv":
            pacsv.write_csv(table, target)
        else:
            pq.write_table(table.replace_schema_metadata(metadata), target)
        written.append(target)
    return written
