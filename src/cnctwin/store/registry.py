"""The twin registry: lathes, their tool twins and every part measurement, in SQLite.

The registry keeps what the wear-compensation twins of Bolyn 2023 need to survive a restart:
each lathe's settings, its active and retired tool twins (whose history is the heritage new
tools draw on) and an append-only log of the measured parts and the corrections given. Every
change is one transaction (``BEGIN IMMEDIATE``), so several processes may share a file.
Lengths are stored in m (SI).
"""

from __future__ import annotations

import json
import math
import sqlite3
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from cnctwin import finite_json
from cnctwin.errors import DataError
from cnctwin.wear import LatheTwin, ManufacturingParameters, Observation, ToolTwin

__all__ = ["MeasurementRecord", "ToolRecord", "TwinRegistry"]

_SCHEMA = """
CREATE TABLE IF NOT EXISTS lathes (
    name TEXT PRIMARY KEY,
    resolution_m REAL NOT NULL,
    criterion REAL NOT NULL,
    max_parameter_distance REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS tools (
    lathe TEXT NOT NULL REFERENCES lathes(name),
    tool_id TEXT NOT NULL,
    state TEXT NOT NULL CHECK (state IN ('active', 'retired')),
    target_m REAL NOT NULL,
    tolerance_low_m REAL NOT NULL,
    tolerance_high_m REAL NOT NULL,
    mounted_at REAL NOT NULL,
    retired_at REAL,
    twin_json TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS tools_by_lathe ON tools(lathe, state, retired_at);
CREATE TABLE IF NOT EXISTS measurements (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    lathe TEXT NOT NULL,
    tool_id TEXT NOT NULL,
    mounted_at REAL NOT NULL,
    part INTEGER NOT NULL,
    measured_m REAL NOT NULL,
    deviation_m REAL NOT NULL,
    slope_m_per_part REAL NOT NULL,
    trusted INTEGER NOT NULL,
    source TEXT NOT NULL,
    correction_m REAL NOT NULL,
    offset_m REAL NOT NULL,
    recorded_at REAL NOT NULL
);
"""

#: A measured dimension further than this from the target is refused as absurd, m
#: (besides being further than ten tolerance widths).
ABSURD_DEVIATION_M = 1e-3


@dataclass(frozen=True, slots=True)
class ToolRecord:
    """A tool as the registry holds it.

    Attributes
    ----------
    lathe, tool_id
        Where and which.
    state
        ``"active"`` or ``"retired"``.
    target_m, tolerance_low_m, tolerance_high_m
        Nominal dimension and the tolerance interval relative to it, m.
    mounted_at, retired_at
        Unix times, s (``retired_at`` is None while active).
    twin
        The tool twin.
    """

    lathe: str
    tool_id: str
    state: str
    target_m: float
    tolerance_low_m: float
    tolerance_high_m: float
    mounted_at: float
    retired_at: float | None
    twin: ToolTwin


@dataclass(frozen=True, slots=True)
class MeasurementRecord:
    """One logged part: what was measured and the correction that was given."""

    tool_id: str
    part: int
    measured_m: float
    deviation_m: float
    slope_m_per_part: float
    trusted: bool
    source: str
    correction_m: float
    offset_m: float
    recorded_at: float


class TwinRegistry:
    """An SQLite registry of lathe twins.

    Parameters
    ----------
    path
        Database file (created with its schema if absent).
    timeout_s
        How long to wait for another process's transaction, s.
    """

    def __init__(self, path: str | Path, *, timeout_s: float = 10.0) -> None:
        self.path = Path(path)
        try:
            self._db = sqlite3.connect(self.path, timeout=timeout_s, isolation_level=None)
            self._db.executescript(_SCHEMA)
        except sqlite3.DatabaseError as err:
            raise DataError(f"{self.path}: not a cnctwin registry database ({err})") from None

    def close(self) -> None:
        """Close the database."""
        self._db.close()

    def __enter__(self) -> TwinRegistry:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        self._db.execute("BEGIN IMMEDIATE")
        try:
            yield self._db
        except BaseException:
            self._db.execute("ROLLBACK")
            raise
        self._db.execute("COMMIT")

    # ------------------------------------------------------------------ lathes
    def _lathe(self, db: sqlite3.Connection, name: str, resolution_m: float) -> LatheTwin:
        """The lathe twin with its tools, created with ``resolution_m`` if new."""
        row = db.execute(
            "SELECT resolution_m, criterion, max_parameter_distance FROM lathes WHERE name = ?",
            (name,),
        ).fetchone()
        if row is None:
            lathe = LatheTwin(resolution=resolution_m)
            db.execute(
                "INSERT INTO lathes VALUES (?, ?, ?, ?)",
                (name, lathe.resolution, lathe.criterion, lathe.max_parameter_distance),
            )
            return lathe
        lathe = LatheTwin(resolution=row[0], criterion=row[1], max_parameter_distance=row[2])
        for state, twin_json in db.execute(
            "SELECT state, twin_json FROM tools WHERE lathe = ? "
            "ORDER BY state, COALESCE(retired_at, mounted_at)",
            (name,),
        ):
            twin = ToolTwin.from_dict(json.loads(twin_json))
            if state == "active":
                lathe.active[twin.tool_id] = twin
            else:
                lathe.retired.append(twin)
        return lathe

    # ------------------------------------------------------------------ tools
    def mount(
        self,
        lathe: str,
        tool_id: str,
        *,
        target_m: float,
        tolerance_m: tuple[float, float],
        parameters: ManufacturingParameters | None = None,
        resolution_m: float = 0.0,
        inherit: bool = True,
    ) -> ToolRecord:
        """Mount a new tool on a lathe; its twin inherits from the most similar retired one.

        Parameters
        ----------
        lathe
            Lathe name (created on first use with ``resolution_m``).
        tool_id
            Name of the physical tool; must not be active on that lathe.
        target_m
            Nominal dimension the tool makes, m.
        tolerance_m
            Tolerance interval relative to the target ``(low, high)``, m, low < high.
        parameters
            Manufacturing conditions (needed for heritage).
        resolution_m
            Offset resolution of a new lathe, m.
        inherit
            False starts from scratch.

        Returns
        -------
        ToolRecord
            Its ``twin.offset`` is the correction to apply before the first part.
        """
        low, high = tolerance_m
        if not (math.isfinite(target_m) and target_m > 0):
            raise DataError(f"target must be a positive dimension in m; got {target_m!r}")
        if not (math.isfinite(low) and math.isfinite(high) and low < high):
            raise DataError(f"tolerance must be (low, high) with low < high; got {tolerance_m!r}")
        with self._transaction() as db:
            twin_lathe = self._lathe(db, lathe, resolution_m)
            twin = twin_lathe.mount(tool_id, parameters, inherit=inherit)
            now = time.time()
            db.execute(
                "INSERT INTO tools VALUES (?, ?, 'active', ?, ?, ?, ?, NULL, ?)",
                (lathe, tool_id, target_m, low, high, now, finite_json.dumps(twin.to_dict())),
            )
        return ToolRecord(lathe, tool_id, "active", target_m, low, high, now, None, twin)

    def _active_row(self, db: sqlite3.Connection, lathe: str, tool_id: str) -> tuple:
        row = db.execute(
            "SELECT target_m, tolerance_low_m, tolerance_high_m, mounted_at FROM tools "
            "WHERE lathe = ? AND tool_id = ? AND state = 'active'",
            (lathe, tool_id),
        ).fetchone()
        if row is None:
            active = [
                r[0]
                for r in db.execute(
                    "SELECT tool_id FROM tools WHERE lathe = ? AND state = 'active'", (lathe,)
                )
            ]
            raise DataError(
                f"tool {tool_id!r} is not mounted on lathe {lathe!r} "
                f"(active: {', '.join(active) or 'none'})"
            )
        return row

    def record(self, lathe: str, tool_id: str, measured_m: float) -> Observation:
        """Record a measured part and return the correction to apply.

        Parameters
        ----------
        lathe, tool_id
            An active tool.
        measured_m
            The part's measured dimension, m.

        Returns
        -------
        Observation
            Its ``correction`` (m) is the offset change to apply before the next part.

        Raises
        ------
        DataError
            For an unknown or retired tool, or an absurd measurement (not finite, or further
            from the target than 1 mm and ten tolerance widths); nothing is stored then.
        """
        with self._transaction() as db:
            target, low, high, mounted_at = self._active_row(db, lathe, tool_id)
            if not math.isfinite(measured_m):
                raise DataError(f"measurement {measured_m!r} is not a finite dimension")
            deviation = measured_m - target
            limit = max(ABSURD_DEVIATION_M, 10.0 * (high - low))
            if abs(deviation) > limit:
                raise DataError(
                    f"measurement {measured_m * 1e3:.4f} mm is {deviation * 1e3:+.4f} mm from "
                    f"the target {target * 1e3:.4f} mm of tool {tool_id!r}; deviations beyond "
                    f"{limit * 1e3:.3f} mm are refused as absurd (wrong tool or gauge?)"
                )
            twin_lathe = self._lathe(db, lathe, 0.0)
            observation = twin_lathe.measure(tool_id, deviation)
            twin = twin_lathe.active[tool_id]
            now = time.time()
            db.execute(
                "UPDATE tools SET twin_json = ? WHERE lathe = ? AND tool_id = ? "
                "AND state = 'active'",
                (finite_json.dumps(twin.to_dict()), lathe, tool_id),
            )
            db.execute(
                "INSERT INTO measurements (lathe, tool_id, mounted_at, part, measured_m, "
                "deviation_m, slope_m_per_part, trusted, source, correction_m, offset_m, "
                "recorded_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (
                    lathe,
                    tool_id,
                    mounted_at,
                    observation.part,
                    measured_m,
                    observation.measured_deviation,
                    observation.slope,
                    int(observation.trusted),
                    observation.source,
                    observation.correction,
                    observation.offset,
                    now,
                ),
            )
        return observation

    def retire(self, lathe: str, tool_id: str) -> ToolRecord:
        """Retire an active tool; its twin becomes heritage for the tools that follow."""
        with self._transaction() as db:
            target, low, high, mounted_at = self._active_row(db, lathe, tool_id)
            twin_lathe = self._lathe(db, lathe, 0.0)
            twin = twin_lathe.retire(tool_id)
            now = time.time()
            db.execute(
                "UPDATE tools SET state = 'retired', retired_at = ? WHERE lathe = ? "
                "AND tool_id = ? AND state = 'active'",
                (now, lathe, tool_id),
            )
        return ToolRecord(lathe, tool_id, "retired", target, low, high, mounted_at, now, twin)

    # ------------------------------------------------------------------ reading
    def tools(self, lathe: str) -> list[ToolRecord]:
        """Every tool of a lathe, oldest first."""
        rows = self._db.execute(
            "SELECT tool_id, state, target_m, tolerance_low_m, tolerance_high_m, mounted_at, "
            "retired_at, twin_json FROM tools WHERE lathe = ? ORDER BY mounted_at",
            (lathe,),
        ).fetchall()
        return [
            ToolRecord(
                lathe,
                r[0],
                r[1],
                r[2],
                r[3],
                r[4],
                r[5],
                r[6],
                ToolTwin.from_dict(json.loads(r[7])),
            )
            for r in rows
        ]

    def history(self, lathe: str, tool_id: str | None = None) -> list[MeasurementRecord]:
        """The logged parts of a lathe (or of one tool), in order."""
        query = (
            "SELECT tool_id, part, measured_m, deviation_m, slope_m_per_part, trusted, source, "
            "correction_m, offset_m, recorded_at FROM measurements WHERE lathe = ?"
        )
        args: tuple[str, ...] = (lathe,)
        if tool_id is not None:
            query += " AND tool_id = ?"
            args += (tool_id,)
        rows = self._db.execute(query + " ORDER BY id", args).fetchall()
        return [
            MeasurementRecord(r[0], r[1], r[2], r[3], r[4], bool(r[5]), r[6], r[7], r[8], r[9])
            for r in rows
        ]
