"""The historian: every run of the twin (signals, predictions, events, decisions) in SQLite
or PostgreSQL, written in batches by a background thread, off the twin cycle's critical path.

``record_*`` calls only encode their arguments and append them to an in-memory queue (a few
microseconds); a writer thread wakes at least every ``flush_interval_s`` (default 0.25 s), or
when ``batch_size`` items are queued, and commits everything queued in one transaction. A
killed process therefore loses at most the last interval and one write. The twin never waits
for the database: when the queue holds ``max_pending`` items (a database that stalls or is
down) further items are dropped and counted in :meth:`Historian.stats`.

Each recorded instant is one row whose values are a little-endian float64 blob in the order
of a *layout* (its ordered signal names, stored once) — see ``docs/historian.md`` for the
schema and the measurements that chose it. Values come back bit-exact, NaN included.
"""

from __future__ import annotations

import atexit
import json
import logging
import math
import threading
import time
from collections.abc import Iterable, Mapping, Sequence
from itertools import count
from pathlib import Path
from typing import Any

import numpy as np
import platformdirs
from pydantic import ValidationError

from cnctwin import finite_json
from cnctwin.errors import ConfigError, DataError
from cnctwin.store._backend import Backend, FrameRow
from cnctwin.store._export import write_run
from cnctwin.store._overview import RunOverview, compute_overview
from cnctwin.store._records import (
    DecisionRecord,
    EventRecord,
    HistorianStats,
    RunDetail,
    RunSummary,
)
from cnctwin.store._sqlite import SqliteBackend
from cnctwin.store.config import HistorianConfig

__all__ = [
    "TIME_COLUMN",
    "DecisionRecord",
    "EventRecord",
    "Historian",
    "HistorianStats",
    "RunDetail",
    "RunSummary",
    "default_database_path",
]

logger = logging.getLogger(__name__)

#: Name of the record-time column of :meth:`Historian.samples` and of exported tables, s
#: (reserved: no signal may be called so).
TIME_COLUMN = "time_s"

_SAMPLE, _PREDICTION, _EVENT, _DECISION, _FLUSH = 0, 1, 2, 3, 4
_KIND_NAMES = {_SAMPLE: "samples", _PREDICTION: "predictions"}
_FLOAT64 = np.dtype("<f8")

_INSERT_EVENT = (
    "INSERT INTO hist_events (run_id, seq, t_s, kind, message, data) VALUES (?, ?, ?, ?, ?, ?)"
)
_INSERT_DECISION = (
    "INSERT INTO hist_decisions (run_id, seq, t_s, rule, action, value, reason, accepted, "
    "readback) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)"
)
_RUNS = """SELECT r.id, r.status, r.started_at, r.ended_at, r.meta, r.summary,
 (SELECT COUNT(*) FROM hist_events e WHERE e.run_id = r.id),
 (SELECT COUNT(*) FROM hist_decisions d WHERE d.run_id = r.id)
FROM hist_runs r"""
#: One layout a run used: (kind, layout id, frames, first seq, last time s).
_LayoutCount = tuple[int, int, int, int, float]
#: Per run, kind and layout: frames, first sequence number and last time (index only).
_LAYOUT_COUNTS = """SELECT run_id, kind, layout_id, COUNT(*), MIN(seq), MAX(t_s)
FROM hist_frames {where} GROUP BY run_id, kind, layout_id"""


def default_database_path() -> Path:
    """The installation's historian file: ``historian.sqlite`` in the user's data folder.

    Returns
    -------
    Path
        E.g. ``~/.local/share/cnctwin/historian.sqlite`` on Linux (platformdirs).
    """
    return platformdirs.user_data_path("cnctwin", appauthor=False) / "historian.sqlite"


def _backend_for(url_or_path: str | Path | None, create: bool) -> Backend:
    """The backend a URL or path names."""
    if url_or_path is None:
        return SqliteBackend(default_database_path(), create=create)
    text = str(url_or_path)
    if "://" not in text:
        return SqliteBackend(Path(text).expanduser(), create=create)
    scheme = text.split("://", 1)[0].lower()
    if scheme in ("postgresql", "postgres"):
        from cnctwin.store._postgres import PostgresBackend

        return PostgresBackend(text)
    raise ConfigError(
        f"historian url scheme {scheme!r} is not supported; give an SQLite file path or "
        "postgresql://USER@HOST:PORT/DATABASE"
    )


def _finite(value: object, what: str) -> float:
    """``value`` as a finite float, or a DataError naming ``what``."""
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        number = math.nan
    if not math.isfinite(number):
        raise DataError(f"{what} must be a finite number; got {value!r}")
    return number


def _json(value: Mapping[str, object] | None, what: str) -> str:
    try:
        return finite_json.dumps(dict(value or {}), default=str)
    except (TypeError, ValueError) as err:
        raise DataError(f"{what} must be a JSON-serialisable mapping: {err}") from None


class Historian:
    """Records the twin's runs; read them back with :meth:`runs`, :meth:`run`, :meth:`samples`.

    Use :meth:`open` (or :meth:`from_config`), preferably as a context manager. ``record_*``
    may be called from any thread; queries share one connection under a lock.
    """

    def __init__(
        self,
        backend: Backend,
        *,
        create: bool = True,
        flush_interval_s: float = 0.25,
        batch_size: int = 2000,
        max_pending: int = 1_000_000,
    ) -> None:
        try:
            cfg = HistorianConfig(
                flush_interval_s=flush_interval_s, batch_size=batch_size, max_pending=max_pending
            )
        except ValidationError as err:
            first = err.errors()[0]
            raise ConfigError(
                f"historian {first['loc'][0]} = {first['input']!r}: {first['msg']}"
            ) from None
        self._backend = backend
        self._interval = cfg.flush_interval_s
        self._batch_size = cfg.batch_size
        self._max_pending = cfg.max_pending
        self._conn = backend.connect()
        self._db_lock = threading.Lock()
        try:
            if create:
                backend.create_schema(self._conn)
            else:
                backend.query(self._conn, "SELECT id FROM hist_runs WHERE id = 0")
        except backend.errors as err:
            self._conn.close()
            raise DataError(
                f"{backend.label}: cannot be used as a cnctwin historian database "
                f"({_one_line(err)})"
            ) from None
        self._seq = count()
        self._lock = threading.Lock()
        self._pending: list[tuple[Any, ...]] = []
        self._wake = threading.Event()
        self._stopping = False
        self._closed = False
        self._dropped = 0
        self._dropped_seen = 0
        self._drop_logged = False
        self._written_items = 0
        self._written_values = 0
        self._batches = 0
        self._last_error: str | None = None
        self._layouts: dict[tuple[str, ...], int] = {}
        self._names_of_layout: dict[int, tuple[str, ...]] = {}
        self._writer = threading.Thread(
            target=self._write_loop, name="cnctwin-historian", daemon=True
        )
        self._writer.start()
        atexit.register(self.close)
        logger.debug("historian at %s", backend.label)

    # ------------------------------------------------------------------ opening
    @classmethod
    def open(
        cls,
        url_or_path: str | Path | None = None,
        *,
        create: bool = True,
        flush_interval_s: float = 0.25,
        batch_size: int = 2000,
        max_pending: int = 1_000_000,
    ) -> Historian:
        """Open (and create) a historian.

        Parameters
        ----------
        url_or_path
            An SQLite file path or ``postgresql://USER@HOST:PORT/DB``; None takes
            :func:`default_database_path`.
        create
            Create the file and the tables when missing; False for read-only tools.
        flush_interval_s, batch_size, max_pending
            The writer's settings, see :class:`~cnctwin.store.config.HistorianConfig`.

        Raises
        ------
        ConfigError
            For a URL scheme other than ``postgresql``, or writer settings out of range.
        DataError
            For a file that is not a database, a missing file with ``create=False``, or a
            server that cannot be reached.
        """
        return cls(
            _backend_for(url_or_path, create),
            create=create,
            flush_interval_s=flush_interval_s,
            batch_size=batch_size,
            max_pending=max_pending,
        )

    @classmethod
    def from_config(cls, config: HistorianConfig) -> Historian:
        """Open the historian a ``[historian]`` table describes."""
        return cls.open(
            config.url,
            flush_interval_s=config.flush_interval_s,
            batch_size=config.batch_size,
            max_pending=config.max_pending,
        )

    @property
    def location(self) -> str:
        """Where the data goes: the SQLite path, or the URL without its password."""
        return self._backend.label

    def __enter__(self) -> Historian:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ runs
    def start_run(self, meta: Mapping[str, object]) -> int:
        """Begin a run (synchronously) and return its id.

        Parameters
        ----------
        meta
            What describes the run: program, config path, machine endpoint, ... (JSON;
            other values are stored as their text).
        """
        meta_json = _json(meta, "run meta")
        rows = self._read(
            "INSERT INTO hist_runs (started_at, status, meta) VALUES (?, 'running', ?) "
            "RETURNING id",
            (time.time(), meta_json),
            write=True,
        )
        run_id = int(rows[0][0])
        logger.info("run %d started in %s", run_id, self.location)
        return run_id

    def end_run(
        self, run_id: int, status: str = "finished", summary: Mapping[str, object] | None = None
    ) -> None:
        """Commit what is queued, then close the run with its status and summary.

        The run is closed even when records were dropped (a warning is logged; see
        :meth:`stats`).

        Parameters
        ----------
        run_id
            A run of :meth:`start_run`.
        status
            E.g. ``"finished"``, ``"stopped"``, ``"failed"``.
        summary
            Figures of the run (JSON).
        """
        if not status:
            raise DataError("run status must be a non-empty text such as 'finished'")
        summary_json = _json(summary, "run summary")
        self._sync()
        if self._dropped:
            logger.warning(
                "run %s ends with %d records dropped by the historian", run_id, self._dropped
            )
        rows = self._read(
            "UPDATE hist_runs SET ended_at = ?, status = ?, summary = ? WHERE id = ? RETURNING id",
            (time.time(), status, summary_json, int(run_id)),
            write=True,
        )
        if not rows:
            raise self._unknown_run(run_id)
        for kind in (_SAMPLE, _PREDICTION):
            try:
                self._write_overview(int(run_id), kind)
            except DataError as err:
                logger.warning("run %s: no overview of its %s: %s", run_id, _KIND_NAMES[kind], err)

    # ------------------------------------------------------------------ recording
    def record_samples(self, run_id: int, t_s: float, values: Mapping[str, float]) -> None:
        """Queue measured signal values of one instant (returns in microseconds).

        Parameters
        ----------
        run_id
            A run of :meth:`start_run`.
        t_s
            Twin time of the instant, s (finite).
        values
            Canonical signal name -> value (anything ``float()`` takes; None becomes NaN).
        """
        self._frame(_SAMPLE, run_id, t_s, values)

    def record_prediction(self, run_id: int, t_s: float, values: Mapping[str, float]) -> None:
        """Queue predicted signal values of one instant, kept apart from the measured ones."""
        self._frame(_PREDICTION, run_id, t_s, values)

    def record_event(
        self,
        run_id: int,
        t_s: float,
        kind: str,
        message: str,
        data: Mapping[str, object] | None = None,
    ) -> None:
        """Queue an event (connection lost, anomaly, program end, ...).

        Parameters
        ----------
        run_id, t_s
            The run; twin time, s.
        kind
            Short category, e.g. ``"connection"``, ``"anomaly"``.
        message
            One human-readable line.
        data
            Details (JSON).
        """
        t = _finite(t_s, "event time t_s")
        self._put(
            (
                _EVENT,
                int(run_id),
                next(self._seq),
                t,
                str(kind),
                str(message),
                _json(data, "event data"),
            )
        )

    def record_decision(
        self,
        run_id: int,
        t_s: float,
        rule: str,
        action: str,
        value: float,
        reason: str,
        accepted: bool,
        readback: float | None = None,
    ) -> None:
        """Queue a decision of the rule engine with its reason and the machine's read-back.

        Parameters
        ----------
        run_id, t_s
            The run; twin time, s.
        rule
            Name of the rule that fired.
        action
            The command, e.g. ``"feed_override_pct"`` or ``"stop"``.
        value
            Commanded value in the command's unit (finite).
        reason
            Why, with the values that caused it.
        accepted
            Whether the safety filter let it through.
        readback
            The machine's confirmed value; None (or NaN) when not read back.
        """
        t = _finite(t_s, "decision time t_s")
        commanded = _finite(value, f"decision value of {action!r}")
        try:
            back = None if readback is None else float(readback)
        except (TypeError, ValueError):
            raise DataError(
                f"read-back of {action!r} must be a number or None; got {readback!r}"
            ) from None
        if back is not None and not math.isfinite(back):
            back = None
        self._put(
            (
                _DECISION,
                int(run_id),
                next(self._seq),
                t,
                str(rule),
                str(action),
                commanded,
                str(reason),
                int(bool(accepted)),
                back,
            )
        )

    def _frame(self, kind: int, run_id: int, t_s: float, values: Mapping[str, float]) -> None:
        try:
            ok = math.isfinite(t_s)
        except TypeError:
            ok = False
        if not ok:
            raise DataError(f"sample time t_s must be a finite number of seconds; got {t_s!r}")
        try:
            blob = np.fromiter(values.values(), dtype=_FLOAT64, count=len(values)).tobytes()
        except (TypeError, ValueError):
            raise DataError(_bad_values(values)) from None
        names = tuple(values)
        if TIME_COLUMN in values:
            raise DataError(f"signal name {TIME_COLUMN!r} is reserved for the record time")
        self._put((kind, int(run_id), next(self._seq), float(t_s), names, blob))

    def _put(self, item: tuple[Any, ...]) -> None:
        with self._lock:
            if self._closed:
                raise DataError(f"historian {self.location} is closed; open it again to record")
            if len(self._pending) >= self._max_pending:
                self._dropped += 1
                if not self._drop_logged:
                    self._drop_logged = True
                    logger.warning(
                        "historian queue full (%d items, %s slow or down): dropping records",
                        self._max_pending,
                        self.location,
                    )
                return
            self._pending.append(item)
            n = len(self._pending)
        if n == self._batch_size:
            self._wake.set()

    def flush(self, timeout_s: float = 10.0) -> None:
        """Wait until everything queued so far is committed.

        Raises
        ------
        DataError
            When it is not committed within ``timeout_s`` (s), or when records were dropped
            since the previous flush.
        """
        self._sync(timeout_s)
        dropped, self._dropped_seen = self._dropped - self._dropped_seen, self._dropped
        if dropped:
            raise DataError(
                f"historian {self.location}: {dropped} records were dropped since the last flush "
                f"(last error: {self._last_error or 'queue full'})"
            )

    def _sync(self, timeout_s: float = 10.0) -> None:
        """Wait until what this historian queued so far is committed (read your writes)."""
        marker = threading.Event()
        with self._lock:
            if self._closed:
                raise DataError(f"historian {self.location} is closed; open it again")
            self._pending.append((_FLUSH, marker))
        self._wake.set()
        if not marker.wait(timeout_s):
            raise DataError(
                f"historian {self.location}: queued records not committed within {timeout_s} s "
                f"(last error: {self._last_error or 'none'})"
            )

    def stats(self) -> HistorianStats:
        """The writer's counters."""
        with self._lock:
            pending = len(self._pending)
        return HistorianStats(
            pending,
            self._written_items,
            self._written_values,
            self._dropped,
            self._batches,
            self._last_error,
        )

    def close(self) -> None:
        """Commit what is queued (waiting up to 10 s), stop the writer, close the database."""
        if self._closed:
            return
        atexit.unregister(self.close)
        try:
            self.flush()
        except DataError as err:
            logger.error("%s", err)
        with self._lock:
            self._closed = True
            self._stopping = True
        self._wake.set()
        self._writer.join(timeout=2 * self._interval + 10.0)
        with self._db_lock:
            self._conn.close()

    # ------------------------------------------------------------------ writer thread
    def _write_loop(self) -> None:
        conn = None
        while True:
            self._wake.wait(self._interval)
            self._wake.clear()
            with self._lock:
                batch, self._pending = self._pending, []
                stopping = self._stopping
            if batch:
                conn = self._write(conn, batch, stopping)
            if stopping:
                break
        if conn is not None:
            conn.close()

    def _write(self, conn: Any, batch: list[tuple[Any, ...]], last: bool) -> Any:
        """Commit ``batch`` in one transaction; return the connection to use next."""
        backend = self._backend
        frames = [item for item in batch if item[0] <= _PREDICTION]
        events = [item[1:] for item in batch if item[0] == _EVENT]
        decisions = [item[1:] for item in batch if item[0] == _DECISION]
        markers = [item[1] for item in batch if item[0] == _FLUSH]
        new_layouts: dict[tuple[str, ...], int] = {}
        retry: tuple[type[BaseException], ...] = (*backend.transient, DataError)
        try:
            if conn is None:
                conn = backend.connect()
            with backend.transaction(conn):
                rows: list[FrameRow] = []
                for kind, run_id, seq, t_s, names, blob in frames:
                    layout = self._layouts.get(names) or new_layouts.get(names)
                    if layout is None:
                        layout = new_layouts[names] = self._layout_id(conn, names)
                    rows.append((run_id, kind, seq, t_s, layout, blob))
                if rows:
                    backend.insert_frames(conn, rows)
                if events:
                    backend.executemany(conn, _INSERT_EVENT, events)
                if decisions:
                    backend.executemany(conn, _INSERT_DECISION, decisions)
        except retry as err:
            self._last_error = _one_line(err)
            if conn is not None:
                conn.close()
            if last:
                self._dropped += len(batch) - len(markers)
                logger.error("historian %s: records lost at close: %s", backend.label, err)
                for marker in markers:
                    marker.set()
            else:
                logger.warning("historian %s: will retry: %s", backend.label, self._last_error)
                with self._lock:
                    self._pending[:0] = batch
            return None
        except backend.errors as err:
            self._last_error = _one_line(err)
            self._dropped += len(batch) - len(markers)
            logger.error("historian %s: batch refused, dropped: %s", backend.label, err)
        else:
            self._layouts.update(new_layouts)
            self._batches += 1
            self._written_items += len(frames) + len(events) + len(decisions)
            self._written_values += sum(len(item[5]) for item in frames) // _FLOAT64.itemsize
            self._drop_logged = False
        for marker in markers:
            marker.set()
        return conn

    def _layout_id(self, conn: Any, names: tuple[str, ...]) -> int:
        backend = self._backend
        text = json.dumps(list(names))
        conn.execute(
            backend.sql(
                "INSERT INTO hist_layouts (names) VALUES (?) ON CONFLICT (names) DO NOTHING"
            ),
            (text,),
        )
        return int(
            backend.query(conn, "SELECT id FROM hist_layouts WHERE names = ?", (text,))[0][0]
        )

    # ------------------------------------------------------------------ queries
    def _read(
        self, sql: str, args: tuple[Any, ...] = (), *, write: bool = False
    ) -> list[tuple[Any, ...]]:
        backend = self._backend
        with self._db_lock:
            if self._closed:
                raise DataError(f"historian {self.location} is closed; open it again to read")
            try:
                return self._query(sql, args, write)
            except backend.transient as err:
                if not _connection_lost(self._conn):
                    raise DataError(f"historian {self.location}: {_one_line(err)}") from None
                logger.warning("historian %s: reconnecting: %s", self.location, _one_line(err))
                self._conn = backend.connect()
            except backend.errors as err:
                raise DataError(f"historian {self.location}: {_one_line(err)}") from None
            try:
                return self._query(sql, args, write)
            except backend.errors as err:
                raise DataError(f"historian {self.location}: {_one_line(err)}") from None

    def _query(self, sql: str, args: tuple[Any, ...], write: bool) -> list[tuple[Any, ...]]:
        if write:
            with self._backend.transaction(self._conn):
                return self._backend.query(self._conn, sql, args)
        return self._backend.query(self._conn, sql, args)

    def _unknown_run(self, run_id: object) -> DataError:
        low, high, n = self._read("SELECT MIN(id), MAX(id), COUNT(*) FROM hist_runs")[0]
        there = f"{n} runs there, ids {low}..{high}" if n else "no runs there yet"
        return DataError(f"run {run_id!r} is not in the historian {self.location} ({there})")

    def runs(self) -> list[RunSummary]:
        """Every run, oldest first (after committing this historian's queue)."""
        self._sync()
        counts = self._layout_counts(None)
        return [
            self._run_summary(row, counts.get(int(row[0]), []))
            for row in self._read(_RUNS + " ORDER BY r.id")
        ]

    def _summary(self, run_id: int) -> tuple[RunSummary, list[_LayoutCount]]:
        """A run's summary, and its layout counts (:meth:`_layout_counts`)."""
        self._sync()
        rows = self._read(_RUNS + " WHERE r.id = ?", (int(run_id),))
        if not rows:
            raise self._unknown_run(run_id)
        counts = self._layout_counts(run_id).get(int(run_id), [])
        return self._run_summary(rows[0], counts), counts

    def _layout_counts(self, run_id: int | None) -> dict[int, list[_LayoutCount]]:
        """Per run: (kind, layout id, frames, first seq, last time s) of each layout it used
        (a closed run's from ``hist_run_layouts``, others counted from the index)."""
        where, args = ("", ()) if run_id is None else ("WHERE run_id = ?", (int(run_id),))
        try:
            rows = self._read(
                "SELECT run_id, kind, layout_id, frames, first_seq, last_t_s "
                f"FROM hist_run_layouts {where}",
                args,
            )
        except DataError:  # a database from before hist_run_layouts
            rows = []
        ids = (
            [int(r[0]) for r in self._read("SELECT id FROM hist_runs")]
            if run_id is None
            else [int(run_id)]
        )
        cached = {int(r[0]) for r in rows}
        for missing in (i for i in ids if i not in cached):
            rows += self._read(_LAYOUT_COUNTS.format(where="WHERE run_id = ?"), (missing,))
        counts: dict[int, list[_LayoutCount]] = {}
        for run, kind, layout, n, first, last in rows:
            counts.setdefault(int(run), []).append(
                (int(kind), int(layout), int(n), int(first), float(last))
            )
        return counts

    def _layout_names(self, layout_ids: Iterable[int]) -> dict[int, tuple[str, ...]]:
        """The signal names of layouts (read once: a layout never changes)."""
        ids = [int(i) for i in layout_ids]
        missing = sorted(set(ids) - self._names_of_layout.keys())
        if missing:
            marks = ", ".join("?" * len(missing))
            for i, text in self._read(
                f"SELECT id, names FROM hist_layouts WHERE id IN ({marks})", tuple(missing)
            ):
                self._names_of_layout[int(i)] = tuple(json.loads(text))
        return {i: self._names_of_layout[i] for i in ids}

    def _run_summary(self, row: Sequence[Any], counts: Sequence[_LayoutCount]) -> RunSummary:
        """A run's summary from its ``hist_runs`` row and its layout counts."""
        widths = {i: len(names) for i, names in self._layout_names(c[1] for c in counts).items()}
        measured = [c for c in counts if c[0] == _SAMPLE]
        return RunSummary(
            run_id=int(row[0]),
            status=row[1],
            started_at=float(row[2]),
            ended_at=None if row[3] is None else float(row[3]),
            meta=json.loads(row[4]),
            summary=None if row[5] is None else json.loads(row[5]),
            frames=sum(c[2] for c in measured),
            values=sum(c[2] * widths[c[1]] for c in measured),
            predicted_values=sum(c[2] * widths[c[1]] for c in counts if c[0] == _PREDICTION),
            events=int(row[6]),
            decisions=int(row[7]),
            last_t_s=max((c[4] for c in measured), default=None),
        )

    def _names(self, counts: Sequence[_LayoutCount], kind: int) -> tuple[str, ...]:
        """The signal names of one kind, in the order a run first recorded them."""
        used = sorted((first, layout) for k, layout, _, first, _ in counts if k == kind)
        layouts = self._layout_names(layout for _, layout in used)
        names: dict[str, None] = {}
        for _, layout in used:
            names.update(dict.fromkeys(layouts[layout]))
        return tuple(names)

    def run(self, run_id: int) -> RunDetail:
        """A run: its summary, signal names, events and decisions.

        Raises
        ------
        DataError
            For an unknown run id.
        """
        summary, counts = self._summary(run_id)
        events = [
            EventRecord(int(r[0]), float(r[1]), r[2], r[3], json.loads(r[4]))
            for r in self._read(
                "SELECT seq, t_s, kind, message, data FROM hist_events WHERE run_id = ? "
                "ORDER BY seq",
                (int(run_id),),
            )
        ]
        decisions = [
            DecisionRecord(
                int(r[0]),
                float(r[1]),
                r[2],
                r[3],
                float(r[4]),
                r[5],
                bool(r[6]),
                None if r[7] is None else float(r[7]),
            )
            for r in self._read(
                "SELECT seq, t_s, rule, action, value, reason, accepted, readback "
                "FROM hist_decisions WHERE run_id = ? ORDER BY seq",
                (int(run_id),),
            )
        ]
        return RunDetail(
            summary,
            self._names(counts, _SAMPLE),
            self._names(counts, _PREDICTION),
            events,
            decisions,
        )

    def samples(
        self,
        run_id: int,
        names: Sequence[str] | None = None,
        *,
        predicted: bool = False,
        t0: float | None = None,
        t1: float | None = None,
    ) -> dict[str, np.ndarray]:
        """The recorded signals of a run as columns, in recording order.

        Parameters
        ----------
        run_id
            The run.
        names
            Signals to return; None for all.
        predicted
            True for the predicted signals instead of the measured ones.
        t0, t1
            Only the instants with ``t0 <= time <= t1`` (s; None: no bound). A closed run's
            overview tells which frames hold them, so a short window of a long run reads
            few frames.

        Returns
        -------
        dict of str to numpy.ndarray
            ``"time_s"`` (twin time, s) first, then one float64 array per signal; NaN where a
            signal was not recorded at an instant.
        """
        kind = _PREDICTION if predicted else _SAMPLE
        if t0 is None and t1 is None:
            return self._columns(run_id, names, kind)[0]
        lo = -math.inf if t0 is None else _finite(t0, "window start t0")
        hi = math.inf if t1 is None else _finite(t1, "window end t1")
        where = " AND t_s >= ? AND t_s <= ?"
        args: tuple[Any, ...] = (lo, hi)
        found = self._stored_overview(int(run_id), kind, [])
        if found is not None:
            where += " AND seq >= ? AND seq <= ?"
            args += found.seq_range(lo, hi)
        return self._columns(run_id, names, kind, where, args)[0]

    def _columns(
        self,
        run_id: int,
        names: Sequence[str] | None,
        kind: int,
        where: str = "",
        args: tuple[Any, ...] = (),
    ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], np.ndarray]:
        """Columns, per signal where it was recorded (a bool mask), and each instant's
        ``seq``; ``where`` (`` AND ...`` with ``args``) narrows the frames read."""
        self._sync()
        if not self._read("SELECT 1 FROM hist_runs WHERE id = ?", (int(run_id),)):
            raise self._unknown_run(run_id)
        available = self._names(self._layout_counts(run_id).get(int(run_id), []), kind)
        wanted = available if names is None else tuple(names)
        unknown = [name for name in wanted if name not in available]
        if unknown:
            raise DataError(
                f"run {run_id} has no {_KIND_NAMES[kind]} named {', '.join(map(repr, unknown))}"
                f" (recorded: {', '.join(available) or 'none'})"
            )
        rows = self._read(
            "SELECT t_s, layout_id, vals, seq FROM hist_frames WHERE run_id = ? AND kind = ?"
            f"{where} ORDER BY seq",
            (int(run_id), kind, *args),
        )
        n = len(rows)
        layout_of = np.fromiter((r[1] for r in rows), dtype=np.int64, count=n)
        columns = {TIME_COLUMN: np.fromiter((r[0] for r in rows), dtype=np.float64, count=n)}
        masks: dict[str, np.ndarray] = {}
        for name in wanted:
            columns[name] = np.full(n, np.nan)
            masks[name] = np.zeros(n, dtype=bool)
        layout_ids = np.unique(layout_of)
        layouts = self._layout_names(int(i) for i in layout_ids)
        for layout in layout_ids:
            layout_names = layouts[int(layout)]
            index = np.flatnonzero(layout_of == layout)
            block = np.frombuffer(b"".join(rows[i][2] for i in index), dtype=_FLOAT64)
            block = block.reshape(len(index), len(layout_names))
            for j, name in enumerate(layout_names):
                if name in masks:
                    columns[name][index] = block[:, j]
                    masks[name][index] = True
        return columns, masks, np.fromiter((r[3] for r in rows), dtype=np.int64, count=n)

    def overview(
        self, run_id: int, names: Sequence[str] | None = None, *, predicted: bool = False
    ) -> RunOverview | None:
        """The min and max of each signal per fine time bucket over a closed run.

        Computed when the run is closed (:meth:`end_run`); for a run closed before overviews
        existed, computed from its frames now and stored for the next time (when the
        database can be written). See :mod:`cnctwin.store._overview` and docs/historian.md.

        Parameters
        ----------
        run_id
            The run.
        names
            Signals to include; None for all.
        predicted
            True for the predicted signals instead of the measured ones.

        Returns
        -------
        RunOverview or None
            None while the run is still ``"running"``.

        Raises
        ------
        DataError
            For an unknown run or signal.
        """
        kind = _PREDICTION if predicted else _SAMPLE
        self._sync()
        rows = self._read("SELECT status FROM hist_runs WHERE id = ?", (int(run_id),))
        if not rows:
            raise self._unknown_run(run_id)
        if rows[0][0] == "running":
            return None
        found = self._stored_overview(int(run_id), kind, names)
        if found is None:
            found = self._write_overview(int(run_id), kind)
        if names is None:
            return found
        unknown = [name for name in names if name not in found.signals]
        if unknown:
            available = self._names(self._layout_counts(run_id).get(int(run_id), []), kind)
            raise DataError(
                f"run {run_id} has no {_KIND_NAMES[kind]} named {', '.join(map(repr, unknown))}"
                f" (recorded: {', '.join(available) or 'none'})"
            )
        return RunOverview(
            found.t_first,
            found.t_last,
            found.frames,
            found.count,
            found.first_t,
            found.seq_lo,
            found.seq_hi,
            {name: found.signals[name] for name in names},
        )

    def _stored_overview(
        self, run_id: int, kind: int, names: Sequence[str] | None
    ) -> RunOverview | None:
        """The stored overview (only ``names`` and the header when given); None if absent."""
        sql = "SELECT name, t_first, t_last, frames, data, buckets FROM hist_overview "
        sql += "WHERE run_id = ? AND kind = ?"
        args: tuple[Any, ...] = (run_id, kind)
        if names is not None:
            sql += f" AND name IN ({', '.join('?' * (len(names) + 1))})"
            args += ("", *names)
        try:
            rows = self._read(sql, args)
        except DataError:  # a database from before hist_overview
            return None
        blobs = {str(r[0]): bytes(r[4]) for r in rows}
        header = next((r for r in rows if r[0] == ""), None)
        if header is None:
            return None
        del blobs[""]
        return RunOverview.from_blobs(
            header[5], header[1], header[2], header[3], bytes(header[4]), blobs
        )

    def _write_overview(self, run_id: int, kind: int) -> RunOverview:
        """Compute a run's overview of one kind from its frames and store it with the run's
        layout counts (a database that cannot be written only logs why)."""
        layouts = self._layout_counts(run_id).get(run_id, [])
        columns, _, seq = self._columns(run_id, None, kind)
        t = columns.pop(TIME_COLUMN)
        found = compute_overview(t, columns, seq)
        head = (run_id, kind)
        tail = (found.buckets, found.t_first, found.t_last, found.frames)
        rows = [(*head, "", *tail, found.header_blob())]
        rows += [(*head, name, *tail, found.signal_blob(name)) for name in found.signals]
        backend = self._backend
        with self._db_lock:
            if self._closed:
                raise DataError(f"historian {self.location} is closed; open it again")
            try:
                with backend.transaction(self._conn):
                    for statement in backend.overview_tables():
                        self._conn.execute(statement)
                    self._conn.execute(
                        backend.sql("DELETE FROM hist_overview WHERE run_id = ? AND kind = ?"),
                        head,
                    )
                    self._conn.execute(
                        backend.sql("DELETE FROM hist_run_layouts WHERE run_id = ?"), (run_id,)
                    )
                    backend.executemany(
                        self._conn,
                        "INSERT INTO hist_run_layouts (run_id, kind, layout_id, frames, "
                        "first_seq, last_t_s) VALUES (?, ?, ?, ?, ?, ?)",
                        [(run_id, *c) for c in layouts],
                    )
                    backend.executemany(
                        self._conn,
                        "INSERT INTO hist_overview (run_id, kind, name, buckets, t_first, "
                        "t_last, frames, data) VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                        rows,
                    )
            except backend.errors as err:
                logger.info(
                    "historian %s: overview of run %d not stored: %s",
                    self.location,
                    run_id,
                    _one_line(err),
                )
        return found

    # ------------------------------------------------------------------ export
    def export(self, run_id: int, path: str | Path, format: str | None = None) -> list[Path]:
        """Write a run to CSV or Parquet files.

        ``PATH`` gets the measured signals as a wide table (``time_s`` then one column per
        signal; empty/null where a signal was not recorded); siblings ``STEM.predictions.EXT``,
        ``STEM.events.EXT`` and ``STEM.decisions.EXT`` get the rest. Floats are written
        exactly (shortest round-trip text in CSV). Parquet files carry the run's summary as
        JSON in the schema metadata key ``cnctwin.run``.

        Parameters
        ----------
        run_id
            The run.
        path
            The samples file; its suffix picks the format unless ``format`` is given.
        format
            ``"csv"`` or ``"parquet"``.

        Returns
        -------
        list of Path
            The files written.
        """
        path = Path(path)
        fmt = (format or path.suffix.lstrip(".")).lower()
        if fmt not in ("csv", "parquet"):
            raise DataError(
                f"export format {fmt or path.name!r} is not supported; name the file .csv or "
                ".parquet (or give format 'csv' or 'parquet')"
            )
        detail = self.run(run_id)
        return write_run(
            detail,
            self._columns(run_id, None, _SAMPLE)[:2],
            self._columns(run_id, None, _PREDICTION)[:2],
            path,
            fmt,
        )


def _bad_values(values: Mapping[str, object]) -> str:
    for name, value in values.items():
        try:
            float(value)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            return f"signal {name!r} has value {value!r}; a number (float) is required"
    return "signal values must be numbers (float)"


def _connection_lost(conn: Any) -> bool:
    """Whether a PostgreSQL connection is broken (an SQLite connection never is)."""
    return bool(getattr(conn, "broken", False) or getattr(conn, "closed", False))


def _one_line(err: BaseException) -> str:
    return " ".join(str(err).split()) or type(err).__name__
