"""A Modbus TCP server (pymodbus) that exposes a machine's signals and takes its commands.

The register map is :mod:`cnctwin.thread.modbus_map` (documented in docs/modbus.md): every
canonical signal in one contiguous input-register block (float32 big-endian, integers as
uint16/uint32), the commands as scaled integers in holding registers and as coils, the applied
flags as discrete inputs. :meth:`ModbusMachineServer.publish` refreshes the block after each
clock tick. A write is decoded, checked against the command's range
(:data:`cnctwin.thread.signals.COMMANDS`) and applied with ``source.command``; a value out of
range, or one the machine refuses, is answered with the Modbus exception ILLEGAL DATA VALUE
(code 3). The values of one request are range-checked together before any is applied, so a
request with a value out of range changes nothing. What a client reads back is what the
machine applied.
"""

from __future__ import annotations

import logging
import math
from collections import Counter
from collections.abc import Mapping
from typing import Protocol

from pymodbus.constants import ExcCodes
from pymodbus.pdu import ModbusPDU
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice
from pymodbus.simulator.simutils import SimUtils

from cnctwin.errors import CnctwinError
from cnctwin.thread import (
    COMMANDS,
    READ_MAP,
    STATUS_MAP,
    WRITE_MAP,
    RegisterAddress,
)
from cnctwin.virtual.exposure import check_exposure

__all__ = ["MachineSource", "ModbusMachineServer"]

logger = logging.getLogger(__name__)

#: Modbus function code -> table it accesses (pymodbus calls the action with these).
_FUNCTION_TABLES = {1: "coil", 5: "coil", 15: "coil", 2: "di", 4: "ir"} | dict.fromkeys(
    (3, 6, 16, 22, 23), "hr"
)
_HR_MAP = {name: addr for name, addr in WRITE_MAP.items() if addr.table == "hr"}
_COIL_MAP = {name: addr for name, addr in WRITE_MAP.items() if addr.table == "coil"}


class MachineSource(Protocol):
    """What a server exposes: the virtual machine, or a fake in tests."""

    def snapshot(self) -> Mapping[str, float]:
        """Current value of every signal (canonical names)."""
        ...

    def command(self, name: str, value: float) -> None:
        """Apply one command; raise :class:`cnctwin.errors.CnctwinError` (ValueError) if invalid."""
        ...


def _table_words(mapping: Mapping[str, RegisterAddress]) -> int:
    return max(addr.address + addr.width for addr in mapping.values())


class ModbusMachineServer:
    """Modbus TCP server for one machine. Use as ``async with``.

    Parameters
    ----------
    source
        The machine: ``snapshot()`` and ``command(name, value)``.
    host
        Interface to listen on; a non-loopback one needs ``insecure`` (Modbus TCP has no
        authentication: anyone who reaches the port can write the commands).
    port
        TCP port; 0 picks a free one (see :attr:`port` once started).
    unit_id
        Modbus unit (slave) id the device answers to.
    insecure
        Allow a non-loopback ``host`` (:func:`~cnctwin.virtual.exposure.check_exposure`).

    Attributes
    ----------
    request_counts
        Requests received, by Modbus function code (3 = read holding registers, 4 = read input
        registers, 5/6/15/16 = writes).
    """

    def __init__(
        self,
        source: MachineSource,
        host: str = "127.0.0.1",
        port: int = 0,
        unit_id: int = 1,
        insecure: bool = False,
    ) -> None:
        check_exposure(host, "modbus", secured=False, insecure=insecure)
        self.source = source
        self.host = host
        self.unit_id = unit_id
        self.request_counts: Counter[int] = Counter()
        self._port = port
        self._server: ModbusTcpServer | None = None
        self._ir_words = [0] * _table_words(READ_MAP)
        self._snapshot: dict[str, float] = {}
        self._hr_by_address = {addr.address: (name, addr) for name, addr in _HR_MAP.items()}
        self._coil_by_address = {addr.address: (name, addr) for name, addr in _COIL_MAP.items()}

    @property
    def port(self) -> int:
        """TCP port the server listens on (the free one chosen when started with port 0)."""
        return self._port

    @property
    def endpoint(self) -> str:
        """``modbus://HOST:PORT``, for :class:`cnctwin.thread.config.ConnectionConfig`."""
        return f"modbus://{self.host}:{self._port}"

    def publish(self, snapshot: Mapping[str, float] | None = None) -> None:
        """Refresh the register block from ``snapshot`` (default: ``source.snapshot()``).

        A value the register cannot hold (NaN in an integer register, a value out of the
        type's range, a missing signal) is published as the type's "invalid" marker.
        """
        snap = dict(self.source.snapshot() if snapshot is None else snapshot)
        words = self._ir_words
        for name, addr in READ_MAP.items():
            value = snap.get(name)
            raw = addr.encode_or_invalid(None if value is None else float(value))
            words[addr.address : addr.address + addr.width] = raw
        self._snapshot = snap

    async def start(self) -> None:
        """Publish the current snapshot and start listening."""
        self.publish()
        device = SimDevice(
            self.unit_id,
            simdata=(
                [SimData(0, values=[False] * 16, datatype=DataType.BITS)],
                [SimData(0, values=[False] * 16, datatype=DataType.BITS)],
                [SimData(0, count=_table_words(_HR_MAP), datatype=DataType.REGISTERS)],
                [SimData(0, count=len(self._ir_words), datatype=DataType.REGISTERS)],
            ),
            action=self._action,
        )
        server = ModbusTcpServer(device, address=(self.host, self._port), trace_pdu=self._trace_pdu)
        await server.serve_forever(background=True)
        self._server = server
        self._port = server.transport.sockets[0].getsockname()[1]  # type: ignore[union-attr,attr-defined]
        logger.info("Modbus server listening at %s (unit %d)", self.endpoint, self.unit_id)

    async def stop(self) -> None:
        """Stop listening and drop every client connection."""
        if self._server is not None:
            await self._server.shutdown()
            self._server = None
            logger.info("Modbus server at %s stopped", self.endpoint)

    async def __aenter__(self) -> ModbusMachineServer:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

    # pymodbus hooks -------------------------------------------------------------------
    def _trace_pdu(self, sending: bool, pdu: ModbusPDU) -> ModbusPDU:
        if not sending:
            self.request_counts[pdu.function_code] += 1
        return pdu

    async def _action(
        self,
        function_code: int,
        start_address: int,
        address: int,
        count: int,
        registers: list[int],
        values: list[int] | list[bool] | None,
    ) -> ExcCodes | None:
        """Called by pymodbus before every access; fills reads, applies writes."""
        table = _FUNCTION_TABLES[function_code]
        if values is not None:
            by_address = self._coil_by_address if table == "coil" else self._hr_by_address
            return self._write(by_address, address, values)
        if table == "ir":
            registers[: len(self._ir_words)] = self._ir_words
        elif table == "hr":
            for name, addr in _HR_MAP.items():
                raw = addr.encode_or_invalid(self._snapshot.get(name))
                registers[addr.address : addr.address + addr.width] = raw
        else:
            bit_map = _COIL_MAP if table == "coil" else STATUS_MAP
            bits = [False] * 16 * (len(registers) - 1)
            for name, addr in bit_map.items():
                value = self._snapshot.get(name, 0.0)
                bits[addr.address] = math.isfinite(value) and value != 0.0
            registers[: len(registers) - 1] = SimUtils.bitsToRegisters(bits)
        return None

    def _write(
        self,
        by_address: Mapping[int, tuple[str, RegisterAddress]],
        address: int,
        values: list[int] | list[bool],
    ) -> ExcCodes | None:
        """Decode, check and apply a write of ``values`` at ``address``; rewrite ``values``
        in place to what the machine applied."""
        commands: list[tuple[int, str, RegisterAddress, float]] = []
        for offset in range(len(values)):
            entry = by_address.get(address + offset)
            if entry is None:
                return ExcCodes.ILLEGAL_ADDRESS
            name, addr = entry
            value = addr.decode([int(values[offset])])
            spec = COMMANDS[name]
            if value is None or not math.isfinite(value):
                logger.warning("refused write of an invalid raw value to %s", name)
                return ExcCodes.ILLEGAL_VALUE
            low = -math.inf if spec.low is None else spec.low
            high = math.inf if spec.high is None else spec.high
            if not low <= value <= high:
                logger.warning("refused write %s=%g: valid %g..%g", name, value, low, high)
                return ExcCodes.ILLEGAL_VALUE
            commands.append((offset, name, addr, value))
        for _, name, _, value in commands:
            try:
                self.source.command(name, value)
            except (CnctwinError, ValueError) as err:
                logger.warning("machine refused %s=%g: %s", name, value, err)
                self.publish()
                return ExcCodes.ILLEGAL_VALUE
        self.publish()
        for offset, name, addr, _ in commands:
            raw = addr.encode_or_invalid(self._snapshot.get(name))
            values[offset] = bool(raw[0]) if addr.is_bit else raw[0]  # type: ignore[call-overload]
        return None
