"""Datasets for training: runs from files or the historian, features by the one feature path,
labels joined per run.

Sources (:func:`read_runs`):

- a CSV or Parquet file, or a folder or glob pattern of them, one run per file: a historian
  export (``cnctwin runs export``: ``time_s`` then one column per signal; its
  ``.predictions``/``.events``/``.decisions`` siblings are skipped) or a replay log such as
  the UMich ``experiment_NN.csv`` files (no time column: samples ``sample_period_s`` apart).
  A file's run key is the number at the end of its stem (``experiment_07`` -> ``7``), else
  the stem;
- a historian, ``historian:LOCATION`` (an SQLite file or a ``postgresql://`` URL): every
  run, keyed by its id, its start metadata as labels.

Labels (:func:`read_table`, joined by :func:`build_dataset`) come from a table with one row
per run, matched on a key column. A ``table`` spec reads observations directly: each row of
each file is one row of the dataset.
"""

from __future__ import annotations

import glob
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cnctwin.errors import DataError, InputError
from cnctwin.learn.features import FeaturePath
from cnctwin.learn.schema import FeatureSchema

__all__ = ["Dataset", "Run", "build_dataset", "key_of", "read_runs", "read_table"]

TIME_COLUMN = "time_s"
RUN_COLUMN = "run"
#: The row's index in the dataset: ``--group-by row`` is a random split of rows, for
#: showing what leakage does (docs/learn.md), never for a figure of merit.
ROW_COLUMN = "row"
_SIBLINGS = (".predictions", ".events", ".decisions")
HISTORIAN_PREFIX = "historian:"


@dataclass
class Run:
    """One run: its key, its columns (numbers as float64, text as object) and labels.

    Attributes
    ----------
    key
        The run's key as text (a file's trailing number, a historian run id).
    columns
        Column name -> array, one value per sample (``time_s`` in s where recorded).
    labels
        Per-run values (a historian run's metadata).
    """

    key: str
    columns: dict[str, NDArray[Any]]
    labels: dict[str, object] = field(default_factory=dict)


@dataclass
class Dataset:
    """Rows of features and the columns to pick a target and groups from.

    Attributes
    ----------
    schema
        The feature schema the rows were built with.
    features
        ``(rows, len(schema.names))`` float64.
    columns
        Per row: ``run`` (key), ``row`` (index), every label, and every column of the runs.
    """

    schema: FeatureSchema
    features: NDArray[np.float64]
    columns: dict[str, NDArray[Any]]

    def __len__(self) -> int:
        return int(self.features.shape[0])

    def column(self, name: str, what: str) -> NDArray[Any]:
        """The column ``name``; ``what`` says what it is for in the error.

        Raises
        ------
        cnctwin.errors.InputError
            When there is no such column (the message lists those there are).
        """
        if name not in self.columns:
            raise InputError(
                f"{what} {name!r} is not a column of the data (columns: "
                f"{', '.join(sorted(self.columns))})"
            )
        return self.columns[name]


def read_table(path: str | Path) -> dict[str, NDArray[Any]]:
    """A CSV or Parquet file as columns: numbers float64 (empty cells NaN), text as object.

    Raises
    ------
    cnctwin.errors.DataError
        When the file cannot be read or parsed (one line, naming the file).
    """
    import pyarrow as pa
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    path = Path(path)
    try:
        if path.suffix.lower() == ".parquet":
            table = pq.read_table(path)
        else:
            table = pacsv.read_csv(path)
    except (OSError, pa.ArrowException) as err:
        raise DataError(f"{path}: cannot read the table ({str(err).splitlines()[0]})") from None
    columns: dict[str, NDArray[Any]] = {}
    for name, column in zip(table.column_names, table.columns, strict=True):
        kind = column.type
        if pa.types.is_integer(kind) or pa.types.is_floating(kind) or pa.types.is_null(kind):
            columns[name] = column.to_numpy(zero_copy_only=False).astype(float)
        elif pa.types.is_boolean(kind):
            columns[name] = np.array(column.to_pylist(), dtype=object)
        else:
            columns[name] = np.array(
                ["" if v is None else str(v) for v in column.to_pylist()], dtype=object
            )
    return columns


def key_of(value: object) -> str:
    """A run key as text: ``7.0`` and ``7`` and ``"07"`` are all ``"7"``."""
    if isinstance(value, float | np.floating) and float(value).is_integer():
        return str(int(value))
    text = str(value).strip()
    return str(int(text)) if text.isdigit() else text


def _files(source: str) -> list[Path]:
    path = Path(source)
    if path.is_dir():
        found = sorted([*path.glob("*.csv"), *path.glob("*.parquet")])
    elif any(c in source for c in "*?["):
        found = sorted(Path(p) for p in glob.glob(source))
    elif path.is_file():
        found = [path]
    else:
        raise InputError(
            f"--data {source!r}: no such file, folder or matching files (give a CSV or "
            f"Parquet file, a folder or glob of them, or historian:DB)"
        )
    found = [p for p in found if not any(p.stem.endswith(s) for s in _SIBLINGS)]
    if not found:
        raise InputError(f"--data {source!r}: no CSV or Parquet files there")
    return found


def read_runs(sources: Sequence[str], exclude: Sequence[str | Path] = ()) -> list[Run]:
    """The runs of every source (see the module's description), in the order given; files
    in ``exclude`` (a labels table in the runs' folder) are no runs.

    Raises
    ------
    cnctwin.errors.InputError
        For a source that names nothing; :class:`~cnctwin.errors.DataError` for a file
        that cannot be read or two runs with one key.
    """
    runs: list[Run] = []
    for source in sources:
        if source.startswith(HISTORIAN_PREFIX):
            runs.extend(_historian_runs(source[len(HISTORIAN_PREFIX) :]))
            continue
        skip = {Path(p).resolve() for p in exclude}
        for path in _files(source):
            if path.resolve() in skip:
                continue
            match = re.search(r"(\d+)$", path.stem)
            key = str(int(match.group(1))) if match else path.stem
            runs.append(Run(key, read_table(path)))
    keys = [r.key for r in runs]
    duplicate = next((k for k in keys if keys.count(k) > 1), None)
    if duplicate is not None:
        raise DataError(f"two runs have the key {duplicate!r}; give each run once")
    return runs


def _historian_runs(location: str) -> list[Run]:
    from cnctwin.store import Historian

    runs = []
    with Historian.open(location, create=False) as historian:
        for summary in historian.runs():
            columns = historian.samples(summary.run_id)
            labels = {
                k: v
                for k, v in summary.meta.items()
                if isinstance(v, str | int | float) and not isinstance(v, bool)
            }
            runs.append(Run(str(summary.run_id), dict(columns), labels))
    return runs


def build_dataset(
    runs: Sequence[Run],
    schema: FeatureSchema,
    labels: Mapping[str, NDArray[Any]] | None = None,
    label_key: str | None = None,
) -> Dataset:
    """Rows of features from ``runs`` with labels joined per run.

    Parameters
    ----------
    runs
        The runs (:func:`read_runs`).
    schema
        Which features; a ``series`` schema passes each run through one
        :class:`~cnctwin.learn.FeaturePath` and keeps the valid samples (every
        ``stride``-th); a ``table`` schema keeps each row with finite features.
    labels, label_key
        A table with one row per run and the column holding the run key.

    Raises
    ------
    cnctwin.errors.DataError
        For a run that lacks a signal of the schema, or no rows at all.
    cnctwin.errors.InputError
        For a ``label_key`` that is not a column of ``labels``.
    """
    by_key: dict[str, dict[str, object]] = {}
    if labels is not None:
        if label_key is None or label_key not in labels:
            raise InputError(
                f"--label-key {label_key!r} is not a column of the labels (columns: "
                f"{', '.join(labels)})"
            )
        keys = [key_of(v) for v in labels[label_key]]
        for i, key in enumerate(keys):
            by_key[key] = {name: column[i] for name, column in labels.items()}
    path = FeaturePath(schema)
    blocks: list[NDArray[np.float64]] = []
    parts: list[dict[str, NDArray[Any]]] = []
    for run in runs:
        schema.require_signals(frozenset(run.columns), f"run {run.key}")
        n = len(next(iter(run.columns.values())))
        if schema.spec.kind == "series":
            t = run.columns.get(TIME_COLUMN)
            features, valid = path.batch(run.columns, None if t is None else t.astype(float))
            keep = valid & (np.arange(n) % schema.spec.stride == 0)
        else:
            features = _table_features(run.columns, schema)
            keep = np.all(np.isfinite(features), axis=1)
        index = np.flatnonzero(keep)
        if index.size == 0:
            continue
        blocks.append(features[index])
        part: dict[str, NDArray[Any]] = {
            name: column[index] for name, column in run.columns.items()
        }
        part[RUN_COLUMN] = np.full(index.size, run.key, dtype=object)
        run_labels = {**run.labels, **by_key.get(run.key, {})}
        for name, value in run_labels.items():
            part.setdefault(name, np.full(index.size, value, dtype=object))
        parts.append(part)
    if not blocks:
        raise DataError(
            f"no rows: {len(runs)} run(s) gave no valid sample with every feature finite"
        )
    names = set.intersection(*(set(p) for p in parts))
    columns = {name: _concat([p[name] for p in parts]) for name in sorted(names)}
    columns.setdefault(ROW_COLUMN, np.arange(sum(len(b) for b in blocks)).astype(float))
    return Dataset(schema, np.concatenate(blocks), columns)


def _concat(arrays: list[NDArray[Any]]) -> NDArray[Any]:
    if all(a.dtype.kind == "f" for a in arrays):
        return np.concatenate(arrays)
    return np.concatenate([a.astype(object) for a in arrays])


def _table_features(columns: Mapping[str, NDArray[Any]], schema: FeatureSchema) -> NDArray[Any]:
    spec = schema.spec
    out = []
    for name in spec.signals:
        try:
            out.append(np.asarray(columns[name], dtype=float))
        except (TypeError, ValueError):
            raise DataError(
                f"column {name!r} holds text; give numbers or list it as a category"
            ) from None
    for name, values in spec.categories.items():
        for value in values:
            out.append((np.asarray(columns[name]).astype(str) == value).astype(float))
    return np.stack(out, axis=1)
