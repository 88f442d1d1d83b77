"""Beckhoff ADS symbol maps: canonical signal -> PLC symbol, IEC 61131-3 type and scale.

A symbol map is a TOML file (docs/ads.md; the default is the packaged
``cnctwin/examples/ads_symbols.toml``, a ``GVL_Twin`` global variable list)::

    [signals]       # read every cycle, in one ADS sum-read
    x_mm = { symbol = "GVL_Twin.fActPosX", type = "LREAL", unit = "mm" }
    spindle_rpm = { symbol = "GVL_Twin.nSpindleSpeed", type = "DINT", scale = 0.1 }

    [commands]      # written by the twin (through the safety filter), read back by signal
    feed_override_pct = { symbol = "GVL_Twin.fFeedOverrideCmd", type = "LREAL" }

Engineering value = raw value x ``scale`` (default 1), in the canonical signal's unit
(:data:`~cnctwin.thread.signals.SIGNALS`); ``unit``, when given, must be that unit (a map
that says ``"m"`` for ``x_mm`` is refused, not converted). A command is read back at the
symbol of the same name in ``[signals]`` (the value the PLC applied, Heide 2025 section 2.4:
"a read-back of the updated variable allows direct verification"), or at its own symbol when
``[signals]`` does not name it.

Values are little-endian, as ADS carries them (Beckhoff Infosys, "ADS data types").
"""

from __future__ import annotations

import math
import struct
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from cnctwin.errors import ConfigError
from cnctwin.thread.signals import COMMANDS, SIGNALS

__all__ = ["PLC_TYPES", "PlcType", "Symbol", "SymbolMap", "load_symbol_map", "parse_symbol_map"]


@dataclass(frozen=True)
class PlcType:
    """One IEC 61131-3 elementary type as ADS carries it.

    Attributes
    ----------
    name
        TwinCAT's name (``"LREAL"``).
    fmt
        :mod:`struct` format, little-endian.
    size
        Bytes.
    ads_type
        ADS data type id of the symbol information (ADST_*: Beckhoff TcAdsDef.h).
    integer
        Whether values are integers (``BOOL`` included).
    """

    name: str
    fmt: str
    size: int
    ads_type: int
    integer: bool

    @property
    def low(self) -> float:
        """Smallest raw value the type holds (``-inf`` for the floats)."""
        if not self.integer:
            return -math.inf
        if self.name == "BOOL" or self.fmt[-1].isupper():
            return 0.0
        return float(-(2 ** (8 * self.size - 1)))

    @property
    def high(self) -> float:
        """Largest raw value the type holds (``inf`` for the floats)."""
        if not self.integer:
            return math.inf
        if self.name == "BOOL":
            return 1.0
        bits = 8 * self.size - (0 if self.fmt[-1].isupper() else 1)
        return float(2**bits - 1)


#: The elementary types a map may name, by TwinCAT name (aliases BYTE, WORD, DWORD, LWORD).
PLC_TYPES: dict[str, PlcType] = {
    t.name: t
    for t in (
        PlcType("BOOL", "<B", 1, 33, True),
        PlcType("SINT", "<b", 1, 16, True),
        PlcType("USINT", "<B", 1, 17, True),
        PlcType("BYTE", "<B", 1, 17, True),
        PlcType("INT", "<h", 2, 2, True),
        PlcType("UINT", "<H", 2, 18, True),
        PlcType("WORD", "<H", 2, 18, True),
        PlcType("DINT", "<i", 4, 3, True),
        PlcType("UDINT", "<I", 4, 19, True),
        PlcType("DWORD", "<I", 4, 19, True),
        PlcType("LINT", "<q", 8, 20, True),
        PlcType("ULINT", "<Q", 8, 21, True),
        PlcType("LWORD", "<Q", 8, 21, True),
        PlcType("REAL", "<f", 4, 4, False),
        PlcType("LREAL", "<d", 8, 5, False),
    )
}


@dataclass(frozen=True)
class Symbol:
    """Where one signal lives in the PLC and how it is encoded.

    Attributes
    ----------
    symbol
        The PLC symbol name (``"GVL_Twin.fActPosX"``, ``"MAIN.fbAxisX.NcToPlc.ActPos"``).
    type
        Its type.
    scale
        Engineering value (canonical unit) = raw value x ``scale``.
    """

    symbol: str
    type: PlcType
    scale: float = 1.0

    def decode(self, raw: bytes) -> float:
        """Engineering value of the raw bytes (NaN and infinities are returned as such).

        Raises
        ------
        ValueError
            ``raw`` is not :attr:`PlcType.size` bytes long.
        """
        if len(raw) != self.type.size:
            raise ValueError(f"{len(raw)} bytes where {self.type.name} has {self.type.size}")
        value = float(struct.unpack(self.type.fmt, raw)[0])
        return value * self.scale if self.scale != 1.0 else value

    def encode(self, value: float) -> bytes:
        """Raw bytes of the engineering ``value``.

        Raises
        ------
        ValueError
            ``value`` is not finite, or does not fit the type after scaling (integer types
            round to the nearest raw value).
        """
        if not math.isfinite(value):
            raise ValueError(f"{value!r} is not a finite number")
        raw = value / self.scale
        if self.type.integer:
            raw = float(round(raw))
        if not self.type.low <= raw <= self.type.high or not math.isfinite(raw):
            raise ValueError(
                f"{value!r} does not fit {self.type.name} with scale {self.scale:g} "
                f"(raw range {self.type.low:g}..{self.type.high:g})"
            )
        return struct.pack(self.type.fmt, int(raw) if self.type.integer else raw)

    def __str__(self) -> str:
        text = f"{self.symbol} ({self.type.name}"
        return f"{text}, scale {self.scale:g})" if self.scale != 1.0 else f"{text})"


@dataclass(frozen=True)
class SymbolMap:
    """A parsed symbol map.

    Attributes
    ----------
    signals
        Canonical signal -> symbol, read every cycle.
    commands
        Command (a name of :data:`~cnctwin.thread.signals.COMMANDS`) -> symbol it is written to.
    source
        Where the map came from (a path), for messages.
    """

    signals: Mapping[str, Symbol]
    commands: Mapping[str, Symbol]
    source: str

    def readback(self, command: str) -> Symbol:
        """The symbol a command is read back at: its signal's, else its own."""
        return self.signals.get(command) or self.commands[command]


_KEYS = {"symbol", "type", "scale", "unit"}


def _entry(where: str, name: str, data: object, *, command: bool) -> Symbol:
    def bad(why: str) -> ConfigError:
        return ConfigError(
            f'{where}: {name}: {why} (expected {{ symbol = "GVL.name", type = "LREAL", '
            "scale = 1.0, unit = ... }})"
        )

    catalogue = COMMANDS if command else SIGNALS
    if name not in catalogue:
        kind = "command" if command else "signal"
        raise ConfigError(f"{where}: unknown {kind} {name!r} (valid: {', '.join(catalogue)})")
    if not isinstance(data, dict):
        raise bad(f"{type(data).__name__} is not a table")
    unknown = set(data) - _KEYS
    if unknown:
        raise bad(f"unknown key(s) {', '.join(sorted(unknown))}")
    symbol = data.get("symbol")
    if not isinstance(symbol, str) or not symbol.strip() or len(symbol) > 255:
        raise bad(f"symbol {symbol!r} is not a name of 1-255 characters")
    type_name = data.get("type")
    if not isinstance(type_name, str) or type_name.upper() not in PLC_TYPES:
        raise bad(f"type {type_name!r} is not one of {', '.join(PLC_TYPES)}")
    plc_type = PLC_TYPES[type_name.upper()]
    scale = data.get("scale", 1.0)
    if isinstance(scale, bool) or not isinstance(scale, int | float):
        raise bad(f"scale {scale!r} is not a number")
    if not math.isfinite(scale) or scale == 0.0 or (plc_type.name == "BOOL" and scale != 1.0):
        raise bad(f"scale {scale!r} must be finite and non-zero (1 for BOOL)")
    unit = data.get("unit")
    expected = catalogue[name].unit
    if unit is not None and unit != expected:
        raise bad(f"unit {unit!r} is not the signal's unit {expected!r} (scale converts to it)")
    return Symbol(symbol.strip(), plc_type, float(scale))


def parse_symbol_map(data: Mapping[str, object], source: str) -> SymbolMap:
    """A symbol map from parsed TOML.

    Raises
    ------
    ConfigError
        One line naming ``source``, the entry and what would be valid.
    """
    unknown = set(data) - {"signals", "commands"}
    if unknown:
        raise ConfigError(
            f"{source}: unknown table(s) {', '.join(sorted(unknown))} (valid: signals, commands)"
        )
    tables: list[dict[str, Symbol]] = []
    for key in ("signals", "commands"):
        table = data.get(key, {})
        if not isinstance(table, dict):
            raise ConfigError(f"{source}: [{key}] is not a table")
        where = f"{source} [{key}]"
        tables.append(
            {
                name: _entry(where, name, entry, command=key == "commands")
                for name, entry in table.items()
            }
        )
    signals, commands = tables
    if not signals:
        raise ConfigError(f"{source}: [signals] maps no signal; map at least one")
    return SymbolMap(signals, commands, source)


def load_symbol_map(path: Path) -> SymbolMap:
    """Read a symbol map file.

    Raises
    ------
    ConfigError
        The file is missing, not TOML, or an entry is invalid (one line).
    """
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise ConfigError(f"ADS symbol map {path}: cannot read ({err})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"ADS symbol map {path}: not TOML ({err})") from None
    return parse_symbol_map(data, str(path))
