"""Write-to-read-back latency of a machine connection, after Heide 2025 section 2.5.

The method: write a new feed override, poll the machine's feedback of it until the new value
appears, repeat ``n`` times with a pause between round trips (Heide 2025: 500 round trips,
500 ms apart, mean 34.2 ms, sigma 4.5 ms, 27.8-51.4 ms over ADS/EtherCAT/PROFIBUS). Write
time, the time of the read that saw the new value, and the whole round trip are reported as
mean, standard deviation, min, median, 99th percentile and max.

Jitter (Heide 2025: uniform random delays of +-5, 10, 20 ms added before each write and read)
is injected here by :class:`JitterProxy`, a loopback TCP proxy between client and server that
holds every client-to-server message (each write and each read request) for a delay drawn
uniformly from ``[0, 2 J]`` ms (J +- J), keeping the byte order; the server-to-client
direction is not delayed (one-way jitter). It works for any TCP transport (OPC UA, Modbus
TCP) without touching client or server.

A read-only transport (MTConnect) takes no write: :func:`measure_read_latency` times the
read round trip alone (one batched read: for MTConnect a ``/sample`` request and its parsed
answer, what the twin does each cycle), with the same pauses, jitter and statistics.

Everything here takes a :class:`~cnctwin.thread.connection.MachineConnection` and is
transport-agnostic, but for :func:`measure_broker_latency`: MQTT's publish-to-receive round
trip through a broker (``cnctwin bench latency --transport mqtt``).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import random
import time
from collections.abc import Callable, Coroutine, Sequence
from dataclasses import asdict, dataclass, replace
from types import TracebackType
from typing import Any
from urllib.parse import urlsplit, urlunsplit

import numpy as np

from cnctwin.errors import ConfigError, DataError, InputError
from cnctwin.thread.config import ConnectionConfig
from cnctwin.thread.connection import MachineConnection
from cnctwin.thread.signals import COMMANDS

__all__ = [
    "JitterProxy",
    "LatencyResult",
    "LatencyStats",
    "measure_broker_latency",
    "measure_endpoint_latency",
    "measure_latency",
    "measure_read_latency",
]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class LatencyStats:
    """Summary of durations, all in ms.

    Attributes
    ----------
    mean, std
        Mean and sample standard deviation (ddof 1; 0 for one sample).
    min, median, p99, max
        Order statistics; ``p99`` by linear interpolation (numpy's default).
    """

    mean: float
    std: float
    min: float
    median: float
    p99: float
    max: float

    @classmethod
    def of(cls, samples_s: Sequence[float]) -> LatencyStats:
        """Statistics of durations given in s (reported in ms)."""
        if not samples_s:
            raise DataError("no latency samples to summarise; run at least one round trip")
        ms = np.asarray(samples_s, dtype=float) * 1e3
        return cls(
            mean=float(ms.mean()),
            std=float(ms.std(ddof=1)) if ms.size > 1 else 0.0,
            min=float(ms.min()),
            median=float(np.median(ms)),
            p99=float(np.percentile(ms, 99.0)),
            max=float(ms.max()),
        )


@dataclass(frozen=True)
class LatencyResult:
    """One latency measurement.

    Attributes
    ----------
    n
        Round trips measured.
    round_trip_ms
        From the start of the write to the end of the read that saw the new value, ms (a
        read-only transport: the read alone).
    write_ms
        Duration of the write request (until the server's answer), ms; ``None`` for a
        read-only transport.
    read_ms
        Duration of the read that returned the new value, ms: for the read-back sent with the
        write (:meth:`~cnctwin.thread.connection.MachineConnection.write_read_back`), from the
        write's answer to the read's; for a later poll, the whole request.
    polls_mean
        Reads per round trip, mean (1 when the read-back is immediate).
    signal
        The command written and polled (``"read"`` for a read-only transport).
    interval_ms
        Pause between round trips, ms.
    jitter_ms
        Injected one-way jitter J (delays uniform in [0, 2 J] ms), 0 for none.
    security
        OPC UA message security of the measured session (``"None"``, or
        ``"Basic256Sha256 Sign"`` / ``"Basic256Sha256 SignAndEncrypt"``); ``None`` for
        transports without it and where the caller did not say.
    """

    n: int
    round_trip_ms: LatencyStats
    write_ms: LatencyStats | None
    read_ms: LatencyStats
    polls_mean: float
    signal: str
    interval_ms: float
    jitter_ms: float
    security: str | None = None

    def to_dict(self) -> dict[str, object]:
        """Plain dict for JSON; durations rounded to 1 us."""

        def stats(s: LatencyStats) -> dict[str, float]:
            return {k: round(v, 3) for k, v in asdict(s).items()}

        return {
            "n": self.n,
            "round_trip_ms": stats(self.round_trip_ms),
            "write_ms": None if self.write_ms is None else stats(self.write_ms),
            "read_ms": stats(self.read_ms),
            "polls_mean": round(self.polls_mean, 3),
            "signal": self.signal,
            "interval_ms": self.interval_ms,
            "jitter_ms": self.jitter_ms,
            "security": self.security,
        }


def _check_run(n: int, interval_s: float) -> None:
    """A latency run of ``n`` round trips ``interval_s`` s apart; ConfigError unless n >= 1
    and the pause a number >= 0 s."""
    if n < 1 or not math.isfinite(interval_s) or interval_s < 0:
        raise ConfigError(f"latency run n={n}, interval_s={interval_s}; valid: n >= 1, >= 0 s")


def _targets(name: str, start: float, n: int) -> list[float]:
    """``n`` setpoints of command ``name``, each different from the one before and from
    ``start``: ten steps below ``start`` (whole units where the range allows), cycled."""
    spec = COMMANDS[name]
    if spec.kind == "bool":
        return [float((i + 1 + round(start)) % 2) for i in range(n)]
    low = spec.low if spec.low is not None else start - 10.0
    high = spec.high if spec.high is not None else start + 10.0
    step = min(1.0, (high - low) / 20.0)
    top = min(max(start, low + 10.0 * step), high)
    return [top - step * (1 + i % 10) for i in range(n)]


async def measure_latency(
    connection: MachineConnection,
    *,
    n: int = 500,
    interval_s: float = 0.5,
    signal: str = "feed_override_pct",
    timeout_s: float = 2.0,
    jitter_ms: float = 0.0,
    progress: Callable[[int], None] | None = None,
    pipelined: bool = True,
) -> LatencyResult:
    """Measure ``n`` write-to-read-back round trips of ``signal`` (Heide 2025, section 2.5).

    Each round trip is :meth:`~cnctwin.thread.connection.MachineConnection.write_read_back`
    (over OPC UA, ``pipelined``, the read-back is on its way before the write is answered),
    then reads of the feedback until it shows the value written (a read-back the server
    answered before the write, or a machine that applies the write later, takes another
    read).

    Parameters
    ----------
    connection
        A connected machine connection (any transport).
    n
        Round trips (>= 1).
    interval_s
        Pause between round trips, s (>= 0; Heide 2025: 0.5 s).
    signal
        Command to write and poll (a name of :data:`~cnctwin.thread.signals.COMMANDS`).
    timeout_s
        Longest wait for the feedback to change, s; longer raises :class:`DataError`.
    jitter_ms
        Jitter injected on the path (by a :class:`JitterProxy`), recorded in the result, ms.
    progress
        Called with the number of round trips done after each one.
    pipelined
        Send the first read-back without waiting for the write's answer where the transport
        can (OPC UA); ``False`` waits for it, as a :class:`JitterProxy` needs to give the
        write and the read a delay each.

    Returns
    -------
    LatencyResult
        Write, read and round-trip statistics in ms. The command is set back to the value it
        had before the measurement.
    """
    _check_run(n, interval_s)
    if signal not in COMMANDS:
        raise ConfigError(f"latency signal {signal!r}; valid: {', '.join(COMMANDS)}")
    start = await connection.read_signal(signal)
    writes: list[float] = []
    reads: list[float] = []
    trips: list[float] = []
    polls = 0
    try:
        for i, target in enumerate(_targets(signal, start, n)):
            t0 = time.perf_counter()
            back = await connection.write_read_back(signal, target, pipelined=pipelined)
            value, read_s = back.value, back.read_s
            polls += 1
            while abs(value - target) > 1e-6 * max(1.0, abs(target)):
                r0 = time.perf_counter()
                if r0 - t0 > timeout_s:
                    raise DataError(
                        f"feedback of {signal} stayed {value} for {r0 - t0:.3f} s after "
                        f"writing {target} (timeout {timeout_s} s)"
                    )
                value = await connection.read_signal(signal)
                read_s = time.perf_counter() - r0
                polls += 1
            writes.append(back.write_s)
            reads.append(read_s)
            trips.append(time.perf_counter() - t0)
            if progress is not None:
                progress(i + 1)
            if interval_s:
                await asyncio.sleep(interval_s)
    finally:
        with contextlib.suppress(Exception):
            await connection.write(signal, start)
    return LatencyResult(
        n=n,
        round_trip_ms=LatencyStats.of(trips),
        write_ms=LatencyStats.of(writes),
        read_ms=LatencyStats.of(reads),
        polls_mean=polls / n,
        signal=signal,
        interval_ms=interval_s * 1e3,
        jitter_ms=jitter_ms,
    )


async def measure_read_latency(
    connection: MachineConnection,
    *,
    n: int = 500,
    interval_s: float = 0.5,
    jitter_ms: float = 0.0,
    progress: Callable[[int], None] | None = None,
) -> LatencyResult:
    """Measure ``n`` read round trips of a read-only connection (Heide 2025's pauses and
    statistics without the write).

    Parameters
    ----------
    connection
        A connected machine connection.
    n
        Round trips (>= 1).
    interval_s
        Pause between round trips, s (>= 0).
    jitter_ms
        Jitter injected on the path, recorded in the result, ms.
    progress
        Called with the number of round trips done after each one.

    Returns
    -------
    LatencyResult
        ``round_trip_ms`` and ``read_ms`` both the batched read's duration; ``write_ms``
        ``None``.
    """
    _check_run(n, interval_s)
    reads: list[float] = []
    for i in range(n):
        t0 = time.perf_counter()
        await connection.read()
        reads.append(time.perf_counter() - t0)
        if progress is not None:
            progress(i + 1)
        if interval_s:
            await asyncio.sleep(interval_s)
    stats = LatencyStats.of(reads)
    return LatencyResult(
        n=n,
        round_trip_ms=stats,
        write_ms=None,
        read_ms=stats,
        polls_mean=1.0,
        signal="read",
        interval_ms=interval_s * 1e3,
        jitter_ms=jitter_ms,
    )


class JitterProxy:
    """Loopback TCP proxy that delays the client-to-server direction at random.

    Parameters
    ----------
    target_host, target_port
        The server.
    jitter_ms
        J: each message from the client waits a delay uniform in ``[0, 2 J]`` ms (J +- J)
        before it is forwarded, never overtaking the one before it (>= 0).
    seed
        Seed of the delays.
    host
        Interface the proxy listens on; :attr:`port` is chosen by the OS.

    Examples
    --------
    ::

        async with JitterProxy("127.0.0.1", 4840, jitter_ms=10) as proxy:
            url = f"opc.tcp://127.0.0.1:{proxy.port}/cnctwin"
    """

    def __init__(
        self,
        target_host: str,
        target_port: int,
        jitter_ms: float,
        *,
        seed: int = 0,
        host: str = "127.0.0.1",
    ) -> None:
        if not (math.isfinite(jitter_ms) and jitter_ms >= 0):
            raise ConfigError(f"jitter {jitter_ms!r} ms; valid: a finite number >= 0")
        self.target = (target_host, target_port)
        self.jitter_s = jitter_ms / 1e3
        self.host = host
        self.port = 0
        self._random = random.Random(seed)
        self._server: asyncio.Server | None = None
        self._tasks: set[asyncio.Task[None]] = set()

    async def __aenter__(self) -> JitterProxy:
        self._server = await asyncio.start_server(self._accept, self.host, 0)
        self.port = int(self._server.sockets[0].getsockname()[1])
        logger.info(
            "jitter proxy %s:%d -> %s:%d, one-way delay U(0, %.1f) ms",
            self.host,
            self.port,
            *self.target,
            2e3 * self.jitter_s,
        )
        return self

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self._server is not None:
            self._server.close()
        for task in list(self._tasks):
            task.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)
        if self._server is not None:
            await self._server.wait_closed()
            self._server = None

    def _spawn(self, coro: Coroutine[Any, Any, None]) -> None:
        task = asyncio.get_running_loop().create_task(coro)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    async def _accept(self, client_r: asyncio.StreamReader, client_w: asyncio.StreamWriter) -> None:
        try:
            server_r, server_w = await asyncio.open_connection(*self.target)
        except OSError as err:
            logger.warning("jitter proxy cannot reach %s:%d: %s", *self.target, err)
            client_w.close()
            return
        self._spawn(self._delayed(client_r, server_w))
        self._spawn(self._pipe(server_r, client_w))

    async def _delayed(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        """Forward with one random delay per message, in order.

        A chunk that arrives while the one before is still held is part of the same message
        (a request written in pieces) and leaves with it; otherwise it draws a new delay.
        """
        loop = asyncio.get_running_loop()
        queue: asyncio.Queue[tuple[float, bytes]] = asyncio.Queue()

        async def sender() -> None:
            due_last = 0.0
            while True:
                due, data = await queue.get()
                if not data:
                    break
                due_last = max(due, due_last)
                wait = due_last - loop.time()
                if wait > 0:
                    await asyncio.sleep(wait)
                writer.write(data)
                await writer.drain()

        send = loop.create_task(sender())
        held_until = 0.0
        try:
            while data := await reader.read(65536):
                now = loop.time()
                if now >= held_until:  # a new message: draw its delay
                    held_until = now + self._random.uniform(0.0, 2.0 * self.jitter_s)
                # else: the rest of a message still held travels with it
                queue.put_nowait((held_until, data))
            queue.put_nowait((0.0, b""))
            await send
        except (OSError, asyncio.IncompleteReadError):
            pass
        finally:
            send.cancel()
            writer.close()

    async def _pipe(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            while data := await reader.read(65536):
                writer.write(data)
                await writer.drain()
        except OSError:
            pass
        finally:
            writer.close()


def _polling_connection(transport: str, endpoint: str, timeout_s: float) -> MachineConnection:
    """A connection of ``transport`` (``"opcua"``, ``"modbus"``, ``"mtconnect"``, ``"ads"`` or
    ``"linuxcnc"``) that reads by request (ADS: the packaged symbol map, GVL_Twin)."""
    config = ConnectionConfig(
        transport=transport,  # type: ignore[arg-type]
        endpoint=endpoint,
        timeout_s=timeout_s,
    )
    if transport == "opcua":
        from cnctwin.thread.opcua import OpcUaConnection

        # Reads by request: the round trip measures the protocol, not a subscription's cache.
        return OpcUaConnection(config, subscription_ms=None)
    if transport == "mtconnect":
        from cnctwin.thread.mtconnect import MTConnectConnection

        return MTConnectConnection(config)
    if transport == "ads":
        from cnctwin.thread.ads import AdsConnection

        return AdsConnection(config)
    if transport == "linuxcnc":
        from cnctwin.thread.linuxcnc import LinuxCncConnection

        return LinuxCncConnection(config)  # commands with $CNCTWIN_LINUXCNC_ENABLE
    from cnctwin.thread.modbus import ModbusConnection

    return ModbusConnection(config)


async def measure_endpoint_latency(
    transport: str,
    endpoint: str,
    *,
    n: int,
    interval_s: float,
    jitter_ms: float = 0.0,
    seed: int = 0,
) -> LatencyResult:
    """Connect to a machine server and measure its write-to-read-back latency.

    Parameters
    ----------
    transport
        ``"opcua"``, ``"modbus"``, ``"mtconnect"`` or ``"ads"``; OPC UA reads by request,
        without a subscription; MTConnect is read-only: its read round trip
        (:func:`measure_read_latency`); ADS writes and reads back the feed override at the
        packaged symbol map's symbols (Heide 2025 section 2.5's test).
    endpoint
        ``opc.tcp://HOST:PORT/PATH``, ``modbus://HOST:PORT``, ``http://HOST:PORT`` or
        ``ads://AMSNETID:AMSPORT@HOST:PORT``.
    n
        Round trips.
    interval_s
        Pause between round trips, s.
    jitter_ms
        One-way jitter J, ms: with J > 0 every request passes a :class:`JitterProxy` that
        delays it by U(0, 2J) ms.
    seed
        Seed of the jitter.

    Raises
    ------
    InputError
        For a transport other than ``"opcua"``, ``"modbus"``, ``"mtconnect"`` and ``"ads"``,
        or jitter on an endpoint without ``HOST:PORT``.
    """
    if transport not in ("opcua", "modbus", "mtconnect", "ads", "linuxcnc"):
        raise InputError(f"transport {transport!r}; valid: opcua, modbus, mtconnect, ads, linuxcnc")
    timeout_s = 2.0 + 4.0 * jitter_ms / 1e3

    async def once(url: str) -> LatencyResult:
        async with _polling_connection(transport, url, timeout_s) as connection:
            if transport == "mtconnect":
                return await measure_read_latency(
                    connection, n=n, interval_s=interval_s, jitter_ms=jitter_ms
                )
            result = await measure_latency(
                connection,
                n=n,
                interval_s=interval_s,
                timeout_s=timeout_s,
                jitter_ms=jitter_ms,
                # the proxy gives a message that comes while the one before is held that one's
                # delay: a read sent behind the write would share the write's (Heide 2025
                # delays each write and each read)
                pipelined=jitter_ms <= 0,
            )
            # the bench's session is anonymous with the default [connection.security]: no
            # message security (docs/latency.md compares Sign and SignAndEncrypt)
            return replace(result, security="None") if transport == "opcua" else result

    if jitter_ms <= 0:
        return await once(endpoint)
    parts = urlsplit(endpoint)
    if parts.hostname is None or parts.port is None:
        raise InputError(f"endpoint {endpoint!r} has no host:port; valid: SCHEME://HOST:PORT")
    async with JitterProxy(parts.hostname, parts.port, jitter_ms, seed=seed) as proxy:
        userinfo = parts.netloc.rpartition("@")[0]  # ADS: the AMS Net ID and port
        netloc = f"{proxy.host}:{proxy.port}"
        via = parts._replace(netloc=f"{userinfo}@{netloc}" if userinfo else netloc)
        return await once(urlunsplit(via))


async def measure_broker_latency(
    endpoint: str | None,
    *,
    n: int,
    interval_s: float,
    jitter_ms: float = 0.0,
    seed: int = 0,
) -> tuple[LatencyResult, str]:
    """The MQTT publish-to-receive round trip (:func:`~cnctwin.thread.mqtt.measure_mqtt_latency`)
    through the broker at ``endpoint``, or through a private Mosquitto started for it.

    Parameters
    ----------
    endpoint
        The broker, ``mqtt://HOST:PORT``; ``None``: start a private
        :class:`~cnctwin.thread.mosquitto.Mosquitto` on loopback for the run.
    n, interval_s
        Round trips and the pause between them, s.
    jitter_ms, seed
        One-way jitter J on the publisher's path, ms, and its seed.

    Returns
    -------
    tuple
        The result and the broker measured.

    Raises
    ------
    InputError
        When ``endpoint`` is not a broker address.
    """
    from cnctwin.thread.mosquitto import Mosquitto
    from cnctwin.thread.mqtt import measure_mqtt_latency
    from cnctwin.thread.mqtt_config import broker_address

    if endpoint is None:
        with Mosquitto() as broker:
            result = await measure_mqtt_latency(
                broker.url, n=n, interval_s=interval_s, jitter_ms=jitter_ms, seed=seed
            )
            return result, broker.url
    try:
        broker_address(endpoint)
    except ValueError as err:
        raise InputError(str(err)) from None
    result = await measure_mqtt_latency(
        endpoint, n=n, interval_s=interval_s, jitter_ms=jitter_ms, seed=seed
    )
    return result, endpoint
