"""Storage: the twin registry (SQLite, embedded) for machines, tools and their twins."""

from cnctwin.store.registry import MeasurementRecord, ToolRecord, TwinRegistry

__all__ = ["MeasurementRecord", "ToolRecord", "TwinRegistry"]
