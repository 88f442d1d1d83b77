"""What the historian gives back: run summaries, events, decisions and writer counters."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

__all__ = ["DecisionRecord", "EventRecord", "HistorianStats", "RunDetail", "RunSummary"]


@dataclass(frozen=True, slots=True)
class RunSummary:
    """One run as :meth:`Historian.runs` lists it.

    Attributes
    ----------
    run_id, status
        Id, and ``"running"`` until :meth:`Historian.end_run` sets another (a run that stays
        ``"running"`` after its twin died was interrupted).
    started_at, ended_at
        Unix times, s.
    meta, summary
        What the twin gave :meth:`Historian.start_run` and :meth:`Historian.end_run`.
    frames
        Recorded instants of measured signals.
    values, predicted_values
        Recorded signal values (measured, predicted).
    events, decisions
        Counts.
    last_t_s
        Twin time of the last measured instant, s (None without samples).
    """

    run_id: int
    status: str
    started_at: float
    ended_at: float | None
    meta: dict[str, Any]
    summary: dict[str, Any] | None
    frames: int
    values: int
    predicted_values: int
    events: int
    decisions: int
    last_t_s: float | None

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict."""
        return asdict(self)


@dataclass(frozen=True, slots=True)
class EventRecord:
    """A recorded event: ``t_s`` twin time, s; ``data`` its JSON payload."""

    seq: int
    t_s: float
    kind: str
    message: str
    data: dict[str, Any]


@dataclass(frozen=True, slots=True)
class DecisionRecord:
    """A recorded decision: which rule asked for which action, why, and what the machine did.

    ``value`` is the commanded value in the command's unit (e.g. % for ``feed_override_pct``);
    ``readback`` the machine's confirmed value (None when not read back).
    """

    seq: int
    t_s: float
    rule: str
    action: str
    value: float
    reason: str
    accepted: bool
    readback: float | None


@dataclass(frozen=True, slots=True)
class RunDetail:
    """A run with its signal names, events and decisions (:meth:`Historian.run`)."""

    summary: RunSummary
    signals: tuple[str, ...]
    predicted: tuple[str, ...]
    events: list[EventRecord]
    decisions: list[DecisionRecord]

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict."""
        return {
            **self.summary.to_dict(),
            "signals": list(self.signals),
            "predicted": list(self.predicted),
            "event_log": [asdict(e) for e in self.events],
            "decision_log": [asdict(d) for d in self.decisions],
        }


@dataclass(frozen=True, slots=True)
class HistorianStats:
    """The writer's counters since :meth:`Historian.open`.

    Attributes
    ----------
    pending
        Items queued, not yet committed.
    written_items, written_values
        Committed frames + events + decisions; committed signal values.
    dropped
        Items lost (queue full, or refused by the database).
    batches
        Committed transactions.
    last_error
        The last database error, if any.
    """

    pending: int
    written_items: int
    written_values: int
    dropped: int
    batches: int
    last_error: str | None
