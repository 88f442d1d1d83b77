"""A Beckhoff ADS server for the virtual machine: pyads' test server serving a symbol map.

The server is pyads' own :class:`pyads.testserver.AdsTestServer` with its
``AdvancedHandler`` (symbols by name, symbol information, sum-reads, writes by index group and
offset), holding one PLC variable for every symbol of a symbol map (default: the packaged
``ads_symbols.toml``, a ``GVL_Twin`` global variable list). :meth:`AdsMachineServer.publish`
writes the machine's snapshot into the signal symbols after each clock tick (encoded as the
map says; a value an integer symbol cannot hold leaves it unchanged). A write to a command
symbol is decoded, applied with ``source.command`` on the event loop, and answered with ADS
error 1803 ("invalid parameter value(s)") when the machine refuses it (out of range); a write
to a signal symbol with ADS error 1827 ("access denied"); a name
the map does not declare is answered with ADS error 1808 ("symbol not found"), where pyads'
handler would leave the request unanswered. What a client reads back is what the machine
applied.

ADS has no authentication here: like Modbus TCP, the server listens on loopback unless told
``insecure``.
"""

from __future__ import annotations

import asyncio
import logging
import struct
from collections.abc import Mapping
from typing import Any

from pyads import constants
from pyads.testserver import AdsTestServer, AdvancedHandler
from pyads.testserver.advanced_handler import PLCVariable
from pyads.testserver.handler import AmsPacket, AmsResponseData

from cnctwin.errors import CnctwinError
from cnctwin.thread import Symbol, SymbolMap, default_symbol_map
from cnctwin.virtual.exposure import check_exposure
from cnctwin.virtual.modbus_server import MachineSource

__all__ = ["AdsMachineServer"]

logger = logging.getLogger(__name__)

_INVALID_PARAMETER = 1803
_SYMBOL_NOT_FOUND = 1808
_ACCESS_DENIED = 1827
_COMMAND_TIMEOUT_S = 5.0


class _MachineHandler(AdvancedHandler):  # type: ignore[misc]
    """pyads' AdvancedHandler, with writes to command symbols applied to the machine."""

    def __init__(self, on_write: Any) -> None:
        super().__init__()
        self.on_write = on_write
        self.commands: dict[tuple[int, int], tuple[str, Symbol]] = {}
        self.read_only: set[tuple[int, int]] = set()

    def handle_request(self, request: AmsPacket) -> AmsResponseData:
        command_id = struct.unpack("<H", request.ams_header.command_id)[0]
        state = struct.pack("<H", struct.unpack("<H", request.ams_header.state_flags)[0] | 1)
        if command_id == constants.ADSCOMMAND_WRITE:
            data = request.ams_header.data
            group, offset, length = struct.unpack_from("<III", data)
            if group == constants.ADSIGRP_SYM_VALBYHND:  # a write by handle (by name)
                try:
                    variable = self.get_variable_by_handle(offset)
                except KeyError:
                    return AmsResponseData(
                        state, request.ams_header.error_code, _result(_SYMBOL_NOT_FOUND)
                    )
                group, offset = variable.index_group, variable.index_offset
            target = self.commands.get((group, offset))
            if target is not None:
                code = self.on_write(target[0], target[1], bytes(data[12 : 12 + length]))
                if code:
                    return AmsResponseData(state, request.ams_header.error_code, _result(code))
            elif (group, offset) in self.read_only:
                return AmsResponseData(
                    state, request.ams_header.error_code, _result(_ACCESS_DENIED)
                )
        try:
            return super().handle_request(request)
        except KeyError:  # a name or place the map does not declare
            return AmsResponseData(
                state, request.ams_header.error_code, _result(_SYMBOL_NOT_FOUND) + bytes(4)
            )


def _result(code: int) -> bytes:
    return struct.pack("<I", code)


class AdsMachineServer:
    """ADS server for one machine. Use as ``async with``.

    Parameters
    ----------
    source
        The machine: ``snapshot()`` and ``command(name, value)``.
    host
        Interface to listen on; a non-loopback one needs ``insecure``.
    port
        TCP port; 0 picks a free one (see :attr:`port` once started).
    symbols
        The symbol map; ``None`` takes the packaged ``ads_symbols.toml``.
    net_id
        The AMS Net ID the endpoint names (the server answers any).
    insecure
        Allow a non-loopback ``host`` (:func:`~cnctwin.virtual.exposure.check_exposure`).
    """

    def __init__(
        self,
        source: MachineSource,
        host: str = "127.0.0.1",
        port: int = 0,
        symbols: SymbolMap | None = None,
        net_id: str = "127.0.0.1.1.1",
        insecure: bool = False,
    ) -> None:
        check_exposure(host, "ads", secured=False, insecure=insecure)
        if symbols is None:
            symbols = default_symbol_map()
        self.source = source
        self.host = host
        self.symbols = symbols
        self.net_id = net_id
        self._port = port
        self._server: AdsTestServer | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self.handler = _MachineHandler(self._on_write)
        self._variables: dict[str, PLCVariable] = {}
        for symbol in [*symbols.signals.values(), *symbols.commands.values()]:
            if symbol.symbol in self._variables:
                continue
            variable = PLCVariable(
                symbol.symbol, bytes(symbol.type.size), symbol.type.ads_type, symbol.type.name
            )
            self._variables[symbol.symbol] = variable
            self.handler.add_variable(variable)
        for name, symbol in symbols.commands.items():
            variable = self._variables[symbol.symbol]
            self.handler.commands[(variable.index_group, variable.index_offset)] = (name, symbol)
        self.handler.read_only = {
            (v.index_group, v.index_offset) for v in self._variables.values()
        } - set(self.handler.commands)

    @property
    def port(self) -> int:
        """TCP port the server listens on (the free one chosen when started with port 0)."""
        return self._port

    @property
    def endpoint(self) -> str:
        """``ads://NETID:851@HOST:PORT``, for :class:`cnctwin.thread.config.ConnectionConfig`."""
        return f"ads://{self.net_id}:851@{self.host}:{self._port}"

    @property
    def request_history(self) -> list[Any]:
        """Every AMS packet received since started (pyads' record), oldest first."""
        return [] if self._server is None else self._server.request_history

    def variable(self, symbol: str) -> PLCVariable:
        """The PLC variable of ``symbol`` (tests set its raw bytes)."""
        return self._variables[symbol]

    def publish(self, snapshot: Mapping[str, float] | None = None) -> None:
        """Write ``snapshot`` (default: ``source.snapshot()``) into the signal symbols, and the
        applied commands into their command symbols."""
        snap = self.source.snapshot() if snapshot is None else snapshot
        for table in (self.symbols.signals, self.symbols.commands):
            for name, symbol in table.items():
                value = snap.get(name)
                if value is None:
                    continue
                try:
                    raw = symbol.encode(float(value))
                except ValueError:
                    if symbol.type.integer:
                        continue
                    raw = struct.pack(symbol.type.fmt, float(value))
                self._variables[symbol.symbol].value = raw

    def _on_write(self, name: str, symbol: Symbol, raw: bytes) -> int:
        """A write to a command symbol (in a server thread): apply it, 0 or an ADS error."""
        loop = self._loop
        if loop is None or len(raw) != symbol.type.size:
            return _INVALID_PARAMETER
        value = symbol.decode(raw)

        async def apply() -> None:
            self.source.command(name, value)

        try:
            asyncio.run_coroutine_threadsafe(apply(), loop).result(_COMMAND_TIMEOUT_S)
        except (CnctwinError, ValueError) as err:
            logger.info("ADS write %s=%r refused: %s", name, value, err)
            return _INVALID_PARAMETER
        self.publish()
        return 0

    async def start(self) -> None:
        """Publish the current snapshot and start listening."""
        self._loop = asyncio.get_running_loop()
        self.publish()
        server = AdsTestServer(
            handler=self.handler, ip_address=self.host, port=self._port, logging=False
        )
        server.server.listen(5)  # listening before the thread starts: no race with a client
        self._port = server.server.getsockname()[1]
        server.start()
        self._server = server
        logger.info("ADS server listening at %s", self.endpoint)

    async def stop(self) -> None:
        """Stop listening and drop every client connection."""
        server, self._server = self._server, None
        if server is not None:
            await asyncio.get_running_loop().run_in_executor(None, _close, server)
            logger.info("ADS server at %s stopped", self.endpoint)

    async def __aenter__(self) -> AdsMachineServer:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()


def _close(server: AdsTestServer) -> None:
    server.close()
    server.join(2.0)
