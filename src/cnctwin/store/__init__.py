"""Storage: the historian of the twin's runs (SQLite or PostgreSQL) and the twin registry
(SQLite, embedded) for machines, tools and their twins."""

from cnctwin.store._overview import OVERVIEW_BUCKETS, Envelope, RunOverview
from cnctwin.store.config import HistorianConfig
from cnctwin.store.historian import (
    TIME_COLUMN,
    DecisionRecord,
    EventRecord,
    Historian,
    HistorianStats,
    RunDetail,
    RunSummary,
    default_database_path,
)
from cnctwin.store.registry import MeasurementRecord, ToolRecord, TwinRegistry

__all__ = [
    "DecisionRecord",
    "Envelope",
    "EventRecord",
    "Historian",
    "HistorianConfig",
    "HistorianStats",
    "MeasurementRecord",
    "OVERVIEW_BUCKETS",
    "RunDetail",
    "RunOverview",
    "RunSummary",
    "TIME_COLUMN",
    "ToolRecord",
    "TwinRegistry",
    "default_database_path",
]
