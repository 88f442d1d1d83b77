"""Modbus register addresses, the virtual machine's register map, and batched-read planning.

An address is written ``"TABLE:ADDRESS:TYPE[:SCALE]"``:

- ``TABLE``: ``ir`` (input registers, read-only), ``hr`` (holding registers), ``coil``
  or ``di`` (discrete inputs, read-only);
- ``ADDRESS``: 0-based protocol address (register 30001 of a manual is ``ir:0``);
- ``TYPE``: ``uint16``, ``int16``, ``uint32``, ``int32``, ``float32`` (registers) or
  ``bool`` (coils and discrete inputs); 32-bit values are big-endian in bytes and in
  words: the register at ``ADDRESS`` holds the high word (order "ABCD");
- ``SCALE``: engineering value = raw value x ``SCALE`` (default 1).

Integer raw values with every bit set in the unsigned types (``0xFFFF``, ``0xFFFFFFFF``) and
the most negative value of the signed types (``0x8000``, ``0x80000000``) mean "no valid
value", as in the SunSpec Modbus information models; a float32 has NaN for that.

The virtual machine's map (:data:`READ_MAP`, :data:`WRITE_MAP`; docs/modbus.md) puts every
canonical signal in one contiguous input-register block, so one request reads them all, and
the commands in holding registers and coils.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from cnctwin.errors import ConfigError

__all__ = [
    "MAX_BITS_PER_READ",
    "MAX_REGISTERS_PER_READ",
    "READ_MAP",
    "STATUS_MAP",
    "TABLES",
    "TYPES",
    "WRITE_MAP",
    "ReadBlock",
    "RegisterAddress",
    "parse_address",
    "plan_reads",
]

#: Tables: name -> (writable, holds bits).
TABLES: dict[str, tuple[bool, bool]] = {
    "ir": (False, False),
    "hr": (True, False),
    "coil": (True, True),
    "di": (False, True),
}

#: Types: name -> (struct format, registers, raw value meaning "invalid" or None).
TYPES: dict[str, tuple[str, int, int | None]] = {
    "uint16": (">H", 1, 0xFFFF),
    "int16": (">h", 1, -0x8000),
    "uint32": (">I", 2, 0xFFFFFFFF),
    "int32": (">i", 2, -0x80000000),
    "float32": (">f", 2, None),
    "bool": ("", 1, None),
}

#: Most registers one read request may return (Modbus application protocol v1.1b3, 6.3/6.4).
MAX_REGISTERS_PER_READ = 125
#: Most coils or discrete inputs one read request may return (same, 6.1/6.2).
MAX_BITS_PER_READ = 2000


@dataclass(frozen=True)
class RegisterAddress:
    """Where one signal lives and how it is encoded.

    Attributes
    ----------
    table
        ``"ir"``, ``"hr"``, ``"coil"`` or ``"di"``.
    address
        0-based protocol address of the first register (or bit).
    type
        One of :data:`TYPES`.
    scale
        Engineering value = raw x ``scale``.
    """

    table: str
    address: int
    type: str
    scale: float = 1.0

    @property
    def width(self) -> int:
        """Registers (or bits) the value occupies."""
        return TYPES[self.type][1]

    @property
    def writable(self) -> bool:
        """Whether the table accepts writes (holding registers and coils)."""
        return TABLES[self.table][0]

    @property
    def is_bit(self) -> bool:
        """Whether the table holds bits (coils and discrete inputs)."""
        return TABLES[self.table][1]

    def encode(self, value: float) -> list[int]:
        """Raw registers (or 0/1 bits) for the engineering ``value``.

        Raises
        ------
        ValueError
            ``value`` is not finite (integer types) or does not fit the type after scaling.
        """
        if self.type == "bool":
            return [1 if value else 0]
        fmt, _, _ = TYPES[self.type]
        raw: float | int = _scaled(value, 1.0 / self.scale)
        if self.type != "float32":
            if not math.isfinite(raw):
                raise ValueError(f"{value!r} cannot be encoded as {self.type}")
            raw = round(raw)
        try:
            data = struct.pack(fmt, raw)
        except (struct.error, OverflowError) as err:
            raise ValueError(
                f"{value!r} does not fit {self.type} with scale {self.scale:g}"
            ) from err
        return [int.from_bytes(data[i : i + 2], "big") for i in range(0, len(data), 2)]

    def encode_or_invalid(self, value: float | None) -> list[int]:
        """Like :meth:`encode`, but the type's "invalid" marker for a value that does not fit."""
        if value is None:
            return self.invalid()
        try:
            return self.encode(value)
        except ValueError:
            return self.invalid()

    def invalid(self) -> list[int]:
        """Raw registers meaning "no valid value" (NaN for float32, 0 for bool)."""
        if self.type == "bool":
            return [0]
        if self.type == "float32":
            return self.encode(math.nan)
        fmt, _, marker = TYPES[self.type]
        data = struct.pack(fmt, marker)
        return [int.from_bytes(data[i : i + 2], "big") for i in range(0, len(data), 2)]

    def decode(self, raw: list[int]) -> float | None:
        """Engineering value of the raw registers (bits), ``None`` for the invalid marker.

        A float32 NaN or infinity is returned as such (the caller rejects it).
        """
        if self.type == "bool":
            return 1.0 if raw[0] else 0.0
        fmt, _, marker = TYPES[self.type]
        data = b"".join(int(word).to_bytes(2, "big") for word in raw)
        value = struct.unpack(fmt, data)[0]
        if marker is not None and value == marker:
            return None
        return _scaled(float(value), self.scale)

    def __str__(self) -> str:
        text = f"{self.table}:{self.address}:{self.type}"
        return text if self.scale == 1.0 else f"{text}:{self.scale:g}"


def _scaled(value: float, scale: float) -> float:
    """``value`` x ``scale``, divided by ``1 / scale`` when that is an integer (so that
    5555 x 0.01 is 55.55, not 55.550000000000004)."""
    inverse = 1.0 / scale
    exact = math.isfinite(inverse) and inverse == round(inverse)
    return value / inverse if exact else value * scale


def parse_address(text: str, signal: str) -> RegisterAddress:
    """Parse ``"TABLE:ADDRESS:TYPE[:SCALE]"`` for ``signal``.

    Raises
    ------
    ConfigError
        One line naming the signal, the bad string and what would be valid.
    """

    def bad(why: str) -> ConfigError:
        return ConfigError(
            f"Modbus address {text!r} of signal {signal!r}: {why} "
            "(expected TABLE:ADDRESS:TYPE[:SCALE], e.g. 'hr:0:uint16:0.01')"
        )

    parts = text.strip().split(":")
    if len(parts) not in (3, 4):
        raise bad(f"{len(parts)} field(s)")
    table, address_text, type_ = (part.strip().lower() for part in parts[:3])
    if table not in TABLES:
        raise bad(f"table {table!r} is not one of {', '.join(TABLES)}")
    try:
        address = int(address_text, 0)
    except ValueError:
        raise bad(f"address {address_text!r} is not an integer") from None
    if type_ not in TYPES:
        raise bad(f"type {type_!r} is not one of {', '.join(TYPES)}")
    is_bit = TABLES[table][1]
    if is_bit != (type_ == "bool"):
        raise bad(f"table {table} needs type {'bool' if is_bit else 'a register type'}")
    if not 0 <= address <= 0xFFFF - TYPES[type_][1] + 1:
        raise bad(f"address {address} is outside 0..65535")
    scale = 1.0
    if len(parts) == 4:
        try:
            scale = float(parts[3])
        except ValueError:
            raise bad(f"scale {parts[3]!r} is not a number") from None
        if not math.isfinite(scale) or scale == 0.0 or type_ == "bool":
            raise bad(f"scale {parts[3]!r} must be a finite non-zero number on a register type")
    return RegisterAddress(table, address, type_, scale)


@dataclass(frozen=True)
class ReadBlock:
    """One read request: a contiguous range of one table and the signals it covers.

    Attributes
    ----------
    table
        Table read.
    start, count
        First address and number of registers (bits).
    signals
        Signal name -> its address, for every signal inside the range.
    """

    table: str
    start: int
    count: int
    signals: Mapping[str, RegisterAddress]

    @property
    def bridges_gaps(self) -> bool:
        """Whether the range includes addresses no signal is mapped to."""
        covered: set[int] = set()
        for addr in self.signals.values():
            covered.update(range(addr.address, addr.address + addr.width))
        return len(covered) < self.count


def plan_reads(
    addresses: Mapping[str, RegisterAddress], *, bridge_gaps: bool = True
) -> list[ReadBlock]:
    """The fewest contiguous block reads that cover every address.

    Addresses of one table are merged into one request as long as the request stays within
    :data:`MAX_REGISTERS_PER_READ` registers (:data:`MAX_BITS_PER_READ` bits); the unmapped
    addresses between them are read and ignored. With ``bridge_gaps=False`` only touching or
    overlapping ranges are merged (for devices that refuse reads of unmapped addresses).
    """
    blocks: list[ReadBlock] = []
    for table in TABLES:
        limit = MAX_BITS_PER_READ if TABLES[table][1] else MAX_REGISTERS_PER_READ
        members = sorted(
            ((name, addr) for name, addr in addresses.items() if addr.table == table),
            key=lambda item: (item[1].address, item[0]),
        )
        current: dict[str, RegisterAddress] = {}
        start = end = 0
        for name, addr in members:
            addr_end = addr.address + addr.width
            joins = bridge_gaps or addr.address <= end
            if current and joins and max(end, addr_end) - start <= limit:
                current[name] = addr
                end = max(end, addr_end)
                continue
            if current:
                blocks.append(ReadBlock(table, start, end - start, current))
            current, start, end = {name: addr}, addr.address, addr_end
        if current:
            blocks.append(ReadBlock(table, start, end - start, current))
    return blocks


def _parse_all(texts: Iterable[tuple[str, str]]) -> dict[str, RegisterAddress]:
    return {name: parse_address(text, name) for name, text in texts}


#: The virtual machine's input-register block: every canonical signal, read in one request.
#: Commands appear here as the values the machine applied (their read-back).
READ_MAP: dict[str, RegisterAddress] = _parse_all(
    [
        ("t_s", "ir:0:float32"),
        ("x_mm", "ir:2:float32"),
        ("y_mm", "ir:4:float32"),
        ("z_mm", "ir:6:float32"),
        ("feed_mm_min", "ir:8:float32"),
        ("spindle_rpm", "ir:10:float32"),
        ("spindle_rpm_command", "ir:12:float32"),
        ("spindle_torque_nm", "ir:14:float32"),
        ("spindle_current_a", "ir:16:float32"),
        ("spindle_power_w", "ir:18:float32"),
        ("load_x_pct", "ir:20:float32"),
        ("load_y_pct", "ir:22:float32"),
        ("load_z_pct", "ir:24:float32"),
        ("force_x_n", "ir:26:float32"),
        ("force_y_n", "ir:28:float32"),
        ("force_z_n", "ir:30:float32"),
        ("feed_override_pct", "ir:32:float32"),
        ("spindle_override_pct", "ir:34:float32"),
        ("tool_length_wear_mm", "ir:36:float32"),
        ("tool_radius_wear_mm", "ir:38:float32"),
        ("program_line", "ir:40:uint32"),
        ("heartbeat", "ir:42:uint32"),
        ("tool_number", "ir:44:uint16"),
        ("work_offset", "ir:45:uint16"),
        ("run_state", "ir:46:uint16"),
        ("feed_hold", "ir:47:uint16"),
        ("stop", "ir:48:uint16"),
        ("emergency_stop", "ir:49:uint16"),
    ]
)

#: Where the virtual machine takes commands: scaled integers in holding registers (one
#: register each, so a write is never split) and the three flags (feed hold, stop, emergency
#: stop) as coils.
WRITE_MAP: dict[str, RegisterAddress] = _parse_all(
    [
        ("feed_override_pct", "hr:0:uint16:0.01"),
        ("spindle_override_pct", "hr:1:uint16:0.01"),
        ("tool_length_wear_mm", "hr:2:int16:0.0001"),
        ("tool_radius_wear_mm", "hr:3:int16:0.0001"),
        ("feed_hold", "coil:0:bool"),
        ("stop", "coil:1:bool"),
        ("emergency_stop", "coil:2:bool"),
    ]
)

#: The virtual machine's discrete inputs: the applied state of the three flags (for PLCs
#: that read bits).
STATUS_MAP: dict[str, RegisterAddress] = _parse_all(
    [("feed_hold", "di:0:bool"), ("stop", "di:1:bool"), ("emergency_stop", "di:2:bool")]
)
