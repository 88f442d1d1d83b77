"""The ``[historian]`` table of a twin configuration: where runs are recorded, and how often."""

from __future__ import annotations

from pydantic import Field

from cnctwin.config import Section

__all__ = ["HistorianConfig"]


class HistorianConfig(Section):
    """Where and how the twin records its runs (``[historian]``).

    Attributes
    ----------
    url
        An SQLite file path or ``postgresql://USER@HOST:PORT/DB``;
        ``None`` takes the installation's file, :func:`cnctwin.store.default_database_path`.
    flush_interval_s
        The writer commits what is queued at least this often, s. A killed twin loses at most
        about this much (plus one write); at most 1 s.
    batch_size
        Queued items (sample frames, events, decisions) that wake the writer before the
        interval is up.
    max_pending
        Items the queue may hold while the database is slow or unreachable; beyond it new
        items are dropped and counted, so the twin's cycle never waits for the database.
        At most 10,000,000 (a few GB of queued frames).
    """

    url: str | None = None
    flush_interval_s: float = Field(default=0.25, gt=0.0, le=1.0)
    batch_size: int = Field(default=2000, ge=1, le=1_000_000)
    max_pending: int = Field(default=1_000_000, ge=1, le=10_000_000)
