"""One interface for every machine connection: state, batched reads, commands, reconnection.

A :class:`MachineConnection` reads all mapped signals in one batched request (or from a
subscription's cache) and writes commands one at a time, each with a timeout. Transports
(:mod:`cnctwin.thread.opcua`, :mod:`cnctwin.thread.modbus`, ...) implement the four
``_``-methods; reconnection with capped exponential backoff and the connection state live
here, once.

A request can also be *started* (:meth:`MachineConnection.start_write`,
:meth:`MachineConnection.start_read_block`): the call sends it and returns at once with a
future of the machine's answer, so a caller in a fixed-period cycle goes on while the machine
answers. A transport that can send without awaiting (OPC UA: the request is handed to the
socket; the in-process machine: the command is applied) has the request on its way when the
call returns; the others (Modbus, ADS, LinuxCNC, MQTT) send it at the event loop's next turn.
"""

from __future__ import annotations

import asyncio
import enum
import logging
import time
from abc import ABC, abstractmethod
from collections.abc import Awaitable, Callable, Coroutine, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Self, TypeVar

import numpy as np

from cnctwin.errors import CnctwinError, ConfigError, DataError

if TYPE_CHECKING:
    from cnctwin.thread.config import ConnectionConfig

__all__ = [
    "Backoff",
    "CommandRejected",
    "ConnectionLost",
    "ConnectionState",
    "MachineConnection",
    "Reading",
    "ReadBack",
    "SampleBlock",
    "drop_answer",
]

logger = logging.getLogger(__name__)

_T = TypeVar("_T")
_A = TypeVar("_A")


class ConnectionLost(CnctwinError, RuntimeError):
    """The machine did not answer (timeout, refused, closed); the connection reconnects."""


class CommandRejected(CnctwinError, ValueError):
    """The machine answered a write with a refusal (out of range, wrong type, not allowed)."""


class ConnectionState(enum.Enum):
    """Where a connection stands."""

    DISCONNECTED = "disconnected"
    CONNECTING = "connecting"
    CONNECTED = "connected"
    RECONNECTING = "reconnecting"
    CLOSED = "closed"


@dataclass(frozen=True)
class Reading:
    """One batched read of the machine.

    Attributes
    ----------
    values
        Canonical signal name -> value (see :data:`cnctwin.thread.signals.SIGNALS`). A
        signal the machine did not deliver, or delivered as garbage (NaN, wrong type), is
        absent; ``rejected`` says why.
    received_s
        ``time.monotonic()`` when the answer arrived, in s.
    rejected
        Signal name -> one-line reason for values that were dropped.
    source_time_s
        The machine's own time stamp of the newest value in the reading (OPC UA
        SourceTimestamp), POSIX s (UTC); ``None`` when the transport carries none.
    server_time_s
        The server's time stamp of the newest value (OPC UA ServerTimestamp), POSIX s (UTC);
        ``None`` when the transport carries none.
    sequence
        A sample counter the machine serves (Modbus: the ``heartbeat`` register, which the
        machine increments once per sample), or ``None``. With neither time stamps nor a
        counter a reading's only time is ``received_s``.
    """

    values: Mapping[str, float]
    received_s: float
    rejected: Mapping[str, str] = field(default_factory=dict)
    source_time_s: float | None = None
    server_time_s: float | None = None
    sequence: float | None = None


@dataclass(frozen=True)
class ReadBack:
    """A command written and read back (:meth:`MachineConnection.write_read_back`).

    Attributes
    ----------
    value
        The command's feedback as read back, in the command's unit.
    write_s
        From the call to the machine's answer to the write, s.
    read_s
        From the machine's answer to the write to its answer to the read, s (a transport
        that sends the read before the write's answer, OPC UA, counts the read's share of
        the round trip only).
    """

    value: float
    write_s: float
    read_s: float


@dataclass(frozen=True, eq=False)
class SampleBlock:
    """Samples of a fast signal (a vibration sensor) that a machine serves as a block.

    Attributes
    ----------
    name
        The block's name (``"vibration"``).
    first_index
        Index of the first sample since the machine's sensor started (sample ``i`` was taken
        at ``i / rate_hz`` s of the sensor's clock).
    rate_hz
        Sampling rate, Hz.
    samples
        (n, channels) values in the block's unit, oldest first.
    """

    name: str
    first_index: int
    rate_hz: float
    samples: np.ndarray

    @property
    def end_index(self) -> int:
        """Index just after the last sample."""
        return self.first_index + int(self.samples.shape[0])


@dataclass(frozen=True)
class Backoff:
    """Capped exponential backoff between reconnection attempts.

    Attempt ``k`` (0-based) waits ``min(initial_s * factor**k, max_s)`` s.
    """

    initial_s: float = 0.1
    factor: float = 2.0
    max_s: float = 5.0

    def delay_s(self, attempt: int) -> float:
        """Wait before attempt ``attempt`` (0-based), in s."""
        return min(self.initial_s * self.factor**attempt, self.max_s)


class MachineConnection(ABC):
    """A connection to one machine. Use as ``async with``; every call has a timeout.

    Parameters
    ----------
    timeout_s
        Timeout of one request (connect, read, write), in s.
    backoff
        Delays between reconnection attempts.

    Attributes
    ----------
    reconnects
        Times the connection was restored.
    last_reconnect
        How the last restoration went, one line (``"closed and opened anew"``; an OPC UA
        connection says whether its session was re-activated and its subscription
        transferred); ``""`` before the first.
    """

    def __init__(self, *, timeout_s: float = 2.0, backoff: Backoff | None = None) -> None:
        self.timeout_s = timeout_s
        self.backoff = backoff or Backoff()
        self.state = ConnectionState.DISCONNECTED
        self.reconnects = 0
        self.last_reconnect = ""
        self._reconnect_task: asyncio.Task[None] | None = None

    def _init_from_config(self, config: ConnectionConfig, transport: str, name: str) -> None:
        """Initialise from a ``[connection]`` table meant for this transport.

        Checks that ``config.transport`` is ``transport`` (``name`` names the connection in
        the error) and takes the table's timeout (s) and reconnection backoff (s).
        """
        if config.transport != transport:
            raise ConfigError(
                f"[connection] transport {config.transport!r} given to the {name} connection "
                f"(expected {transport!r})"
            )
        MachineConnection.__init__(
            self,
            timeout_s=config.timeout_s,
            backoff=Backoff(initial_s=config.reconnect_initial_s, max_s=config.reconnect_max_s),
        )

    # Transport hooks ------------------------------------------------------------------
    @abstractmethod
    async def _open(self) -> None:
        """Open the transport (raise OSError/TimeoutError/ConnectionLost on failure)."""

    @abstractmethod
    async def _close(self) -> None:
        """Close the transport; must not raise."""

    @abstractmethod
    async def _read(self) -> Reading:
        """One batched read of every mapped signal."""

    @abstractmethod
    async def _write(self, name: str, value: float) -> None:
        """Write one command (a name of :data:`~cnctwin.thread.signals.COMMANDS`)."""

    async def _write_read_back(self, name: str, value: float, pipelined: bool) -> ReadBack:
        """Write command ``name``, then read its feedback; this default waits for the write's
        answer before it sends the read (``pipelined`` or not)."""
        t0 = time.perf_counter()
        await self._write(name, value)
        t1 = time.perf_counter()
        back = await self._read_signal(name)
        return ReadBack(back, t1 - t0, time.perf_counter() - t1)

    def _start_write(self, name: str, value: float) -> Awaitable[None]:
        """Send command ``name`` = ``value`` now if the transport can without awaiting, and
        return the awaitable of its answer (raise like :meth:`_write`). This default sends
        nothing itself: it returns :meth:`_write`, which sends when it is first awaited."""
        return self._write(name, value)

    def _start_read_block(self, name: str, since: int) -> Awaitable[SampleBlock]:
        """Send the read of block ``name`` from sample ``since`` on (as :meth:`_start_write`);
        its answer is the :class:`SampleBlock`. This default has no blocks: DataError."""
        raise DataError(
            f"the {type(self).__name__} transport carries no sample blocks ({name!r}); "
            "read it over an in-process connection"
        )

    async def _reopen(self) -> str:
        """Restore the transport after a loss; return how, one line.

        This default closes what is left and opens anew; a transport that can resume its
        session (OPC UA) overrides it. Raises like :meth:`_open`.
        """
        await self._close()
        await asyncio.wait_for(self._open(), self.timeout_s)
        return "closed and opened anew"

    # Public API -----------------------------------------------------------------------
    async def connect(self) -> None:
        """Connect once; raise :class:`ConnectionLost` if the machine does not answer."""
        self.state = ConnectionState.CONNECTING
        try:
            await asyncio.wait_for(self._open(), self.timeout_s)
        except (OSError, TimeoutError, ConnectionLost) as err:
            self.state = ConnectionState.DISCONNECTED
            raise ConnectionLost(f"cannot connect: {err or type(err).__name__}") from err
        self.state = ConnectionState.CONNECTED

    async def read(self) -> Reading:
        """Read every mapped signal; :class:`ConnectionLost` (and a reconnect) on failure."""
        self._require_connected()
        try:
            async with asyncio.timeout(self.timeout_s):
                return await self._read()
        except (OSError, TimeoutError, ConnectionLost) as err:
            self._lost(err)
            raise ConnectionLost(f"read failed: {err or type(err).__name__}") from err

    async def read_signal(self, name: str) -> float:
        """Read one signal now, e.g. a command's read-back.

        Cheaper than :meth:`read` where the transport can read one address. Raises
        :class:`ConnectionLost` (and reconnects) on failure, and
        :class:`~cnctwin.errors.DataError` when the value is garbage.
        """
        self._require_connected()
        try:
            async with asyncio.timeout(self.timeout_s):
                return await self._read_signal(name)
        except (OSError, TimeoutError, ConnectionLost) as err:
            self._lost(err)
            raise ConnectionLost(f"read of {name} failed: {err or type(err).__name__}") from err

    async def _read_signal(self, name: str) -> float:
        """One signal; this default takes it from a full batched read."""
        reading = await self._read()
        if name not in reading.values:
            reason = reading.rejected.get(name, "not mapped")
            raise DataError(f"machine signal {name!r} unusable: {reason}")
        return reading.values[name]

    async def read_block(self, name: str, since: int) -> SampleBlock:
        """Read the samples of a fast signal taken from index ``since`` on (fewer, from the
        oldest kept, when the machine no longer holds them); :class:`ConnectionLost` (and a
        reconnect) on failure, :class:`~cnctwin.errors.DataError` when the transport or the
        machine has no such block."""
        return await self._send_and_wait(
            f"read of block {name}", self._start_read_block, name, since
        )

    def start_read_block(self, name: str, since: int) -> asyncio.Future[SampleBlock]:
        """Send the read of :meth:`read_block` now and return the future of its answer
        (module notes: where the transport can, the request is on its way on return).

        The future fails as :meth:`read_block` raises, a failure at the send included.
        Call it in the running event loop, and retrieve the future's result or exception.
        """
        return self._started(f"read of block {name}", self._start_read_block, name, since)

    async def write(self, name: str, value: float) -> None:
        """Write one command; :class:`ConnectionLost` (and a reconnect) on failure,
        :class:`CommandRejected` when the machine refuses it."""
        await self._send_and_wait(f"write of {name}={value!r}", self._start_write, name, value)

    def start_write(self, name: str, value: float) -> asyncio.Future[None]:
        """Send one command now and return the future of the machine's answer (module
        notes: where the transport can, the command is on its way on return).

        The future completes with ``None`` when the machine took the command, and fails as
        :meth:`write` raises (:class:`CommandRejected`; :class:`ConnectionLost`, and a
        reconnect, on a failure at the send or no answer within ``timeout_s``). A read of
        the machine that shows the command is the caller's to make. Call it in the running
        event loop, and retrieve the future's result or exception.
        """
        return self._started(f"write of {name}={value!r}", self._start_write, name, value)

    def _sent_now(
        self, what: str, send: Callable[[str, _A], Awaitable[_T]], name: str, arg: _A
    ) -> Awaitable[_T]:
        """Send ``send(name, arg)`` (a ``_start_`` hook) now; return the awaitable of its
        answer. A failure of the link at the send is :class:`ConnectionLost` (and a
        reconnect); ``what`` names the request in it."""
        self._require_connected()
        try:
            return send(name, arg)
        except (OSError, ConnectionLost) as err:
            self._lost(err)
            raise ConnectionLost(f"{what} failed: {err or type(err).__name__}") from err

    async def _answered(self, what: str, answer: Awaitable[_T]) -> _T:
        """The answer of a request sent, within ``timeout_s``; a failure of the link is
        :class:`ConnectionLost` (and a reconnect)."""
        try:
            async with asyncio.timeout(self.timeout_s):
                return await answer
        except (OSError, TimeoutError, ConnectionLost) as err:
            self._lost(err)
            raise ConnectionLost(f"{what} failed: {err or type(err).__name__}") from err

    async def _send_and_wait(
        self, what: str, send: Callable[[str, _A], Awaitable[_T]], name: str, arg: _A
    ) -> _T:
        return await self._answered(what, self._sent_now(what, send, name, arg))

    def _started(
        self, what: str, send: Callable[[str, _A], Awaitable[_T]], name: str, arg: _A
    ) -> asyncio.Future[_T]:
        """:meth:`_sent_now` now, its answer in a future (a failure at the send too)."""
        loop = asyncio.get_running_loop()
        try:
            answer = self._sent_now(what, send, name, arg)
        except (ConnectionLost, CommandRejected, DataError) as err:
            failed: asyncio.Future[_T] = loop.create_future()
            failed.set_exception(err)
            return failed
        task = loop.create_task(self._answered(what, answer))
        if isinstance(answer, Coroutine):
            # a fallback's request cancelled before it was sent (the event loop closing)
            task.add_done_callback(lambda _: answer.close())
        return task

    async def write_read_back(self, name: str, value: float, *, pipelined: bool = True) -> ReadBack:
        """Write one command and read its feedback, in one timeout: Heide 2025's
        write-to-read-back step (:func:`~cnctwin.thread.measure_latency`).

        The read is sent after the write, on the same link. With ``pipelined`` a transport
        that may have both in flight at once (OPC UA) sends it right behind the write, without
        waiting for the write's answer; a server that answers out of order may then return the
        value before the write (the caller reads again, as
        :func:`~cnctwin.thread.measure_latency` does). ``pipelined=False`` waits for the
        write's answer on every transport.
        :class:`CommandRejected` when the machine refuses the write, :class:`ConnectionLost`
        (and a reconnect) on failure, :class:`~cnctwin.errors.DataError` when the feedback is
        garbage.
        """
        self._require_connected()
        try:
            async with asyncio.timeout(self.timeout_s):
                return await self._write_read_back(name, value, pipelined)
        except (OSError, TimeoutError, ConnectionLost) as err:
            self._lost(err)
            raise ConnectionLost(
                f"write and read-back of {name}={value!r} failed: {err or type(err).__name__}"
            ) from err

    async def close(self) -> None:
        """Stop reconnecting and close the transport."""
        if self._reconnect_task is not None:
            self._reconnect_task.cancel()
            self._reconnect_task = None
        await self._close()
        self.state = ConnectionState.CLOSED

    async def __aenter__(self) -> Self:
        await self.connect()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    # Reconnection ---------------------------------------------------------------------
    def _require_connected(self) -> None:
        if self.state is not ConnectionState.CONNECTED:
            raise ConnectionLost(f"not connected ({self.state.value})")

    def _lost(self, err: BaseException) -> None:
        if self.state is not ConnectionState.CONNECTED:
            return
        logger.warning("machine connection lost: %s", err)
        self.state = ConnectionState.RECONNECTING
        self._reconnect_task = asyncio.get_running_loop().create_task(self._reconnect())

    async def _reconnect(self) -> None:
        attempt = 0
        while self.state is ConnectionState.RECONNECTING:
            await asyncio.sleep(self.backoff.delay_s(attempt))
            attempt += 1
            try:
                how = await self._reopen()
            except (OSError, TimeoutError, ConnectionLost) as err:
                logger.info("reconnect attempt %d failed: %s", attempt, err)
                continue
            self.reconnects += 1
            self.last_reconnect = how
            self.state = ConnectionState.CONNECTED
            logger.info("machine connection restored after %d attempts: %s", attempt, how)


def drop_answer(answer: asyncio.Future[Any]) -> None:
    """Stop waiting for the answer of a started request (:meth:`MachineConnection.start_write`):
    its outcome, when it comes, is taken and dropped (so that no failure is left unretrieved).
    Nothing is cancelled: the request is on its way, and its answer still counts for the
    connection (no answer within ``timeout_s`` is a lost connection)."""
    if answer.done():
        _take(answer)
    else:
        answer.add_done_callback(_take)


def _take(answer: asyncio.Future[Any]) -> None:
    if not answer.cancelled():
        answer.exception()


def now_s() -> float:
    """Monotonic clock in s (what :attr:`Reading.received_s` uses)."""
    return time.monotonic()
