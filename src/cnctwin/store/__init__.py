"""Storage: the historian of the twin's runs (SQLite or PostgreSQL) and the twin registry
(SQLite, embedded) for machines, tools and their twins."""

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
    "EventRecord",
    "Historian",
    "HistorianConfig",
    "HistorianStats",
    "MeasurementRecord",
    "RunDetail",
    "RunSummary",
    "TIME_COLUMN",
    "ToolRecord",
    "TwinRegistry",
    "default_database_path",
]
