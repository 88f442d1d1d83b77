"""The historian's SQLite backend: one file, WAL journal, ``synchronous=NORMAL``.

In WAL mode a commit is durable against the death of the process (SIGKILL included) as soon
as it returns; ``synchronous=NORMAL`` gives up only the last commits on a power cut, for a
commit that costs no fsync. Readers never block the writer, and several processes may share
the file (one writes at a time; the others wait up to the busy timeout).
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from cnctwin.errors import DataError
from cnctwin.store._backend import FRAME_COLUMNS, Backend, FrameRow

__all__ = ["SqliteBackend"]

_INSERT_FRAMES = (
    f"INSERT INTO hist_frames ({', '.join(FRAME_COLUMNS)}) VALUES ({', '.join('?' * 6)})"
)


class SqliteBackend(Backend):
    """An SQLite historian file.

    Parameters
    ----------
    path
        The database file.
    create
        Create the file (and its folder) when absent; otherwise a missing file is an error.
    busy_timeout_s
        How long a write waits for another process's transaction, s.
    """

    errors = (sqlite3.Error,)
    transient = (sqlite3.OperationalError,)
    types = ("INTEGER PRIMARY KEY AUTOINCREMENT", "REAL", "BLOB")
    table_suffix = " WITHOUT ROWID"

    def __init__(self, path: Path, *, create: bool = True, busy_timeout_s: float = 10.0) -> None:
        self.path = path
        self.label = str(path)
        self.busy_timeout_s = busy_timeout_s
        if not path.exists():
            if not create:
                raise DataError(
                    f"no historian database at {path} (give --db with an existing SQLite "
                    "file or a postgresql:// URL)"
                )
            path.parent.mkdir(parents=True, exist_ok=True)

    def connect(self) -> sqlite3.Connection:
        conn = sqlite3.connect(
            self.path,
            timeout=self.busy_timeout_s,
            isolation_level=None,
            check_same_thread=False,
        )
        try:
            mode = conn.execute("PRAGMA journal_mode=WAL").fetchone()[0]
            conn.execute("PRAGMA synchronous=NORMAL")
        except sqlite3.DatabaseError as err:
            conn.close()
            raise DataError(f"{self.path}: not a readable SQLite database ({err})") from None
        if str(mode).lower() != "wal":
            conn.close()
            raise DataError(f"{self.path}: cannot switch to WAL journal mode (got {mode!r})")
        return conn

    @contextmanager
    def transaction(self, conn: sqlite3.Connection) -> Iterator[None]:
        conn.execute("BEGIN IMMEDIATE")
        try:
            yield
        except BaseException:
            conn.execute("ROLLBACK")
            raise
        conn.execute("COMMIT")

    def insert_frames(self, conn: sqlite3.Connection, rows: Sequence[FrameRow]) -> None:
        conn.executemany(_INSERT_FRAMES, rows)
