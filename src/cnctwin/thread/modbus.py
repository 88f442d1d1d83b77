"""Modbus TCP machine connection (pymodbus client) with batched reads and mapped commands.

The default map is the virtual machine's (:data:`cnctwin.thread.modbus_map.READ_MAP` for
reading, :data:`~cnctwin.thread.modbus_map.WRITE_MAP` for commands); ``[connection] mapping``
overrides single signals with ``"TABLE:ADDRESS:TYPE[:SCALE]"`` strings (docs/modbus.md), or
removes one with ``"none"``. A command given in the mapping is written and read back at that
address, which must be a holding register or a coil.

A read plans the fewest contiguous block reads that cover every mapped address
(:func:`~cnctwin.thread.modbus_map.plan_reads`): the virtual machine's map is one request.
Values that decode to garbage (NaN or infinite floats, the type's "invalid" marker, values
outside a signal's plausible range of :data:`~cnctwin.thread.signals.SIGNALS`) go to
:attr:`Reading.rejected`, as do the signals of a block the device answered with an exception.

Modbus has no time stamps. A reading's sample counter (:attr:`Reading.sequence`) is the
``heartbeat`` register when it is mapped (the virtual machine increments it once per tick):
the twin takes a reading whose counter has not moved as no new sample. Without it, every
answered read counts as a new sample at its receive time.
"""

from __future__ import annotations

import logging

from pymodbus.client import AsyncModbusTcpClient
from pymodbus.exceptions import ConnectionException, ModbusException
from pymodbus.pdu import ModbusPDU

from cnctwin.errors import ConfigError, DataError
from cnctwin.thread.config import ConnectionConfig
from cnctwin.thread.connection import (
    CommandRejected,
    ConnectionLost,
    MachineConnection,
    Reading,
    now_s,
)
from cnctwin.thread.endpoint import split_endpoint
from cnctwin.thread.modbus_map import (
    READ_MAP,
    WRITE_MAP,
    ReadBlock,
    RegisterAddress,
    parse_address,
    plan_reads,
)
from cnctwin.thread.signals import COMMANDS, SIGNALS, implausible

__all__ = ["ModbusConnection", "modbus_maps", "parse_endpoint"]

logger = logging.getLogger(__name__)

_ILLEGAL_ADDRESS = 2
_EXCEPTION_NAMES = {
    1: "ILLEGAL FUNCTION",
    2: "ILLEGAL DATA ADDRESS",
    3: "ILLEGAL DATA VALUE",
    4: "SERVER DEVICE FAILURE",
    6: "SERVER DEVICE BUSY",
    11: "GATEWAY TARGET DEVICE FAILED TO RESPOND",
}


def parse_endpoint(endpoint: str) -> tuple[str, int]:
    """Host and port of ``modbus://HOST[:PORT]`` (port 502 when absent).

    Raises
    ------
    ConfigError
        One line naming the endpoint and the expected form.
    """
    host, port, _ = split_endpoint(
        endpoint,
        scheme="modbus",
        default_port=502,
        what="Modbus",
        form="modbus://HOST:PORT",
        example="modbus://127.0.0.1:5020",
    )
    return host, port


def modbus_maps(
    mapping: dict[str, str],
) -> tuple[dict[str, RegisterAddress], dict[str, RegisterAddress]]:
    """Read map and write map: the virtual machine's, with ``mapping`` overriding signals.

    Parameters
    ----------
    mapping
        Canonical signal name -> ``"TABLE:ADDRESS:TYPE[:SCALE]"`` or ``"none"``.

    Raises
    ------
    ConfigError
        An unknown signal, a malformed address, or a command mapped to a read-only table.
    """
    read_map = dict(READ_MAP)
    write_map = dict(WRITE_MAP)
    for name, text in mapping.items():
        if name not in SIGNALS:
            raise ConfigError(
                f"[connection] mapping names unknown signal {name!r} (valid: {', '.join(SIGNALS)})"
            )
        if text.strip().lower() == "none":
            read_map.pop(name, None)
            write_map.pop(name, None)
            continue
        addr = parse_address(text, name)
        if name in COMMANDS:
            if not addr.writable:
                raise ConfigError(
                    f"Modbus address {text!r} of command {name!r} is in read-only table "
                    f"{addr.table!r} (a command needs hr or coil)"
                )
            write_map[name] = addr
        read_map[name] = addr
    return read_map, write_map


class ModbusConnection(MachineConnection):
    """A machine over Modbus TCP.

    Parameters
    ----------
    config
        ``[connection]`` with ``transport = "modbus"``, ``endpoint = "modbus://HOST:PORT"``,
        ``unit_id``, timeouts, backoff and ``mapping``.

    Attributes
    ----------
    read_map, write_map
        Signal -> address for reading and for commands.
    blocks
        The planned block reads of one :meth:`read`.
    """

    def __init__(self, config: ConnectionConfig) -> None:
        self._init_from_config(config, "modbus", "Modbus")
        self.host, self.port = parse_endpoint(config.endpoint)
        self.unit_id = config.unit_id
        self.read_map, self.write_map = modbus_maps(config.mapping)
        self.blocks: list[ReadBlock] = plan_reads(self.read_map)
        self._client: AsyncModbusTcpClient | None = None

    # Transport hooks ------------------------------------------------------------------
    async def _open(self) -> None:
        client = AsyncModbusTcpClient(
            self.host,
            port=self.port,
            timeout=self.timeout_s,
            retries=0,
            reconnect_delay=0,
            name=f"cnctwin-{self.host}:{self.port}",
            trace_connect=self._on_link,
        )
        self._client = client
        if not await client.connect():
            raise ConnectionLost(f"no Modbus server at {self.host}:{self.port}")

    async def _close(self) -> None:
        if self._client is not None:
            self._client.close()
            self._client = None

    async def _read(self) -> Reading:
        values: dict[str, float] = {}
        rejected: dict[str, str] = {}
        pending = list(self.blocks)
        planned: list[ReadBlock] = []
        while pending:
            block = pending.pop(0)
            response = await self._request_read(block)
            if response.isError() and _code(response) == _ILLEGAL_ADDRESS and block.bridges_gaps:
                split = plan_reads(block.signals, bridge_gaps=False)
                logger.info(
                    "device refused %s across unmapped addresses; reading %d blocks instead",
                    _describe(block),
                    len(split),
                )
                pending[:0] = split
                continue
            planned.append(block)
            _decode_block(block, response, values, rejected)
        self.blocks = planned
        # Modbus carries no time stamps: the heartbeat register (incremented by the machine
        # once per sample) is the reading's sample counter when it is mapped.
        return Reading(
            values=values,
            received_s=now_s(),
            rejected=rejected,
            sequence=values.get("heartbeat"),
        )

    async def _read_signal(self, name: str) -> float:
        """One signal in one request of its own registers (a command's read-back)."""
        addr = self.read_map.get(name)
        if addr is None:
            raise DataError(f"machine signal {name!r} unusable: not mapped")
        values: dict[str, float] = {}
        rejected: dict[str, str] = {}
        block = ReadBlock(addr.table, addr.address, addr.width, {name: addr})
        _decode_block(block, await self._request_read(block), values, rejected)
        if name not in values:
            raise DataError(f"machine signal {name!r} unusable: {rejected[name]}")
        return values[name]

    async def _write(self, name: str, value: float) -> None:
        addr = self.write_map.get(name)
        if addr is None:
            raise ConfigError(
                f"command {name!r} has no Modbus address (commands: {', '.join(self.write_map)})"
            )
        try:
            raw = addr.encode(value)
        except ValueError as err:
            raise CommandRejected(f"command {name}={value!r} at {addr}: {err}") from None
        client = self._require_client()
        try:
            if addr.is_bit:
                response = await client.write_coil(
                    addr.address, bool(raw[0]), device_id=self.unit_id
                )
            elif len(raw) == 1:
                response = await client.write_register(addr.address, raw[0], device_id=self.unit_id)
            else:
                response = await client.write_registers(addr.address, raw, device_id=self.unit_id)
        except ModbusException as err:
            raise ConnectionLost(str(err)) from err
        if response.isError():
            spec = COMMANDS[name]
            raise CommandRejected(
                f"machine refused command {name}={value!r} at {addr}: "
                f"{_exception_name(response)}; valid: {spec.low:g}..{spec.high:g} {spec.unit}"
            )

    # Helpers --------------------------------------------------------------------------
    def _on_link(self, up: bool) -> None:
        """pymodbus' connect/disconnect callback: fail a pending request at once when the
        device closes the connection (pymodbus itself would wait for the timeout)."""
        client = self._client
        if up or client is None:
            return
        pending = client.ctx.response_future
        if not pending.done():
            pending.set_exception(ConnectionException("connection closed by the device"))
            pending.exception()  # retrieved: no "never retrieved" warning if nobody waits

    def _require_client(self) -> AsyncModbusTcpClient:
        client = self._client
        if client is None or not client.connected:
            raise ConnectionLost(f"Modbus connection to {self.host}:{self.port} is closed")
        return client

    async def _request_read(self, block: ReadBlock) -> ModbusPDU:
        client = self._require_client()
        read = {
            "ir": client.read_input_registers,
            "hr": client.read_holding_registers,
            "coil": client.read_coils,
            "di": client.read_discrete_inputs,
        }[block.table]
        try:
            return await read(block.start, count=block.count, device_id=self.unit_id)
        except ModbusException as err:
            raise ConnectionLost(str(err)) from err


def _decode_block(
    block: ReadBlock, response: ModbusPDU, values: dict[str, float], rejected: dict[str, str]
) -> None:
    """Decode the answer to ``block`` into ``values``, garbage and refusals into ``rejected``."""
    if response.isError():
        reason = f"device answered {_exception_name(response)} to {_describe(block)}"
        rejected.update(dict.fromkeys(block.signals, reason))
        return
    raw = response.bits if block.table in ("coil", "di") else response.registers
    for name, addr in block.signals.items():
        offset = addr.address - block.start
        value = addr.decode(list(raw[offset : offset + addr.width]))
        why = implausible(name, value)
        if why is None and value is not None:
            values[name] = value
        else:
            rejected[name] = f"{why} at {addr}"


def _code(response: ModbusPDU) -> int:
    return int(getattr(response, "exception_code", 0))


def _exception_name(response: ModbusPDU) -> str:
    code = _code(response)
    return f"exception {code} ({_EXCEPTION_NAMES.get(code, 'unknown')})"


def _describe(block: ReadBlock) -> str:
    return f"a read of {block.table}:{block.start}..{block.start + block.count - 1}"
