"""The mapping of a recorded log onto the canonical signals: a TOML file (docs/replay.md).

A log written by another system names its columns in its own way and in its own units; the
mapping says, for each canonical signal of :data:`cnctwin.thread.SIGNALS`, which column holds
it (``column``), or the Euclidean norm of which columns (``norm``: a path speed from the axis
velocities), or a constant (``value``), and the unit of the column (``unit``), converted into
the signal's own unit (:data:`UNITS`). It also says how rows are timed (a time column or a fixed
sample period), which rows are glitches (``[[glitches]]``: every condition of one rule holds),
and where per-file constants live (``[metadata]``: a table keyed by a number in the log's file
name). Without a mapping, a log's columns named like canonical signals map onto them and its
``time_s`` column times the rows: the historian's ``cnctwin runs export`` format.
"""

from __future__ import annotations

import os
import re
import tomllib
from pathlib import Path
from typing import Annotated, Any

from pydantic import Field, ValidationError, field_validator, model_validator

from cnctwin.config import Section, describe_validation_error
from cnctwin.drives import RAD_S_PER_RPM
from cnctwin.errors import ConfigError
from cnctwin.thread import COMMANDS, SIGNALS

__all__ = [
    "GlitchRule",
    "LogTiming",
    "MetadataTable",
    "ReplayMap",
    "SignalSource",
    "UNITS",
    "load_replay_map",
    "unit_factor",
]

#: Units a mapping may name -> (quantity, factor to the quantity's canonical unit: mm, mm/min,
#: rpm, s, N m, A, W, N, %, 1). A column's value times the factor is in the signal's unit.
UNITS: dict[str, tuple[str, float]] = {
    "s": ("time", 1.0),
    "ms": ("time", 1e-3),
    "min": ("time", 60.0),
    "mm": ("length", 1.0),
    "m": ("length", 1e3),
    "um": ("length", 1e-3),
    "in": ("length", 25.4),
    "mm/min": ("speed", 1.0),
    "mm/s": ("speed", 60.0),
    "m/min": ("speed", 1e3),
    "m/s": ("speed", 6e4),
    "in/min": ("speed", 25.4),
    "rpm": ("rotation", 1.0),
    "rev/s": ("rotation", 60.0),
    "rad/s": ("rotation", 1.0 / RAD_S_PER_RPM),
    "deg/s": ("rotation", 1.0 / 6.0),
    "N m": ("torque", 1.0),
    "N mm": ("torque", 1e-3),
    "A": ("current", 1.0),
    "mA": ("current", 1e-3),
    "W": ("power", 1.0),
    "kW": ("power", 1e3),
    "N": ("force", 1.0),
    "kN": ("force", 1e3),
    "%": ("percent", 1.0),
    "1": ("count", 1.0),
}

#: Signals a replay makes itself (never read from a log): the liveness counter and the
#: commands, which read back what a client wrote.
GENERATED = frozenset({"heartbeat", *COMMANDS})

_Name = Annotated[str, Field(min_length=1, max_length=200)]


def unit_factor(unit: str, signal: str) -> float:
    """The factor that converts a value in ``unit`` into ``signal``'s own unit.

    Raises
    ------
    ConfigError
        On an unknown unit, or one of another quantity than the signal's (the message lists
        the units that fit).
    """
    target = SIGNALS[signal].unit
    quantity, to_base = UNITS[target]
    fitting = [u for u, (q, _) in UNITS.items() if q == quantity]
    given = UNITS.get(unit)
    if given is None or given[0] != quantity:
        raise ConfigError(
            f"signals.{signal}.unit {unit!r} cannot be converted to {target}; "
            f"valid: {', '.join(fitting)}"
        )
    return given[1] / to_base


class SignalSource(Section):
    """Where one canonical signal comes from (``[signals.NAME]``): exactly one of ``column``,
    ``norm`` and ``value``.

    Attributes
    ----------
    column
        The log's column.
    norm
        Columns whose Euclidean norm is the signal (e.g. the path speed from the axis
        velocities).
    value
        A constant, in the signal's unit (no conversion).
    unit
        The unit of the column(s) (:data:`UNITS`); default: the signal's own.
    scale
        Factor applied in the column's unit before the conversion (e.g. -1 for a sign
        convention).
    """

    column: _Name | None = None
    norm: list[_Name] | None = Field(default=None, min_length=1, max_length=16)
    value: float | None = None
    unit: str | None = None
    scale: float = Field(default=1.0, ge=-1e9, le=1e9)

    @model_validator(mode="after")
    def _one_source(self) -> SignalSource:
        given = [k for k in ("column", "norm", "value") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(f"give exactly one of column, norm, value (got {given or 'none'})")
        return self

    @property
    def columns(self) -> list[str]:
        """The log columns this signal reads."""
        if self.column is not None:
            return [self.column]
        return list(self.norm or [])


class LogTiming(Section):
    """How the rows are timed (``[log]``): a time column, or a fixed sample period.

    Attributes
    ----------
    time_column
        Column of the sample times (non-decreasing); the replay starts at its first value.
    time_unit
        Unit of ``time_column``: ``s``, ``ms`` or ``min``.
    period_s
        Fixed sample period, s (row k at k x period_s); replaces ``time_column``.
    """

    time_column: _Name | None = "time_s"
    time_unit: str = "s"
    period_s: float | None = Field(default=None, gt=0.0, le=3600.0)

    @field_validator("time_unit")
    @classmethod
    def _time_unit(cls, unit: str) -> str:
        if UNITS.get(unit, ("", 0.0))[0] != "time":
            raise ValueError(f"time_unit {unit!r}; valid: s, ms, min")
        return unit


class GlitchRule(Section):
    """One kind of glitch row (``[[glitches]]``): a row for which every condition holds.

    Attributes
    ----------
    name
        What it is, for the report.
    equals
        Column -> value (number or text) the row's cell equals.
    one_of
        Column -> values, one of which the row's cell equals.
    """

    name: _Name
    equals: dict[str, float | str] = Field(default_factory=dict)
    one_of: dict[str, list[float | str]] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _some_condition(self) -> GlitchRule:
        if not self.equals and not self.one_of:
            raise ValueError("a glitch rule needs at least one condition (equals or one_of)")
        return self

    @property
    def columns(self) -> list[str]:
        """The log columns the rule reads."""
        return [*self.equals, *self.one_of]


class MetadataTable(Section):
    """Per-file constants (``[metadata]``): one row of a CSV table, found by a number in the
    log's file name. Reported with the replay, not served (no canonical signal holds them).

    Attributes
    ----------
    table
        The CSV table; a relative path is relative to the log's folder.
    key_column
        The table's column holding the number.
    file_pattern
        Regular expression whose first group, searched in the log's file name, is the number.
    """

    table: Path
    key_column: _Name
    file_pattern: _Name

    @field_validator("file_pattern")
    @classmethod
    def _pattern(cls, text: str) -> str:
        try:
            compiled = re.compile(text)
        except re.error as err:
            raise ValueError(f"file_pattern {text!r} is not a regular expression: {err}") from None
        if compiled.groups < 1:
            raise ValueError(f"file_pattern {text!r} needs a group ( ) around the number")
        return text


class ReplayMap(Section):
    """A mapping file: how a recorded log becomes the canonical signals.

    Attributes
    ----------
    log
        How rows are timed.
    signals
        Canonical signal name -> its source. ``heartbeat`` and the commands cannot be mapped
        (a replay counts its own heartbeat; commands read back what a client wrote).
    glitches
        Rules of glitch rows: counted, reported and never served (the previous row holds).
    metadata
        Per-file constants, reported.
    """

    log: LogTiming = Field(default_factory=LogTiming)
    signals: dict[str, SignalSource] = Field(default_factory=dict)
    glitches: list[GlitchRule] = Field(default_factory=list, max_length=64)
    metadata: MetadataTable | None = None

    @field_validator("signals")
    @classmethod
    def _canonical(cls, signals: dict[str, SignalSource]) -> dict[str, SignalSource]:
        for name, source in signals.items():
            if name not in SIGNALS:
                raise ValueError(
                    f"signals.{name}: not a canonical signal; valid: "
                    + ", ".join(n for n in SIGNALS if n not in GENERATED)
                )
            if name in GENERATED:
                raise ValueError(
                    f"signals.{name}: not replayed (a replay counts its own heartbeat; "
                    "commands read back what a client writes)"
                )
            if source.unit is not None:
                unit_factor(source.unit, name)
        return signals

    def factor(self, name: str) -> float:
        """Scale x unit conversion of signal ``name``'s column(s) into its unit."""
        source = self.signals[name]
        if source.value is not None:
            return 1.0
        unit = source.unit if source.unit is not None else SIGNALS[name].unit
        return source.scale * unit_factor(unit, name)


def load_replay_map(path: str | os.PathLike[str]) -> ReplayMap:
    """Read a mapping file.

    Parameters
    ----------
    path
        The TOML file (docs/replay.md; the UMich mapping: examples/replay/umich.toml).

    Returns
    -------
    ReplayMap
        The mapping.

    Raises
    ------
    ConfigError
        One line naming the file and the key, when the file cannot be read or is invalid.
    """
    path = Path(path)
    try:
        data: dict[str, Any] = tomllib.loads(path.read_bytes().decode("utf-8"))
    except OSError as err:
        raise ConfigError(f"cannot read mapping: {err.strerror}", str(path)) from err
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as err:
        raise ConfigError(f"not a TOML mapping: {' '.join(str(err).split())}", str(path)) from err
    try:
        mapping = ReplayMap.model_validate(data)
    except ValidationError as err:
        raise ConfigError(describe_validation_error(err, ReplayMap), str(path)) from err
    return mapping
