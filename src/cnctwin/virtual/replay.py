"""A recorded machine: a log (CSV or Parquet) replayed as the canonical signals (docs/replay.md).

:func:`read_replay_log` reads a log through a :class:`~cnctwin.virtual.replay_map.ReplayMap`
(or, without one, the historian's ``cnctwin runs export`` format) into one array per signal, in
the signal's unit. :class:`ReplayMachine` plays it back tick by tick, sample and hold: after
machine time ``t`` its snapshot is the last row recorded at or before ``t``. It has the virtual
machine's interface (``step``, ``snapshot``, ``command``, ``finished``, ``restart``), so the same
clock (:class:`~cnctwin.virtual.MachineClock`) and servers (OPC UA, Modbus, MTConnect) serve it,
at recorded time or scaled.

What is not in the log is not invented: a signal the mapping does not give reads NaN (a client
sees it as unavailable); ``heartbeat`` counts ticks; ``t_s`` is the row's time since the first
row unless the log has it; ``run_state`` is RUNNING while playing and FINISHED after the last
row unless the log has it. Commands are checked as the virtual machine checks them, accepted
and read back, and change nothing of the recording.

Rows: a null (empty) cell holds the column's previous value (counted); a glitch row (a
``[[glitches]]`` rule of the mapping) is dropped, so the previous row holds through its time
(counted per rule, reported). Memory: the log is read whole, after an estimate is checked
against the work limit (:func:`cnctwin.memory.check_memory`, ``CNCTWIN_MEMORY_LIMIT_GB``).
"""

from __future__ import annotations

import csv
import logging
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cnctwin import memory
from cnctwin.errors import DataError
from cnctwin.thread import COMMANDS, SIGNALS, RunState
from cnctwin.virtual.faults import FaultEvent
from cnctwin.virtual.machine import check_command
from cnctwin.virtual.replay_map import GENERATED, UNITS, GlitchRule, ReplayMap

__all__ = ["ReplayLog", "ReplayMachine", "read_replay_log"]

logger = logging.getLogger(__name__)

#: Bytes of memory per byte of a CSV log while it is read (pyarrow's table with its string
#: columns, the float arrays, the glitch test's cells): the peak resident memory grew by 2.8
#: bytes per byte reading a 67 MB CSV of the UMich files; 8 is the bound checked against the
#: work limit.
CSV_BYTES_PER_BYTE = 8.0
#: Command values before any write: the overrides at 100 %, the flags and offsets at 0.
_COMMAND_DEFAULTS = {name: 100.0 if spec.unit == "%" else 0.0 for name, spec in COMMANDS.items()}


@dataclass(frozen=True)
class ReplayLog:
    """A log read for replay.

    Attributes
    ----------
    path
        The log file.
    times_s
        Row times since the first row, s (non-decreasing), glitch rows removed.
    signals
        Canonical signal -> its values at the rows, in the signal's unit (NaN: not recorded
        yet).
    period_s
        Sample period: the fixed one, else the median step between rows, s (> 0).
    rows_read
        Data rows in the file.
    glitch_rows
        Glitch rule name -> rows it dropped (a row matched by several counts for the first).
    held_cells
        Null cells that held the column's previous value.
    metadata
        The file's per-file constants (``[metadata]`` of the mapping), as text.
    """

    path: Path
    times_s: NDArray[np.float64]
    signals: dict[str, NDArray[np.float64]]
    period_s: float
    rows_read: int
    glitch_rows: dict[str, int] = field(default_factory=dict)
    held_cells: int = 0
    metadata: dict[str, str] = field(default_factory=dict)

    @property
    def rows(self) -> int:
        """Rows replayed (glitch rows removed)."""
        return int(self.times_s.size)

    @property
    def duration_s(self) -> float:
        """Recorded time the replay lasts: the last row's time plus one period, s."""
        return float(self.times_s[-1]) + self.period_s

    def summary(self) -> str:
        """One line: file, rows, period, duration, glitches, held cells, metadata."""
        glitches = sum(self.glitch_rows.values())
        by_rule = ", ".join(f"{n}: {c}" for n, c in self.glitch_rows.items() if c)
        text = (
            f"{self.path.name}: {self.rows} rows of {self.rows_read} replayed, "
            f"{self.period_s * 1e3:g} ms period, {self.duration_s:.1f} s; "
            f"{glitches} glitch rows dropped{f' ({by_rule})' if by_rule else ''}; "
            f"{self.held_cells} empty cells held; signals: {', '.join(self.signals)}"
        )
        if self.metadata:
            text += "; " + ", ".join(f"{k}={v}" for k, v in self.metadata.items())
        return text


def read_replay_log(path: str | Path, mapping: ReplayMap | None = None) -> ReplayLog:
    """Read a recorded log (CSV or Parquet) into canonical signals.

    Parameters
    ----------
    path
        ``.csv`` or ``.parquet``.
    mapping
        How columns become signals (docs/replay.md); ``None``: the historian's export format
        (``time_s`` and columns named like canonical signals).

    Returns
    -------
    ReplayLog
        The rows to replay.

    Raises
    ------
    DataError
        One line naming the file (and the column, and the row where one is at fault): an
        unreadable or unknown file type, a missing or non-numeric column, a time that goes
        back, no row left.
    ConfigError
        When the estimated memory exceeds the work limit.
    """
    path = Path(path)
    kind = path.suffix.lower().lstrip(".")
    if kind not in ("csv", "parquet"):
        raise DataError(f"{path}: a replay log is .csv or .parquet, not {path.suffix or 'none'!r}")
    header, estimate = _header(path, kind)
    identity = mapping is None
    if mapping is None:
        names = [c for c in header if c in SIGNALS and c not in GENERATED]
        if not names:
            raise DataError(
                f"{path}: no column is a canonical signal (e.g. x_mm, spindle_rpm); "
                "give a mapping (--map) for a foreign log"
            )
        mapping = ReplayMap.model_validate({"signals": {n: {"column": n} for n in names}})
    timing = mapping.log
    time_column = timing.time_column if timing.period_s is None else None
    wanted: list[str] = []
    for needed in (
        [time_column] if time_column else [],
        *(source.columns for source in mapping.signals.values()),
        *(rule.columns for rule in mapping.glitches),
    ):
        wanted.extend(c for c in needed if c not in wanted)
    for column in wanted:
        if column not in header:
            raise DataError(f"{path}: column {column!r} is missing (it has {len(header)} columns)")
    memory.check_memory(
        f"replay log {path} ({estimate:.3g} bytes to read)",
        estimate,
        lambda fits: f"replay a log {fits:.2g} times as large, or a shorter one",
    )
    table = _read(path, kind, wanted)
    rows = table.num_rows
    if rows == 0:
        raise DataError(f"{path}: no data rows")
    numeric = {c for s in mapping.signals.values() for c in s.columns}
    if time_column:
        numeric.add(time_column)
    columns: dict[str, NDArray[np.float64]] = {}
    held = 0
    for name in numeric:
        values, nulls = _numeric(table.column(name), name, path, kind)
        columns[name] = values
        if name != time_column:
            held += int(nulls.sum())
    keep = np.ones(rows, dtype=bool)
    glitches: dict[str, int] = {}
    for rule in mapping.glitches:
        hit = _glitch_mask(rule, table, path) & keep
        glitches[rule.name] = glitches.get(rule.name, 0) + int(hit.sum())
        keep &= ~hit
    if not keep.any():
        raise DataError(f"{path}: every one of its {rows} rows is a glitch row")
    if time_column:
        times = columns[time_column] * UNITS[timing.time_unit][1]
        _check_times(times, time_column, path, kind)
        times = times[keep]
        steps = np.diff(times)
        steps = steps[steps > 0.0]
        if steps.size == 0:
            raise DataError(f"{path}: column {time_column!r} does not advance; give period_s")
        period = float(np.median(steps))
    else:
        assert timing.period_s is not None
        period = timing.period_s
        times = np.flatnonzero(keep).astype(np.float64) * period
    times = times - times[0]
    signals: dict[str, NDArray[np.float64]] = {}
    for name, source in mapping.signals.items():
        if source.value is not None:
            signals[name] = np.full(times.size, source.value)
            continue
        parts = [columns[c][keep] for c in source.columns]
        raw = parts[0] if source.column is not None else np.sqrt(sum(p * p for p in parts))
        signals[name] = np.asarray(raw * mapping.factor(name), dtype=np.float64)
    meta = _metadata(mapping, path) if not identity else {}
    return ReplayLog(path, times, signals, period, rows, glitches, held, meta)


def _header(path: Path, kind: str) -> tuple[list[str], float]:
    """The log's column names and the estimated bytes of reading it."""
    try:
        if kind == "parquet":
            import pyarrow.parquet as pq

            meta = pq.ParquetFile(path).metadata
            return list(meta.schema.names), 16.0 * meta.num_rows * meta.num_columns
        with path.open(newline="", encoding="utf-8") as text:
            first = next(csv.reader(text), None)
        return (first or []), CSV_BYTES_PER_BYTE * path.stat().st_size
    except OSError as err:
        raise DataError(f"{path}: cannot read the log: {err.strerror or err}") from err
    except (UnicodeDecodeError, csv.Error) as err:
        raise DataError(f"{path}: not a CSV text file: {err}") from err
    except Exception as err:  # pyarrow's errors on a file that is not Parquet
        raise DataError(f"{path}: not a Parquet file: {_one_line(err)}") from err


def _read(path: Path, kind: str, columns: list[str]) -> Any:
    """The columns of the log as a pyarrow table."""
    import pyarrow as pa
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    try:
        if kind == "parquet":
            return pq.read_table(path, columns=columns)
        return pacsv.read_csv(path, convert_options=pacsv.ConvertOptions(include_columns=columns))
    except (OSError, pa.ArrowException) as err:
        raise DataError(f"{path}: cannot read the log: {_one_line(err)}") from err


def _numeric(
    column: Any, name: str, path: Path, kind: str
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """A column as floats, each null holding the previous value (NaN before the first), and
    where the nulls were; DataError naming the first cell that is not a number."""
    import pyarrow as pa

    if not (pa.types.is_floating(column.type) or pa.types.is_integer(column.type)) and not (
        pa.types.is_null(column.type)
    ):
        for row, cell in enumerate(column.to_pylist()):
            if cell is None:
                continue
            try:
                float(cell)
            except (TypeError, ValueError):
                where = f"line {row + 2}" if kind == "csv" else f"row {row + 1}"
                raise DataError(
                    f"{path}: column {name!r} is not numeric ({where}: {str(cell)[:40]!r})"
                ) from None
        raise DataError(f"{path}: column {name!r} is not numeric (type {column.type})")
    nulls = column.is_null().to_numpy(zero_copy_only=False)
    values = column.to_numpy(zero_copy_only=False).astype(np.float64)
    values[nulls] = np.nan
    if nulls.any():
        last = np.where(~nulls, np.arange(values.size), 0)
        np.maximum.accumulate(last, out=last)
        filled = values[last]
        filled[np.cumsum(~nulls) == 0] = np.nan
        values = filled
    return values, nulls


def _check_times(times: NDArray[np.float64], name: str, path: Path, kind: str) -> None:
    bad = np.flatnonzero(~np.isfinite(times))
    back = np.flatnonzero(np.diff(times) < 0.0) + 1 if times.size > 1 else np.array([], int)
    for rows, why in ((bad, "is not a finite time"), (back, "goes back in time")):
        if rows.size:
            row = int(rows[0])
            where = f"line {row + 2}" if kind == "csv" else f"row {row + 1}"
            raise DataError(f"{path}: column {name!r} {why} at {where} ({times[row]!r})")


def _glitch_mask(rule: GlitchRule, table: Any, path: Path) -> NDArray[np.bool_]:
    """Rows for which every condition of ``rule`` holds."""
    mask = np.ones(table.num_rows, dtype=bool)
    conditions = [(c, [v]) for c, v in rule.equals.items()] + list(rule.one_of.items())
    for column, values in conditions:
        cells = table.column(column).to_pylist()
        mask &= np.fromiter((_matches(cell, values) for cell in cells), bool, len(cells))
    return mask


def _matches(cell: object, values: list[float | str]) -> bool:
    for value in values:
        if isinstance(value, str):
            if cell is not None and str(cell) == value:
                return True
        elif isinstance(cell, int | float) and not isinstance(cell, bool) and cell == value:
            return True
    return False


def _metadata(mapping: ReplayMap, path: Path) -> dict[str, str]:
    """The log's row of the mapping's metadata table (empty without one)."""
    meta = mapping.metadata
    if meta is None:
        return {}
    found = re.search(meta.file_pattern, path.name)
    if found is None:
        raise DataError(
            f"{path}: the file name does not match the mapping's file_pattern {meta.file_pattern!r}"
        )
    table = meta.table if meta.table.is_absolute() else path.parent / meta.table
    try:
        key = float(found.group(1))
        with table.open(newline="", encoding="utf-8") as text:
            for row in csv.DictReader(text):
                if meta.key_column not in row:
                    raise DataError(f"{table}: column {meta.key_column!r} is missing")
                try:
                    if float(row[meta.key_column]) == key:
                        return {k: v for k, v in row.items() if k != meta.key_column}
                except ValueError:
                    continue
    except OSError as err:
        raise DataError(f"{table}: cannot read the metadata table: {err.strerror}") from err
    except ValueError:
        raise DataError(f"{path}: {found.group(1)!r} in its name is not a number") from None
    raise DataError(f"{table}: no row with {meta.key_column} = {found.group(1)} for {path.name}")


def _one_line(err: BaseException) -> str:
    return " ".join(str(err).split())[:300] or type(err).__name__


class ReplayMachine:
    """A recorded log played back as a machine, tick by tick, sample and hold.

    Parameters
    ----------
    log
        The log (:func:`read_replay_log`).
    loop
        Start again from the first row after the last (a new program run: ``t_s`` restarts,
        ``heartbeat`` keeps counting); otherwise the last row holds and the run is finished.

    Notes
    -----
    Before the first step the snapshot is the first row; after steps adding up to ``t`` s it
    is the last row recorded at or before ``t``. The clock steps it by :attr:`tick_s`, the
    log's sample period, so every row is served once (a log with uneven steps: every row at
    least one period after the one shown before it).
    """

    def __init__(self, log: ReplayLog, loop: bool = False) -> None:
        self.log = log
        self.loop = loop
        self.passes = 0
        self._commands = dict(_COMMAND_DEFAULTS)
        self._heartbeat = 0
        self._unmapped = {n: math.nan for n in SIGNALS if n not in log.signals}
        self._columns = list(log.signals.items())
        self._start()

    def _start(self) -> None:
        self._t = 0.0
        self._index = 0
        self._over = False

    @property
    def tick_s(self) -> float:
        """The log's sample period: machine time per clock tick, s."""
        return self.log.period_s

    @property
    def time_s(self) -> float:
        """Machine time since the start of this pass through the log, s."""
        return self._t

    @property
    def index(self) -> int:
        """The row served now (0-based, glitch rows removed)."""
        return self._index

    @property
    def finished(self) -> bool:
        """Whether the log has been played to its end (never with ``loop``)."""
        return self._over

    @property
    def run_state(self) -> RunState:
        """RUNNING while playing, FINISHED after the last row."""
        return RunState.FINISHED if self._over else RunState.RUNNING

    @property
    def fault_events(self) -> list[FaultEvent]:
        """Injected faults: none (a recording has what it recorded)."""
        return []

    def restart(self) -> None:
        """Play the log again from its first row (commands keep their values)."""
        self._start()

    def step(self, dt_s: float) -> None:
        """Advance by ``dt_s`` seconds of recorded time.

        Raises
        ------
        DataError
            On a step that is not finite and > 0.
        """
        if not (math.isfinite(dt_s) and dt_s > 0.0):
            raise DataError(f"step(dt_s={dt_s!r}); give a finite tick > 0 s")
        self._heartbeat += 1
        if self._over:
            return
        t = self._t + dt_s
        times = self.log.times_s
        if t >= self.log.duration_s - 1e-9 * (1.0 + t):
            if not self.loop:
                self._t = t
                self._over = True
                return
            self.passes += 1
            self._start()
            return
        slack = 1e-9 * (1.0 + t)
        index = self._index
        while index + 1 < times.size and times[index + 1] <= t + slack:
            index += 1
        self._t = t
        self._index = index

    def snapshot(self) -> dict[str, float]:
        """Every signal of :data:`~cnctwin.thread.SIGNALS` at the row served now.

        Returns
        -------
        dict
            Signal name -> value in the signal's unit; NaN where the log does not give it.
        """
        k = self._index
        values = dict(self._unmapped)
        values["t_s"] = float(self.log.times_s[k])
        values["run_state"] = float(self.run_state)
        for name, column in self._columns:
            values[name] = float(column[k])
        values.update(self._commands)
        values["heartbeat"] = float(self._heartbeat)
        return values

    def command(self, name: str, value: float) -> None:
        """Accept a command and read it back; the recording does not change.

        Raises
        ------
        ConfigError
            As the virtual machine (:func:`~cnctwin.virtual.machine.check_command`).
        """
        self._commands[name] = check_command(name, value)
