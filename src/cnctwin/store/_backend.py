"""What the historian asks of a database: the schema and the few operations SQLite and
PostgreSQL do differently (connecting, transactions, bulk insert of sample frames).

The schema (both databases; ``?`` is the placeholder, PostgreSQL gets ``%s``):

``hist_runs``
    one row per run: id, ``started_at``/``ended_at`` (Unix time, s), status, ``meta`` and
    ``summary`` (JSON text).
``hist_layouts``
    each distinct ordered set of signal names, as a JSON list, once.
``hist_frames``
    one row per recorded instant: run, kind (0 measured, 1 predicted), ``seq`` (the order the
    twin recorded it in), ``t_s`` (twin time, s), layout and ``vals``: the values as
    little-endian IEEE 754 float64, in the layout's order (bit-exact, NaN included).
``hist_events``, ``hist_decisions``
    one row each, sharing the ``seq`` counter with the frames so a run replays in order.
``hist_overview``
    a closed run's overview (:mod:`cnctwin.store._overview`): per run and kind, one row named
    ``""`` (instants per fine bucket and the first one's time) and one row per signal (its
    min and max per fine bucket), each with the bucket count, the first and last instant's
    time and the instants. Added after the first release: a database without it gets it on
    the first overview written (:meth:`Backend.overview_tables`).
``hist_run_layouts``
    a closed run's frames per kind and layout, with the first one's ``seq`` and the last
    one's time (what ``hist_frames_by_layout`` gives, without counting the run's frames
    again), written with its overview.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterator, Sequence
from contextlib import AbstractContextManager
from typing import Any

__all__ = ["FRAME_COLUMNS", "Backend", "FrameRow"]

#: Columns of ``hist_frames`` in insert order.
FRAME_COLUMNS = ("run_id", "kind", "seq", "t_s", "layout_id", "vals")

#: One ``hist_frames`` row: (run_id, kind, seq, t_s, layout_id, vals).
FrameRow = tuple[int, int, int, float, int, bytes]


class Backend(ABC):
    """One database flavour: DDL types, connection and bulk insert.

    Attributes
    ----------
    label
        Where the data goes, for messages (a path, or a URL without its password).
    errors
        The driver's base error class(es).
    transient
        Errors after which the writer reconnects and retries the batch (busy file, lost
        server); other errors drop the batch.
    """

    label: str
    errors: tuple[type[BaseException], ...]
    transient: tuple[type[BaseException], ...]
    #: ``(id column, float, blob)`` type names of the DDL.
    types: tuple[str, str, str]
    #: Appended to the frame/event/decision tables (clustered primary key on SQLite).
    table_suffix: str = ""

    @abstractmethod
    def connect(self) -> Any:
        """A new autocommit DB-API connection, usable from any thread but one at a time."""

    @abstractmethod
    def transaction(self, conn: Any) -> AbstractContextManager[None]:
        """A write transaction on ``conn``: committed on exit, rolled back on an error."""

    @abstractmethod
    def insert_frames(self, conn: Any, rows: Sequence[FrameRow]) -> None:
        """Insert many frames inside the current transaction (the hot path)."""

    def sql(self, text: str) -> str:
        """``text`` with this driver's placeholder (``?`` in the source)."""
        return text

    def executemany(self, conn: Any, text: str, rows: Sequence[tuple[Any, ...]]) -> None:
        """Run one statement for many rows."""
        conn.executemany(self.sql(text), rows)

    def query(self, conn: Any, text: str, args: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
        """Every row of a query."""
        return list(conn.execute(self.sql(text), args).fetchall())

    def statements(self) -> Iterator[str]:
        """The schema's DDL statements (idempotent)."""
        ident, real, blob = self.types
        end = self.table_suffix
        yield f"""CREATE TABLE IF NOT EXISTS hist_runs (
            id {ident}, started_at {real} NOT NULL, ended_at {real},
            status TEXT NOT NULL, meta TEXT NOT NULL, summary TEXT)"""
        yield f"CREATE TABLE IF NOT EXISTS hist_layouts (id {ident}, names TEXT NOT NULL UNIQUE)"
        yield f"""CREATE TABLE IF NOT EXISTS hist_frames (
            run_id BIGINT NOT NULL, kind SMALLINT NOT NULL, seq BIGINT NOT NULL,
            t_s {real} NOT NULL, layout_id BIGINT NOT NULL, vals {blob} NOT NULL,
            PRIMARY KEY (run_id, kind, seq)){end}"""
        # What a run holds (frames and instants per layout, names in first-recorded order,
        # last time) is read from this index alone, never from the frames' values.
        yield (
            "CREATE INDEX IF NOT EXISTS hist_frames_by_layout "
            "ON hist_frames (run_id, kind, layout_id, seq, t_s)"
        )
        yield f"""CREATE TABLE IF NOT EXISTS hist_events (
            run_id BIGINT NOT NULL, seq BIGINT NOT NULL, t_s {real} NOT NULL,
            kind TEXT NOT NULL, message TEXT NOT NULL, data TEXT NOT NULL,
            PRIMARY KEY (run_id, seq)){end}"""
        yield f"""CREATE TABLE IF NOT EXISTS hist_decisions (
            run_id BIGINT NOT NULL, seq BIGINT NOT NULL, t_s {real} NOT NULL,
            rule TEXT NOT NULL, action TEXT NOT NULL, value {real} NOT NULL,
            reason TEXT NOT NULL, accepted SMALLINT NOT NULL, readback {real},
            PRIMARY KEY (run_id, seq)){end}"""
        yield from self.overview_tables()

    def overview_tables(self) -> Iterator[str]:
        """The DDL of ``hist_overview`` and ``hist_run_layouts`` (idempotent; also run before
        the first overview is written into a database created before these tables)."""
        _, real, blob = self.types
        end = self.table_suffix
        yield f"""CREATE TABLE IF NOT EXISTS hist_overview (
            run_id BIGINT NOT NULL, kind SMALLINT NOT NULL, name TEXT NOT NULL,
            buckets BIGINT NOT NULL, t_first {real} NOT NULL, t_last {real} NOT NULL,
            frames BIGINT NOT NULL, data {blob} NOT NULL,
            PRIMARY KEY (run_id, kind, name)){end}"""
        yield f"""CREATE TABLE IF NOT EXISTS hist_run_layouts (
            run_id BIGINT NOT NULL, kind SMALLINT NOT NULL, layout_id BIGINT NOT NULL,
            frames BIGINT NOT NULL, first_seq BIGINT NOT NULL, last_t_s {real} NOT NULL,
            PRIMARY KEY (run_id, kind, layout_id)){end}"""

    def create_schema(self, conn: Any) -> None:
        """Create the tables that are missing."""
        with self.transaction(conn):
            for statement in self.statements():
                conn.execute(statement)
