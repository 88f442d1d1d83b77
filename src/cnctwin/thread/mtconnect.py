"""MTConnect machine connection: a streaming reader of an agent, read-only by design.

MTConnect is a read-only standard: an agent publishes what a machine does and takes no
commands. :class:`MTConnectConnection` therefore refuses every write with
:class:`~cnctwin.thread.connection.CommandRejected` ("MTConnect is read-only"): a twin on an
MTConnect machine monitors, it does not control.

The reader follows the agent's protocol (MTConnect Standard, Part 1, section 8, "HTTP
requests"):

1. ``GET /probe`` once: the data items, resolved to canonical signals by
   :func:`~cnctwin.thread.mtconnect_map.resolve_map` (defaults documented there and in
   docs/mtconnect.md, overridable by ``[connection] mapping``);
2. ``GET /current``: the newest value of every data item, and the ``nextSequence`` to go on
   from;
3. each :meth:`~MachineConnection.read`: ``GET /sample?from=NEXT&count=N``, repeated until
   caught up with the agent's ``lastSequence`` (at most :data:`MAX_CATCH_UP` requests).

Sequence numbers are tracked. When the agent's buffer has overrun the reader (``from`` below
the agent's ``firstSequence``, answered as ``OUT_OF_RANGE`` or by a buffer that starts
later), the lost range is recorded in :attr:`MTConnectConnection.gaps` and the reader resumes
from ``/current``. A changed ``instanceId`` means the agent restarted (its sequence numbers
start anew): the reader probes again (the device model may have changed), resumes from
``/current`` and records the gap with the reason. A value that is not a finite number, an
unknown enumeration value or one outside the signal's plausible range is never fed: it goes
to :attr:`Reading.rejected`, counted by data item in :attr:`MTConnectConnection.garbage` and
logged; ``UNAVAILABLE`` is rejected with that reason, not counted as garbage.

MTConnect reports a value when it changes, and the agent's answer means every value is
current as of that answer: a reading carries neither a source time nor a sample counter, so
the twin takes every answered read as a new sample at its receive time
(:mod:`cnctwin.twin.freshness`, case 3). MTConnect has no machine heartbeat either; the
``heartbeat`` signal is the count of the agent's answers while the device's AVAILABILITY is
``AVAILABLE`` (the agent reports ``UNAVAILABLE`` when it loses the machine's adapter): it
stops moving, and the twin's watchdog trips, when the agent or the machine goes away.

HTTP/1.1 over one kept-alive TCP connection, with the standard library's asyncio (no HTTP
client dependency); responses are bounded to
:data:`~cnctwin.thread.mtconnect_documents.MAX_DOCUMENT_BYTES`.
"""

from __future__ import annotations

import asyncio
import logging
from collections import Counter
from dataclasses import dataclass

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
from cnctwin.thread.mtconnect_documents import (
    MAX_DOCUMENT_BYTES,
    AgentError,
    Devices,
    Header,
    Observation,
    Streams,
    parse_devices,
    parse_streams,
)
from cnctwin.thread.mtconnect_map import MappedItem, convert, resolve_map

__all__ = ["MAX_CATCH_UP", "MTConnectConnection", "SequenceGap", "parse_endpoint"]

logger = logging.getLogger(__name__)

#: Most ``/sample`` requests one read makes to catch up with the agent.
MAX_CATCH_UP = 10
_MAX_HEADER_BYTES = 16 * 1024


def parse_endpoint(endpoint: str) -> tuple[str, int, str]:
    """Host, port and device path of ``http://HOST[:PORT][/DEVICE]`` (port 80 when absent).

    The device path is ``""`` for every device of the agent, else ``"/DEVICE"``.

    Raises
    ------
    ConfigError
        One line naming the endpoint and the expected form.
    """
    return split_endpoint(
        endpoint,
        scheme="http",
        default_port=80,
        what="MTConnect",
        form="http://HOST:PORT[/DEVICE]",
        example="http://127.0.0.1:5000",
        segments=1,
    )


@dataclass(frozen=True)
class SequenceGap:
    """Observations the reader could not read one by one.

    Attributes
    ----------
    instance_id
        The agent instance whose observations were lost.
    expected
        The sequence number the reader asked for.
    resumed
        The sequence number it went on from (of the instance ``resumed_instance_id``).
    resumed_instance_id
        The agent instance it went on with (differs from ``instance_id`` after a restart).
    reason
        ``"buffer overrun"`` or ``"agent restarted"``, with detail.
    received_s
        ``time.monotonic()`` when the gap was found, s.
    """

    instance_id: int
    expected: int
    resumed: int
    resumed_instance_id: int
    reason: str
    received_s: float


class _HttpClient:
    """HTTP/1.1 GET over one kept-alive connection; reopened on the next request after an
    error or a ``Connection: close``."""

    def __init__(self, host: str, port: int) -> None:
        self.host = host
        self.port = port
        self._reader: asyncio.StreamReader | None = None
        self._writer: asyncio.StreamWriter | None = None

    async def get(self, target: str) -> tuple[int, bytes]:
        """Status and body of ``GET target``; OSError/ConnectionLost when the link fails."""
        if self._writer is None:
            self._reader, self._writer = await asyncio.open_connection(self.host, self.port)
        reader, writer = self._reader, self._writer
        assert reader is not None
        try:
            writer.write(
                f"GET {target} HTTP/1.1\r\nHost: {self.host}:{self.port}\r\n"
                "Accept: application/xml\r\n\r\n".encode("ascii")
            )
            await writer.drain()
            status, headers = await self._head(reader)
            body = await self._body(reader, headers)
        except BaseException:
            self.close()
            raise
        if headers.get("connection", "").lower() == "close":
            self.close()
        return status, body

    async def _head(self, reader: asyncio.StreamReader) -> tuple[int, dict[str, str]]:
        try:
            head = await reader.readuntil(b"\r\n\r\n")
        except asyncio.IncompleteReadError as err:
            raise ConnectionLost("the agent closed the connection") from err
        except asyncio.LimitOverrunError as err:
            raise ConnectionLost("the agent's response header is too long") from err
        if len(head) > _MAX_HEADER_BYTES:
            raise ConnectionLost("the agent's response header is too long")
        lines = head.decode("latin-1").split("\r\n")
        status_line = lines[0].split(" ", 2)
        if len(status_line) < 2 or not status_line[0].startswith("HTTP/"):
            raise ConnectionLost(f"not an HTTP response: {lines[0][:60]!r}")
        try:
            status = int(status_line[1])
        except ValueError:
            raise ConnectionLost(f"not an HTTP status: {lines[0][:60]!r}") from None
        headers: dict[str, str] = {}
        for line in lines[1:]:
            name, sep, value = line.partition(":")
            if sep:
                headers[name.strip().lower()] = value.strip()
        return status, headers

    async def _body(self, reader: asyncio.StreamReader, headers: dict[str, str]) -> bytes:
        if headers.get("transfer-encoding", "").lower() == "chunked":
            chunks: list[bytes] = []
            total = 0
            while True:
                size_line = await reader.readline()
                try:
                    size = int(size_line.split(b";")[0].strip(), 16)
                except ValueError:
                    raise ConnectionLost("malformed chunked response") from None
                if size == 0:
                    await reader.readline()
                    return b"".join(chunks)
                total += size
                if total > MAX_DOCUMENT_BYTES:
                    raise ConnectionLost(f"response over {MAX_DOCUMENT_BYTES} bytes")
                chunks.append(await reader.readexactly(size))
                await reader.readline()
        length_text = headers.get("content-length")
        if length_text is None:  # the body ends with the connection
            body = await reader.read(MAX_DOCUMENT_BYTES + 1)
            self.close()
        else:
            try:
                length = int(length_text)
            except ValueError:
                raise ConnectionLost(f"Content-Length {length_text!r}") from None
            if not 0 <= length <= MAX_DOCUMENT_BYTES:
                raise ConnectionLost(f"response of {length} bytes; limit {MAX_DOCUMENT_BYTES}")
            body = await reader.readexactly(length)
        if len(body) > MAX_DOCUMENT_BYTES:
            raise ConnectionLost(f"response over {MAX_DOCUMENT_BYTES} bytes")
        return body

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
        self._reader = self._writer = None


class MTConnectConnection(MachineConnection):
    """A machine through an MTConnect agent (read-only).

    Parameters
    ----------
    config
        ``[connection]`` with ``transport = "mtconnect"``,
        ``endpoint = "http://HOST:PORT[/DEVICE]"``, ``sample_count`` (observations per
        ``/sample`` request), timeouts, backoff and ``mapping`` (signal -> selector, see
        :mod:`cnctwin.thread.mtconnect_map`).

    Attributes
    ----------
    devices
        The agent's probe (``None`` before the first connect).
    mapped
        Signal -> the data item that feeds it.
    instance_id
        The agent instance read.
    next_sequence
        The sequence number the next ``/sample`` asks for.
    gaps
        Every gap in the sequence found (buffer overruns, agent restarts).
    agent_restarts
        Times a changed ``instanceId`` was seen.
    garbage
        Garbage values rejected, by data item id.
    requests
        HTTP requests made.
    """

    def __init__(self, config: ConnectionConfig) -> None:
        self._init_from_config(config, "mtconnect", "MTConnect")
        self.host, self.port, self.device_path = parse_endpoint(config.endpoint)
        self.mapping = dict(config.mapping)
        self.sample_count = config.sample_count
        self.devices: Devices | None = None
        self.mapped: dict[str, MappedItem] = {}
        self.instance_id: int | None = None
        self.next_sequence: int | None = None
        self.gaps: list[SequenceGap] = []
        self.agent_restarts = 0
        self.garbage: Counter[str] = Counter()
        self.requests = 0
        self._http = _HttpClient(self.host, self.port)
        self._latest: dict[str, Observation] = {}
        self._bad: dict[str, str] = {}
        self._availability: str | None = None
        self._beats = 0

    # Transport hooks ------------------------------------------------------------------
    async def _open(self) -> None:
        try:
            await self._start()
        except (DataError, AgentError) as err:
            raise ConnectionLost(f"agent at {self.host}:{self.port}: {err}") from err

    async def _reopen(self) -> str:
        """Close and open anew; a probe the mapping no longer fits (an agent restarted with
        another device model) fails the attempt, and the reconnection tries again."""
        await self._close()
        try:
            await asyncio.wait_for(self._open(), self.timeout_s)
        except ConfigError as err:
            raise ConnectionLost(f"the agent's probe no longer fits the mapping: {err}") from err
        return "closed, probed and read /current anew"

    async def _close(self) -> None:
        self._http.close()

    async def _read(self) -> Reading:
        try:
            for _ in range(MAX_CATCH_UP):
                if await self._sample():
                    break
            self._beats += 1
        except (DataError, AgentError, ConfigError) as err:
            # a garbled answer, or a restarted agent whose probe the mapping does not fit:
            # reconnect, probe again
            raise ConnectionLost(f"agent at {self.host}:{self.port}: {err}") from err
        return self._reading()

    async def _write(self, name: str, value: float) -> None:
        raise CommandRejected(
            f"command {name}={value!r} refused: MTConnect is read-only (an agent publishes, "
            "it takes no commands); use OPC UA or Modbus to control the machine"
        )

    # Protocol -------------------------------------------------------------------------
    async def _get(self, request: str) -> bytes:
        self.requests += 1
        _status, body = await self._http.get(f"{self.device_path}/{request}")
        return body

    async def _start(self) -> None:
        """Probe, resolve the mapping, and take the newest values from ``/current``."""
        devices = parse_devices(await self._get("probe"))
        mapped = resolve_map(devices, self.mapping)
        current = parse_streams(await self._get("current"))
        old_instance, expected = self.instance_id, self.next_sequence
        self.devices, self.mapped = devices, mapped
        self._availability = next(
            (i.id for i in devices.data_items if i.type == "AVAILABILITY"), None
        )
        self._latest.clear()
        self._bad.clear()
        self._take(current)
        if old_instance is not None and current.header.instance_id != old_instance:
            self._restarted(old_instance, expected, current.header)
        self.instance_id = current.header.instance_id
        self.next_sequence = current.header.next_sequence

    def _restarted(self, old_instance: int, expected: int | None, header: Header) -> None:
        self.agent_restarts += 1
        self._gap(
            old_instance,
            expected or 0,
            header,
            f"agent restarted (instanceId {old_instance} -> {header.instance_id})",
        )

    def _gap(self, instance: int, expected: int, header: Header, reason: str) -> None:
        gap = SequenceGap(
            instance_id=instance,
            expected=expected,
            resumed=header.next_sequence or 0,
            resumed_instance_id=header.instance_id,
            reason=reason,
            received_s=now_s(),
        )
        self.gaps.append(gap)
        logger.warning(
            "MTConnect gap: %s; observations from %d of instance %d lost, resumed at %d",
            reason,
            gap.expected,
            gap.instance_id,
            gap.resumed,
        )

    async def _resume(self, reason: str) -> None:
        """Go on from ``/current`` after a buffer overrun (same instance) or a restart."""
        old_instance, expected = self.instance_id, self.next_sequence
        current = parse_streams(await self._get("current"))
        if current.header.instance_id != old_instance:
            await self._start()  # a restarted agent may serve another device model
            return
        self._take(current)
        self._gap(old_instance or 0, expected or 0, current.header, reason)
        self.next_sequence = current.header.next_sequence

    async def _sample(self) -> bool:
        """One ``/sample`` request; whether the reader has caught up with the agent."""
        start = self.next_sequence
        try:
            streams = parse_streams(
                await self._get(f"sample?from={start}&count={self.sample_count}")
            )
        except AgentError as err:
            if err.header is not None and err.header.instance_id != self.instance_id:
                await self._start()
                return True
            if err.code == "OUT_OF_RANGE":
                await self._resume(f"buffer overrun (agent: {err.text})")
                return True
            raise
        header = streams.header
        if header.instance_id != self.instance_id:
            await self._start()
            return True
        if (
            start is not None
            and header.first_sequence is not None
            and header.first_sequence > start
        ):
            await self._resume(f"buffer overrun (agent's buffer starts at {header.first_sequence})")
            return True
        self._take(streams)
        self.next_sequence = header.next_sequence
        last = header.last_sequence
        return last is None or self.next_sequence is None or self.next_sequence > last

    def _take(self, streams: Streams) -> None:
        """Keep the newest observation of each mapped data item; count the garbage."""
        wanted = {m.item.id: m for m in self.mapped.values()}
        for obs in streams.observations:
            if obs.data_item_id == self._availability:
                self._latest[obs.data_item_id] = obs
            mapped = wanted.get(obs.data_item_id)
            if mapped is None:
                continue
            self._latest[obs.data_item_id] = obs
            if obs.unavailable:
                self._bad[obs.data_item_id] = "UNAVAILABLE at the agent"
                continue
            try:
                convert(mapped, obs.value)
            except DataError as err:
                self.garbage[obs.data_item_id] += 1
                self._bad[obs.data_item_id] = str(err)
                logger.warning(
                    "MTConnect value rejected (%d from %s so far): %s",
                    self.garbage[obs.data_item_id],
                    obs.data_item_id,
                    err,
                )
                continue
            self._bad.pop(obs.data_item_id, None)

    def _reading(self) -> Reading:
        values: dict[str, float] = {}
        rejected: dict[str, str] = {}
        for signal, mapped in self.mapped.items():
            ident = mapped.item.id
            obs = self._latest.get(ident)
            if obs is None:
                rejected[signal] = f"{ident}: no observation yet"
            elif ident in self._bad:
                rejected[signal] = self._bad[ident]
            else:
                values[signal] = convert(mapped, obs.value)
        available = self._latest.get(self._availability or "")
        if "heartbeat" in self.mapped:  # the user mapped a counter of the machine's
            pass
        elif available is None or available.value == "AVAILABLE":
            values["heartbeat"] = float(self._beats)
        else:
            rejected["heartbeat"] = f"device {available.value} at the agent ({available.device})"
        return Reading(values=values, received_s=now_s(), rejected=rejected)
