"""Beckhoff ADS machine connection (pyads) with sum-reads and mapped commands.

The endpoint is ``ads://AMSNETID[:AMSPORT]@HOST[:PORT]``: the PLC's AMS Net ID and AMS port
(default 851, the first TwinCAT 3 PLC runtime, the port Heide 2025 section 2.4 reads), and the
host and TCP port of its AMS router (default 48898). The symbol map
(:mod:`cnctwin.thread.ads_map`, ``[connection] symbol_map``) names a PLC symbol, its type and
scale for each canonical signal and command.

Opening a connection (pyads' bundled AdsLib routes in-process on Linux and macOS; on Windows
the TwinCAT router does, and steps 1 and 2's route are TwinCAT's; docs/ads.md):

1. this computer's AMS Net ID is set (``[connection] local_net_id``, else the IPv4 address it
   reaches the PLC from plus ``.1.1``): the PLC answers only a Net ID its static route names;
2. a route to the PLC's Net ID over ``HOST:PORT`` is added, an AMS port opened, the ADS
   timeout set to 80 % of ``timeout_s``, and the PLC's ADS state read (it must answer);
3. every mapped symbol is resolved by name (ADSIGRP_SYM_INFOBYNAMEEX) to its index group,
   index offset, size and ADS type. A symbol the PLC does not know, or whose size or
   elementary type differs from the map's (an enumeration or alias, ADS type 65, is checked
   by size), is unusable: its signal is rejected in every reading (and its
   command refused) with that reason; the others go on. Symbols are resolved anew on each
   reconnection (an online change may move them).

A read is one ADS sum-read (ADSIGRP_SUMUP_READ, at most :data:`MAX_SUB_COMMANDS` symbols
a request) of every usable signal, decoded here from the raw bytes. A value that is not a
finite number, lies outside the signal's plausible range, or that the PLC answers with an
ADS error goes to :attr:`Reading.rejected`; a sum-read answer of the wrong size rejects its
signals. ADS carries no time stamps: the ``heartbeat`` symbol, when mapped, is the reading's
sample counter (as for Modbus).

A command is range-checked against :data:`~cnctwin.thread.signals.COMMANDS`, encoded and
written once (ADS write by index group and offset); a refusal by the PLC (an ADS device
error) is :class:`~cnctwin.thread.connection.CommandRejected`, a lost connection
:class:`~cnctwin.thread.connection.ConnectionLost`. Nothing is retried: a write whose answer
was lost may or may not have been applied, and the twin's read-back decides (docs/control.md).

pyads' calls block: they run one at a time on a thread of their own, so requests keep their
order and the event loop never waits on the network.
"""

from __future__ import annotations

import asyncio
import ctypes
import logging
import socket
import struct
import sys
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar
from urllib.parse import urlsplit

from pyads import pyads_ex
from pyads.errorcodes import ERROR_CODES
from pyads.pyads_ex import ADSError
from pyads.structs import AmsAddr, SAdsSumRequest

from cnctwin.errors import ConfigError, DataError
from cnctwin.examples import example_file
from cnctwin.thread.ads_map import Symbol, SymbolMap, load_symbol_map
from cnctwin.thread.config import ConnectionConfig
from cnctwin.thread.connection import (
    CommandRejected,
    ConnectionLost,
    MachineConnection,
    Reading,
    now_s,
)
from cnctwin.thread.signals import COMMANDS, implausible

__all__ = [
    "DEFAULT_AMS_PORT",
    "DEFAULT_TCP_PORT",
    "MAX_SUB_COMMANDS",
    "AdsConnection",
    "AdsEndpoint",
    "default_symbol_map",
    "parse_endpoint",
    "parse_net_id",
]

logger = logging.getLogger(__name__)

#: AMS port of the first TwinCAT 3 PLC runtime.
DEFAULT_AMS_PORT = 851
#: TCP port of the AMS router (ADS over TCP).
DEFAULT_TCP_PORT = 48898
#: Most symbols one sum-read asks for (Beckhoff's recommended limit; pyads uses the same).
MAX_SUB_COMMANDS = 500

_ADSIGRP_SUMUP_READ = 0xF080
#: ADS device errors (0x700-0x73F): the PLC answered and refused. Everything else (router
#: errors below 0x700, client errors from 0x740 such as 0x745 "timeout elapsed", AdsLib's
#: socket errors) means the PLC was not reached.
_DEVICE_ERRORS = range(0x700, 0x740)
_SYMBOL_NOT_FOUND = 0x710
#: pyads' AdsLib routes in this process (Linux, macOS, BSD); on Windows the TwinCAT router
#: service does, with the routes and the Net ID configured in TwinCAT.
_IN_PROCESS_ROUTER = sys.platform != "win32"
#: ADS type of a symbol whose type is not elementary (an enumeration, an alias): its size
#: alone is checked.
_BIGTYPE = 65

T = TypeVar("T")


@dataclass(frozen=True)
class AdsEndpoint:
    """Where a PLC is.

    Attributes
    ----------
    net_id
        The PLC's AMS Net ID (``"5.80.201.232.1.1"``).
    ams_port
        Its AMS port (851: PLC runtime 1).
    host, port
        Host and TCP port of its AMS router.
    """

    net_id: str
    ams_port: int
    host: str
    port: int

    def __str__(self) -> str:
        return f"ads://{self.net_id}:{self.ams_port}@{self.host}:{self.port}"


def parse_net_id(text: str, what: str) -> str:
    """``text`` checked as an AMS Net ID: six numbers 0-255 separated by dots.

    Raises
    ------
    ConfigError
        One line naming ``what`` and the value.
    """
    parts = text.split(".")
    if len(parts) != 6 or not all(p.isdigit() and int(p) <= 255 for p in parts):
        raise ConfigError(
            f"{what} {text!r} is not an AMS Net ID (six numbers 0-255, e.g. 5.80.201.232.1.1)"
        )
    return ".".join(str(int(p)) for p in parts)


def parse_endpoint(endpoint: str) -> AdsEndpoint:
    """The PLC of ``ads://AMSNETID[:AMSPORT]@HOST[:PORT]``.

    Raises
    ------
    ConfigError
        One line naming the endpoint and the expected form.
    """
    form = (
        f"ADS endpoint {endpoint!r} is not of the form ads://AMSNETID[:AMSPORT]@HOST[:PORT] "
        "(e.g. ads://5.80.201.232.1.1:851@192.168.0.10)"
    )
    parts = urlsplit(endpoint)
    try:
        port = parts.port
        ams_port_text = parts.password
    except ValueError:
        raise ConfigError(form) from None
    if (
        parts.scheme != "ads"
        or not parts.hostname
        or not parts.username
        or parts.path not in ("", "/")
        or parts.query
        or parts.fragment
    ):
        raise ConfigError(form)
    net_id = parse_net_id(parts.username, "ADS endpoint's AMS Net ID")
    ams_port = DEFAULT_AMS_PORT
    if ams_port_text is not None:
        if not ams_port_text.isdigit() or not 1 <= int(ams_port_text) <= 65535:
            raise ConfigError(f"{form}: AMS port {ams_port_text!r} is not 1-65535")
        ams_port = int(ams_port_text)
    return AdsEndpoint(net_id, ams_port, parts.hostname, DEFAULT_TCP_PORT if port is None else port)


def default_symbol_map() -> SymbolMap:
    """The packaged ``ads_symbols.toml``: every canonical signal in ``GVL_Twin``."""
    from importlib.resources import as_file

    with as_file(example_file("ads_symbols.toml")) as path:
        return load_symbol_map(Path(path))


def _describe(code: int) -> str:
    return f"ADS error {code} ({ERROR_CODES.get(code, 'unknown')})"


def _type_name(info: Any) -> str:
    """The PLC's name of a symbol's type, from its symbol information ("?" when unreadable)."""
    try:
        return str(info.symbol_type)[:64] or "?"
    except (UnicodeDecodeError, ValueError):
        return "?"


def _ads_timeout_ms(timeout_s: float) -> int:
    """AdsLib's own timeout: 80 % of the connection's, so that a request the PLC leaves
    unanswered ends with ADS error 1861 on the connection's thread before the connection's
    timeout abandons it (the next request would queue behind it)."""
    return max(1, round(0.8 * timeout_s * 1e3))


def _lost(err: ADSError) -> bool:
    return err.err_code not in _DEVICE_ERRORS


def _local_net_id(host: str, port: int) -> str:
    """The IPv4 address this computer reaches ``host`` from, plus ``.1.1`` (TwinCAT's
    convention for a Net ID). A UDP socket's connect sends nothing."""
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            probe.connect((host, port))
            address = probe.getsockname()[0]
    except OSError as err:
        raise ConnectionLost(f"cannot find a route to {host}: {err}") from err
    return f"{address}.1.1"


@dataclass(frozen=True)
class _Resolved:
    """A symbol's place in the PLC, found at connection."""

    group: int
    offset: int


class AdsConnection(MachineConnection):
    """A machine over Beckhoff ADS (TwinCAT), through pyads.

    Parameters
    ----------
    config
        ``[connection]`` with ``transport = "ads"``, ``endpoint = "ads://..."``, timeouts,
        backoff, ``symbol_map`` and ``local_net_id``.
    base_dir
        Folder ``symbol_map`` is relative to (the configuration file's).

    Attributes
    ----------
    endpoint
        The PLC.
    symbols
        The symbol map.
    unusable
        Signal or command -> why its symbol cannot be used (not found, wrong size or type),
        from the last connection.
    request_count
        ADS requests made (symbol resolution, sum-reads, writes, read-backs).
    """

    def __init__(self, config: ConnectionConfig, base_dir: Path | None = None) -> None:
        self._init_from_config(config, "ads", "ADS")
        self.endpoint = parse_endpoint(config.endpoint)
        self._local_net_id = (
            None
            if config.local_net_id is None
            else parse_net_id(config.local_net_id, "[connection] local_net_id")
        )
        if config.symbol_map is None:
            self.symbols = default_symbol_map()
        else:
            path = Path(config.symbol_map)
            if not path.is_absolute() and base_dir is not None:
                path = base_dir / path
            self.symbols = load_symbol_map(path)
        self.unusable: dict[str, str] = {}
        self.request_count = 0
        self._addr = AmsAddr(self.endpoint.net_id, self.endpoint.ams_port)
        self._port: int | None = None
        self._places: dict[str, _Resolved] = {}
        self._executor = ThreadPoolExecutor(1, thread_name_prefix="cnctwin-ads")

    # Blocking pyads calls, one at a time on the connection's thread ----------------------
    async def _call(self, fn: Callable[..., T], *args: Any) -> T:
        return await asyncio.get_running_loop().run_in_executor(self._executor, fn, *args)

    def _request(self, fn: Any, *args: Any) -> Any:
        """One ADS request on the open port; :class:`ConnectionLost` when not reached."""
        if self._port is None:
            raise ConnectionLost(f"ADS connection to {self.endpoint} is closed")
        self.request_count += 1
        try:
            return fn(self._port, self._addr, *args)
        except ADSError as err:
            if _lost(err):
                raise ConnectionLost(f"{_describe(err.err_code)} from {self.endpoint}") from err
            raise

    # Transport hooks ------------------------------------------------------------------
    async def _open(self) -> None:
        await self._call(self._open_blocking)

    def _open_blocking(self) -> None:
        endpoint = self.endpoint
        local = "the TwinCAT router's"
        try:
            if _IN_PROCESS_ROUTER:
                local = self._local_net_id or _local_net_id(endpoint.host, endpoint.port)
                pyads_ex.adsSetLocalAddress(AmsAddr(local, 0).netIdStruct())
            self._port = pyads_ex.adsPortOpenEx()
            pyads_ex.adsSyncSetTimeoutEx(self._port, _ads_timeout_ms(self.timeout_s))
            if _IN_PROCESS_ROUTER:
                route = f"{endpoint.host}:{endpoint.port}"
                pyads_ex.adsAddRoute(self._addr.netIdStruct(), route)
        except ADSError as err:
            self._close_blocking()
            raise ConnectionLost(
                f"no AMS router at {endpoint.host}:{endpoint.port}: {_describe(err.err_code)}"
            ) from err
        try:
            self._request(pyads_ex.adsSyncReadStateReqEx)
            self._resolve()
        except ConnectionLost:
            self._close_blocking()
            raise
        except (ADSError, RuntimeError) as err:
            self._close_blocking()
            why = _describe(err.err_code) if isinstance(err, ADSError) else str(err)
            raise ConnectionLost(f"PLC {endpoint} did not give its state: {why}") from err
        logger.info(
            "ADS connection to %s (local Net ID %s): %d symbols, %d unusable",
            endpoint,
            local,
            len(self._places),
            len(self.unusable),
        )

    def _resolve(self) -> None:
        """Find every mapped symbol's index group and offset; check size and type."""
        self._places = {}
        self.unusable = {}
        entries = [(n, s) for n, s in self.symbols.signals.items()] + [
            (f"command {n}", s) for n, s in self.symbols.commands.items()
        ]
        for key, symbol in entries:
            try:
                info = self._request(pyads_ex.adsGetSymbolInfo, symbol.symbol)
            except ConnectionLost:
                raise
            except (RuntimeError, ValueError) as err:  # pyads: an answer of the wrong length
                self.unusable[key] = f"symbol {symbol.symbol}: malformed symbol information ({err})"
                continue
            except ADSError as err:
                why = (
                    "not found in the PLC"
                    if err.err_code == _SYMBOL_NOT_FOUND
                    else f"answered {_describe(err.err_code)}"
                )
                self.unusable[key] = f"symbol {symbol.symbol} {why}"
                continue
            data_type = int(info.dataType)
            if info.size != symbol.type.size or data_type not in (symbol.type.ads_type, _BIGTYPE):
                self.unusable[key] = (
                    f"symbol {symbol.symbol} is {_type_name(info)} ({info.size} bytes, "
                    f"ADS type {info.dataType}) in the PLC, {symbol.type.name} "
                    f"({symbol.type.size} bytes, ADS type {symbol.type.ads_type}) in "
                    f"{self.symbols.source}"
                )
                continue
            self._places[key] = _Resolved(int(info.iGroup), int(info.iOffs))
        for key, why in self.unusable.items():
            logger.warning("ADS %s unusable: %s", key, why)

    async def _close(self) -> None:
        await self._call(self._close_blocking)

    def _close_blocking(self) -> None:
        port, self._port = self._port, None
        if port is None:
            return
        calls: list[tuple[Any, tuple[Any, ...]]] = [(pyads_ex.adsPortCloseEx, (port,))]
        if _IN_PROCESS_ROUTER:
            calls.insert(0, (pyads_ex.adsDelRoute, (self._addr.netIdStruct(),)))
        for call, args in calls:
            try:
                call(*args)
            except ADSError as err:
                logger.debug("ADS close: %s", _describe(err.err_code))

    async def close(self) -> None:
        """Stop reconnecting, close the route and the port, end the connection's thread."""
        await super().close()
        self._executor.shutdown(wait=False)

    async def _read(self) -> Reading:
        return await self._call(self._read_blocking)

    def _read_blocking(self) -> Reading:
        values: dict[str, float] = {}
        rejected = {n: why for n, why in self.unusable.items() if n in self.symbols.signals}
        usable = [(n, s) for n, s in self.symbols.signals.items() if n in self._places]
        for start in range(0, len(usable), MAX_SUB_COMMANDS):
            self._sum_read(usable[start : start + MAX_SUB_COMMANDS], values, rejected)
        return Reading(
            values=values, received_s=now_s(), rejected=rejected, sequence=values.get("heartbeat")
        )

    def _sum_read(
        self,
        chunk: list[tuple[str, Symbol]],
        values: dict[str, float],
        rejected: dict[str, str],
    ) -> None:
        """One ADSIGRP_SUMUP_READ: n error codes (uint32), then each symbol's bytes."""
        requests = (SAdsSumRequest * len(chunk))()
        for request, (name, symbol) in zip(requests, chunk, strict=True):
            place = self._places[name]
            request.iGroup, request.iOffset, request.size = (
                place.group,
                place.offset,
                symbol.type.size,
            )
        expected = 4 * len(chunk) + sum(symbol.type.size for _, symbol in chunk)
        try:
            # pyads' adsSumReadBytes, with the answer's length checked: a short answer would
            # otherwise leave zeros in the buffer, read as values
            answer = bytes(
                self._request(
                    pyads_ex.adsSyncReadWriteReqEx2,
                    _ADSIGRP_SUMUP_READ,
                    len(chunk),
                    None,
                    requests,
                    None,
                    False,
                    True,
                )
            )
        except ConnectionLost:
            raise
        except RuntimeError as err:  # pyads: "Insufficient data (expected N bytes, M were read)"
            rejected.update(dict.fromkeys((n for n, _ in chunk), f"sum-read: {err}"))
            return
        except ADSError as err:
            rejected.update(
                dict.fromkeys((n for n, _ in chunk), f"sum-read: {_describe(err.err_code)}")
            )
            return
        if len(answer) != expected:
            why = f"sum-read answer of {len(answer)} bytes, expected {expected}"
            rejected.update(dict.fromkeys((n for n, _ in chunk), why))
            return
        codes = struct.unpack_from(f"<{len(chunk)}I", answer)
        offset = 4 * len(chunk)
        for (name, symbol), code in zip(chunk, codes, strict=True):
            raw = answer[offset : offset + symbol.type.size]
            offset += symbol.type.size
            if code:
                rejected[name] = f"PLC answered {_describe(code)} for {symbol}"
                continue
            self._accept(name, symbol, raw, values, rejected)

    @staticmethod
    def _accept(
        name: str, symbol: Symbol, raw: bytes, values: dict[str, float], rejected: dict[str, str]
    ) -> None:
        value = symbol.decode(raw)
        why = implausible(name, value)
        if why is None:
            values[name] = value
        else:
            rejected[name] = f"{why} at {symbol}"

    async def _read_signal(self, name: str) -> float:
        """One signal in one ADS read of its own symbol (a command's read-back)."""
        return await self._call(self._read_signal_blocking, name)

    def _read_signal_blocking(self, name: str) -> float:
        if name in self.symbols.signals:
            key, symbol = name, self.symbols.signals[name]
        elif name in self.symbols.commands:
            key, symbol = f"command {name}", self.symbols.commands[name]
        else:
            raise DataError(f"machine signal {name!r} unusable: not in {self.symbols.source}")
        if key not in self._places:
            raise DataError(f"machine signal {name!r} unusable: {self.unusable.get(key)}")
        place = self._places[key]
        buffer_type = ctypes.c_ubyte * symbol.type.size
        try:
            raw = self._request(
                pyads_ex.adsSyncReadReqEx2, place.group, place.offset, buffer_type, True
            )
        except ADSError as err:
            raise DataError(
                f"machine signal {name!r}: PLC answered {_describe(err.err_code)}"
            ) from None
        except ConnectionLost:
            raise
        except RuntimeError as err:  # pyads: fewer bytes than asked for
            raise DataError(f"machine signal {name!r} at {symbol}: {err}") from None
        values: dict[str, float] = {}
        rejected: dict[str, str] = {}
        self._accept(name, symbol, bytes(raw), values, rejected)
        if name not in values:
            raise DataError(f"machine signal {name!r} unusable: {rejected[name]}")
        return values[name]

    async def _write(self, name: str, value: float) -> None:
        await self._call(self._write_blocking, name, value)

    def _write_blocking(self, name: str, value: float) -> None:
        symbol = self.symbols.commands.get(name)
        if symbol is None:
            raise CommandRejected(
                f"command {name!r} has no symbol in {self.symbols.source} "
                f"(commands: {', '.join(self.symbols.commands) or 'none'})"
            )
        place = self._places.get(f"command {name}")
        if place is None:
            raise CommandRejected(f"command {name}: {self.unusable.get(f'command {name}')}")
        spec = COMMANDS[name]
        assert spec.low is not None and spec.high is not None
        if not spec.low <= value <= spec.high:  # NaN fails too
            raise CommandRejected(
                f"command {name}={value!r} outside {spec.low:g}..{spec.high:g} {spec.unit}"
            )
        try:
            raw = symbol.encode(value)
        except ValueError as err:
            raise CommandRejected(f"command {name}={value!r} at {symbol}: {err}") from None
        buffer_type = ctypes.c_ubyte * len(raw)
        try:
            self._request(
                pyads_ex.adsSyncWriteReqEx,
                place.group,
                place.offset,
                buffer_type.from_buffer_copy(raw),
                buffer_type,
            )
        except ADSError as err:
            raise CommandRejected(
                f"PLC refused command {name}={value!r} at {symbol}: {_describe(err.err_code)}; "
                f"valid: {spec.low:g}..{spec.high:g} {spec.unit}"
            ) from None
