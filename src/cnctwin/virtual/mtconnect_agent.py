"""An MTConnect agent for the virtual machine: ``/probe``, ``/current``, ``/sample``, ``/assets``.

The agent serves one device, ``cnctwin-vm``, over HTTP/1.1 (the standard library's asyncio,
kept-alive connections) and answers with documents of the MTConnect 2.7 schemas
(``../shared/data/mtconnect/schemas``; the tests validate every kind of response against
them):

* ``/probe`` (also ``/`` and ``/cnctwin-vm``): ``MTConnectDevices`` with the data items of
  :data:`DATA_ITEMS` -- axes X, Y, Z (POSITION ACTUAL in MILLIMETER, LOAD), the spindle C
  (ROTARY_VELOCITY ACTUAL and COMMANDED, its override, TORQUE, AMPERAGE, WATTAGE), the
  controller (EMERGENCY_STOP, SYSTEM condition) and its path (EXECUTION, LINE_NUMBER,
  PATH_FEEDRATE in MILLIMETER/SECOND, PATH_FEEDRATE_OVERRIDE, TOOL_NUMBER);
* ``/current``: the newest observation of every data item;
* ``/sample?from=F&count=N``: the observations with sequence numbers ``F`` to ``F+N-1`` that
  are in the buffer (default ``from`` the oldest, ``count`` 100 or the buffer's size);
* ``/assets``: an empty ``MTConnectAssets`` document (the machine has no assets);
* anything else: an ``MTConnectError`` -- ``OutOfRange`` for ``from``/``count`` outside the
  buffer, ``InvalidParameterValue`` for a non-integer, ``Unsupported`` for ``interval``, ``at``
  and ``path`` (streaming and XPath filters are not served), ``NoDevice``, ``InvalidURI``,
  ``InvalidRequest`` (not a GET).

:meth:`MTConnectAgent.publish` (called after each clock tick) turns the machine's snapshot
into observations: a data item whose value text changed gets the next sequence number and the
wall-clock time (UTC). Values convert from the canonical signals by the factors of
:data:`cnctwin.thread.mtconnect_map.UNIT_FACTORS` (feed rate mm/min / 60 = mm/s); a NaN is
``UNAVAILABLE``. The buffer keeps the newest ``buffer_size`` observations; every start makes a
new ``instanceId`` (a restart, as a client sees it). The agent takes no commands: MTConnect
is read-only.

:meth:`MTConnectAgent.load_devices` replaces the virtual machine's device model with a real
probe (served as given) and :meth:`MTConnectAgent.feed_shdr` observes an adapter's SHDR lines
on it, as a reference agent fed by that adapter would: the reference agent's Okuma with its
recorded log (``../shared/data/mtconnect/samples``) gives real observations to serve.
"""

from __future__ import annotations

import asyncio
import logging
import math
import secrets
import time
import xml.etree.ElementTree as ET
from collections import deque
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Protocol
from urllib.parse import parse_qs, urlsplit

from cnctwin.thread import (
    RUN_STATE_EXECUTION,
    UNIT_FACTORS,
    Devices,
    RunState,
    ShdrFeed,
    parse_devices,
    parse_shdr,
)
from cnctwin.virtual.exposure import check_exposure

__all__ = ["DATA_ITEMS", "DEVICE_NAME", "AgentItem", "MTConnectAgent"]

logger = logging.getLogger(__name__)

#: The device the agent serves.
DEVICE_NAME = "cnctwin-vm"
_DEVICE_UUID = "cnctwin-virtual-machine"
_VERSION = "2.7"
_NS = "urn:mtconnect.org:MTConnect{kind}:2.7"
_MAX_REQUEST_BYTES = 8 * 1024
_DEFAULT_COUNT = 100
_UNAVAILABLE = "UNAVAILABLE"


class SnapshotSource(Protocol):
    """What the agent reads: the virtual machine, or a fake in tests."""

    def snapshot(self) -> Mapping[str, float]:
        """Current value of every signal (canonical names)."""
        ...


@dataclass(frozen=True)
class AgentItem:
    """One data item of the agent's device.

    Attributes
    ----------
    id, type, sub_type, category, units
        As in the probe (``units`` ``None`` for events and conditions).
    component, component_id, component_name
        Where it sits (``Linear``, ``x``, ``X``).
    signal
        The canonical signal it reports (``None``: derived, e.g. AVAILABILITY, or fed by SHDR).
    device, device_uuid
        Its device.
    """

    id: str
    type: str
    sub_type: str | None
    category: str
    units: str | None
    component: str
    component_id: str
    component_name: str
    signal: str | None
    device: str = DEVICE_NAME
    device_uuid: str = _DEVICE_UUID


def _axis(name: str) -> tuple[AgentItem, ...]:
    low = name.lower()
    return (
        AgentItem(
            f"{low}_pos",
            "POSITION",
            "ACTUAL",
            "SAMPLE",
            "MILLIMETER",
            "Linear",
            low,
            name,
            f"{low}_mm",
        ),
        AgentItem(
            f"{low}_load", "LOAD", None, "SAMPLE", "PERCENT", "Linear", low, name, f"load_{low}_pct"
        ),
    )


#: The device's data items, in probe order.
DATA_ITEMS: tuple[AgentItem, ...] = (
    AgentItem("avail", "AVAILABILITY", None, "EVENT", None, "Device", "vm", DEVICE_NAME, None),
    *_axis("X"),
    *_axis("Y"),
    *_axis("Z"),
    AgentItem(
        "s_speed",
        "ROTARY_VELOCITY",
        "ACTUAL",
        "SAMPLE",
        "REVOLUTION/MINUTE",
        "Rotary",
        "c",
        "C",
        "spindle_rpm",
    ),
    AgentItem(
        "s_speed_cmd",
        "ROTARY_VELOCITY",
        "COMMANDED",
        "SAMPLE",
        "REVOLUTION/MINUTE",
        "Rotary",
        "c",
        "C",
        "spindle_rpm_command",
    ),
    AgentItem(
        "s_ovr",
        "ROTARY_VELOCITY_OVERRIDE",
        None,
        "EVENT",
        "PERCENT",
        "Rotary",
        "c",
        "C",
        "spindle_override_pct",
    ),
    AgentItem(
        "s_torque",
        "TORQUE",
        None,
        "SAMPLE",
        "NEWTON_METER",
        "Rotary",
        "c",
        "C",
        "spindle_torque_nm",
    ),
    AgentItem(
        "s_amps", "AMPERAGE", None, "SAMPLE", "AMPERE", "Rotary", "c", "C", "spindle_current_a"
    ),
    AgentItem("s_watts", "WATTAGE", None, "SAMPLE", "WATT", "Rotary", "c", "C", "spindle_power_w"),
    AgentItem(
        "estop",
        "EMERGENCY_STOP",
        None,
        "EVENT",
        None,
        "Controller",
        "cont",
        "controller",
        "emergency_stop",
    ),
    AgentItem(
        "system", "SYSTEM", None, "CONDITION", None, "Controller", "cont", "controller", None
    ),
    AgentItem("execution", "EXECUTION", None, "EVENT", None, "Path", "path", "path", "run_state"),
    AgentItem(
        "line", "LINE_NUMBER", "ABSOLUTE", "EVENT", None, "Path", "path", "path", "program_line"
    ),
    AgentItem(
        "feed",
        "PATH_FEEDRATE",
        "ACTUAL",
        "SAMPLE",
        "MILLIMETER/SECOND",
        "Path",
        "path",
        "path",
        "feed_mm_min",
    ),
    AgentItem(
        "feed_ovr",
        "PATH_FEEDRATE_OVERRIDE",
        "PROGRAMMED",
        "EVENT",
        "PERCENT",
        "Path",
        "path",
        "path",
        "feed_override_pct",
    ),
    AgentItem("tool", "TOOL_NUMBER", None, "EVENT", None, "Path", "path", "path", "tool_number"),
)


def _element(kind: str) -> str:
    """The Streams element of a data item type: ``PATH_FEEDRATE`` -> ``PathFeedrate``."""
    return "".join(w.title() for w in kind.split("_"))


_GROUP_OF_CATEGORY = {"SAMPLE": "Samples", "EVENT": "Events", "CONDITION": "Condition"}


def _timestamp(seconds: float) -> str:
    return datetime.fromtimestamp(seconds, UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def _decimal(value: float) -> str:
    text = f"{value:.6f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def _value_text(item: AgentItem, snapshot: Mapping[str, float]) -> str:
    """The observation text of ``item`` in ``snapshot`` (``UNAVAILABLE`` when unknown)."""
    if item.type == "AVAILABILITY":
        return "AVAILABLE"
    if item.type == "SYSTEM":
        state = snapshot.get("run_state", math.nan)
        return (
            _UNAVAILABLE
            if not math.isfinite(state)
            else ("FAULT" if round(state) == RunState.FAULT else "NORMAL")
        )
    value = snapshot.get(item.signal or "", math.nan)
    if not math.isfinite(value):
        return _UNAVAILABLE
    if item.type == "EXECUTION":
        try:
            return RUN_STATE_EXECUTION[RunState(round(value))]
        except ValueError:
            return _UNAVAILABLE
    if item.type == "EMERGENCY_STOP":
        return "TRIGGERED" if value else "ARMED"
    if item.units is None:  # an integer event
        return str(round(value))
    return _decimal(value / UNIT_FACTORS[item.units][1])


@dataclass(frozen=True)
class _Observation:
    sequence: int
    item: AgentItem
    value: str
    timestamp: str
    native_code: str | None = None
    message: str | None = None


class _RequestError(Exception):
    """An MTConnectError answer: element name, HTTP status, message, query parameter."""

    def __init__(
        self,
        element: str,
        status: int,
        message: str,
        parameter: tuple[str, str, int | None, int | None] | None = None,
    ) -> None:
        super().__init__(message)
        self.element = element
        self.status = status
        self.message = message
        self.parameter = parameter


class MTConnectAgent:
    """The virtual machine's MTConnect agent. Use as ``async with``.

    Parameters
    ----------
    source
        The machine: ``snapshot()``.
    host
        Interface to listen on; a non-loopback one needs ``insecure`` (the agent has no
        authentication; it is read-only, but it tells anyone what the machine does).
    port
        TCP port; 0 picks a free one (see :attr:`port` once started).
    buffer_size
        Observations kept (>= 16).
    insecure
        Allow a non-loopback ``host``.

    Attributes
    ----------
    instance_id
        This run of the agent; a new one at every construction.
    requests
        Requests answered.
    """

    def __init__(
        self,
        source: SnapshotSource,
        host: str = "127.0.0.1",
        port: int = 0,
        buffer_size: int = 131072,
        insecure: bool = False,
    ) -> None:
        check_exposure(host, "mtconnect", secured=False, insecure=insecure)
        if buffer_size < 16:
            raise ValueError(f"MTConnect buffer_size {buffer_size}; valid: >= 16 observations")
        self.source = source
        self.items = DATA_ITEMS
        self._probe: bytes | None = None
        self._devices_model: Devices | None = None
        self.host = host
        self.buffer_size = buffer_size
        self.instance_id = 1 + secrets.randbelow(2**31 - 2)
        self.requests = 0
        self._port = port
        self._server: asyncio.Server | None = None
        self._buffer: deque[_Observation] = deque(maxlen=buffer_size)
        self._latest: dict[str, _Observation] = {}
        self._next = 1
        self._created = _timestamp(time.time())
        self._connections: dict[asyncio.StreamWriter, asyncio.Task[None]] = {}

    @property
    def port(self) -> int:
        """TCP port the agent listens on."""
        return self._port

    @property
    def endpoint(self) -> str:
        """``http://HOST:PORT``, for :class:`cnctwin.thread.config.ConnectionConfig`."""
        return f"http://{self.host}:{self._port}"

    # Observations ---------------------------------------------------------------------
    def publish(self, snapshot: Mapping[str, float] | None = None) -> None:
        """Add an observation for every data item whose value changed in ``snapshot``
        (default: ``source.snapshot()``)."""
        if self._probe is not None:
            return  # a loaded device model is fed by SHDR, not by the machine
        snap = self.source.snapshot() if snapshot is None else snapshot
        stamp = _timestamp(time.time())
        for item in self.items:
            self._observe(item, _value_text(item, snap), stamp)

    def _observe(
        self,
        item: AgentItem,
        text: str,
        stamp: str,
        native_code: str | None = None,
        message: str | None = None,
    ) -> None:
        """A new observation of ``item``, unless its value (and condition) is unchanged."""
        held = self._latest.get(item.id)
        if held is not None and (held.value, held.native_code, held.message) == (
            text,
            native_code,
            message,
        ):
            return
        obs = _Observation(self._next, item, text, stamp, native_code, message)
        self._next += 1
        self._buffer.append(obs)
        self._latest[item.id] = obs

    def _unavailable_all(self) -> None:
        stamp = _timestamp(time.time())
        for item in self.items:
            obs = _Observation(self._next, item, _UNAVAILABLE, stamp)
            self._next += 1
            self._buffer.append(obs)
            self._latest[item.id] = obs

    def load_devices(self, probe: bytes) -> Devices:
        """Serve another device model: a probe's devices and data items (every value
        ``UNAVAILABLE`` until :meth:`feed_shdr` observes it). ``/probe`` answers ``probe``
        itself; the machine's snapshots are no longer published.

        Raises
        ------
        DataError
            ``probe`` is not an MTConnectDevices document.
        """
        devices = parse_devices(probe)
        self.items = tuple(
            AgentItem(
                i.id,
                i.type,
                i.sub_type,
                i.category,
                i.units,
                i.component,
                i.component_id,
                i.component_name,
                None,
                i.device,
                i.device_uuid,
            )
            for i in devices.data_items
            if ":" not in i.type  # an extension type has no element in the standard's schema
        )
        self._devices_model = devices
        self._probe = probe
        self._buffer.clear()
        self._latest.clear()
        self._unavailable_all()
        return devices

    def feed_shdr(self, lines: Iterable[str]) -> ShdrFeed:
        """Observe an adapter's SHDR lines on the loaded device model (:meth:`load_devices`),
        as an agent fed by that adapter does, at their SHDR timestamps. A number sent in a
        data item's ``nativeUnits`` is converted to its ``units`` where both are in
        :data:`~cnctwin.thread.mtconnect_map.UNIT_FACTORS` (MILLIMETER/MINUTE ->
        MILLIMETER/SECOND: / 60); other values are served as sent.

        Returns
        -------
        ShdrFeed
            What was read; a key without a data item, a condition level outside
            NORMAL/WARNING/FAULT/UNAVAILABLE, are added to its ``rejected``. Asset commands are
            read and not served.
        """
        devices = self._devices_model
        feed = parse_shdr(lines, devices)
        by_key = {item.id: item for item in self.items}
        factors: dict[str, float] = {}
        if devices is not None:
            for data_item in devices.data_items:
                if data_item.name and data_item.name not in by_key and data_item.id in by_key:
                    by_key[data_item.name] = by_key[data_item.id]
                native = UNIT_FACTORS.get(data_item.native_units or "")
                units = UNIT_FACTORS.get(data_item.units or "")
                if native and units and native[0] == units[0] and native != units:
                    factors[data_item.id] = native[1] / units[1]
        for record in feed.records:
            if record.key.startswith("@"):
                continue
            item = by_key.get(record.key)
            if item is None:
                feed.rejected.append(f"line {record.line}: no data item {record.key!r}")
                continue
            stamp = _timestamp(record.timestamp_s)
            if item.category == "CONDITION":
                level = record.fields[0].upper() or _UNAVAILABLE
                if level not in ("NORMAL", "WARNING", "FAULT", _UNAVAILABLE):
                    feed.rejected.append(f"line {record.line}: condition level {level!r}")
                    continue
                code, message = record.fields[1], record.fields[4]
                self._observe(item, level, stamp, code or None, message or None)
                continue
            value = record.fields[0]
            if not value and item.category == "SAMPLE":
                value = _UNAVAILABLE
            elif item.id in factors and value != _UNAVAILABLE:
                try:
                    value = _decimal(float(value) * factors[item.id])
                except ValueError:
                    pass  # not a number: served as sent, as a real agent would
            self._observe(item, value, stamp)
        return feed

    @property
    def first_sequence(self) -> int:
        """Oldest sequence number in the buffer."""
        return self._buffer[0].sequence if self._buffer else self._next

    @property
    def next_sequence(self) -> int:
        """The sequence number the next observation gets."""
        return self._next

    # Server ---------------------------------------------------------------------------
    async def start(self) -> None:
        """Observe the machine's current values and start listening."""
        if not self._buffer:  # an agent starts with every value unknown
            self._unavailable_all()
        self.publish()
        self._server = await asyncio.start_server(self._handle, self.host, self._port)
        self._port = int(self._server.sockets[0].getsockname()[1])
        logger.info(
            "MTConnect agent listening at %s (instance %d)", self.endpoint, self.instance_id
        )

    async def stop(self) -> None:
        """Stop listening and drop every client connection."""
        if self._server is None:
            return
        self._server.close()
        handlers = list(self._connections.values())
        for writer in list(self._connections):
            writer.close()
        if handlers:  # each ends on its closed connection
            await asyncio.wait(handlers, timeout=5.0)
        await self._server.wait_closed()
        self._server = None
        logger.info("MTConnect agent at %s stopped", self.endpoint)

    async def __aenter__(self) -> MTConnectAgent:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

    async def _handle(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        assert task is not None
        self._connections[writer] = task
        try:
            while True:
                try:
                    head = await reader.readuntil(b"\r\n\r\n")
                except (asyncio.IncompleteReadError, asyncio.LimitOverrunError, OSError):
                    return
                if len(head) > _MAX_REQUEST_BYTES:
                    return
                lines = head.decode("latin-1").split("\r\n")
                parts = lines[0].split(" ")
                headers = {
                    k.strip().lower(): v.strip()
                    for k, sep, v in (line.partition(":") for line in lines[1:])
                    if sep
                }
                connection = headers.get("connection", "").lower()
                http10 = len(parts) > 2 and parts[2] == "HTTP/1.0" and connection != "keep-alive"
                # a request with a body is not one of ours: answer it, then close
                close = connection == "close" or http10 or "content-length" in headers
                status, body = self.answer(parts[0], parts[1] if len(parts) > 1 else "/")
                self.requests += 1
                writer.write(
                    (
                        f"HTTP/1.1 {status} {'OK' if status == 200 else 'Error'}\r\n"
                        "Content-Type: text/xml; charset=utf-8\r\n"
                        f"Content-Length: {len(body)}\r\n"
                        f"Connection: {'close' if close else 'keep-alive'}\r\n\r\n"
                    ).encode("ascii")
                    + body
                )
                await writer.drain()
                if close:
                    return
        except (ConnectionError, OSError):
            return
        finally:
            self._connections.pop(writer, None)
            writer.close()

    # Requests -------------------------------------------------------------------------
    def answer(self, method: str, target: str) -> tuple[int, bytes]:
        """HTTP status and document of a request (``GET /sample?from=1``)."""
        try:
            if method != "GET":
                raise _RequestError("InvalidRequest", 405, f"method {method!r}; only GET")
            parts = urlsplit(target)
            query = parse_qs(parts.query, keep_blank_values=True)
            path = [p for p in parts.path.split("/") if p]
            names = sorted({item.device for item in self.items})
            device: str | None = None
            if path and path[0] in names:
                device, path = path[0], path[1:]
            elif len(path) == 2 or (
                path and path[0] not in ("probe", "current", "sample", "assets")
            ):
                raise _RequestError(
                    "NoDevice", 404, f"no device {path[0]!r}; devices: {', '.join(names)}"
                )
            request = path[0] if path else "probe"
            if len(path) > 1 or request not in ("probe", "current", "sample", "assets"):
                raise _RequestError(
                    "InvalidURI", 404, f"{parts.path!r}: valid are probe, current, sample, assets"
                )
            for unsupported in ("interval", "at", "path", "heartbeat"):
                if unsupported in query:
                    raise _RequestError(
                        "Unsupported", 400, f"query parameter {unsupported!r} is not served"
                    )
            if request == "probe":
                return 200, self._devices()
            if request == "assets":
                return 200, self._assets()
            if request == "current":
                latest = [o for o in self._latest.values() if device in (None, o.item.device)]
                return 200, self._streams(latest, self._next)
            return 200, self._sample(query, device)
        except _RequestError as err:
            return err.status, self._error(err, target)

    def _int(self, query: dict[str, list[str]], name: str, default: int) -> int:
        if name not in query:
            return default
        text = query[name][-1]
        try:
            return int(text)
        except ValueError:
            raise _RequestError(
                "InvalidParameterValue",
                400,
                f"{name}={text!r} is not an integer",
                (name, text, None, None),
            ) from None

    def _sample(self, query: dict[str, list[str]], device: str | None) -> bytes:
        first, nxt = self.first_sequence, self._next
        start = self._int(query, "from", first)
        count = self._int(query, "count", min(_DEFAULT_COUNT, self.buffer_size))
        if not first <= start <= nxt:
            raise _RequestError(
                "OutOfRange",
                400,
                f"'from' must be between {first} and {nxt}",
                ("from", str(start), first, nxt),
            )
        if not 1 <= count <= self.buffer_size:
            raise _RequestError(
                "OutOfRange",
                400,
                f"'count' must be between 1 and {self.buffer_size}",
                ("count", str(count), 1, self.buffer_size),
            )
        offset = start - first
        chosen = [self._buffer[i] for i in range(offset, min(offset + count, len(self._buffer)))]
        nxt = chosen[-1].sequence + 1 if chosen else start
        return self._streams([o for o in chosen if device in (None, o.item.device)], nxt)

    # Documents ------------------------------------------------------------------------
    def _root(self, kind: str) -> ET.Element:
        ns = _NS.format(kind=kind)
        root = ET.Element(
            f"MTConnect{kind}",
            {
                "xmlns": ns,
                "xmlns:m": ns,
                "xmlns:xsi": "http://www.w3.org/2001/XMLSchema-instance",
                "xsi:schemaLocation": f"{ns} /schemas/MTConnect{kind}_{_VERSION}.xsd",
            },
        )
        return root

    def _header(self, root: ET.Element, **extra: str) -> None:
        ET.SubElement(
            root,
            "Header",
            {
                "creationTime": _timestamp(time.time()),
                "sender": "cnctwin",
                "instanceId": str(self.instance_id),
                "version": _VERSION + ".0",
                "deviceModelChangeTime": self._created,
                **extra,
            },
        )

    @staticmethod
    def _bytes(root: ET.Element) -> bytes:
        data: bytes = ET.tostring(root, encoding="utf-8", xml_declaration=True)
        return data

    def _devices(self) -> bytes:
        if self._probe is not None:
            return self._probe
        root = self._root("Devices")
        self._header(root, bufferSize=str(self.buffer_size), assetBufferSize="1024", assetCount="0")
        device = ET.SubElement(
            ET.SubElement(root, "Devices"),
            "Device",
            {"id": "vm", "name": DEVICE_NAME, "uuid": _DEVICE_UUID},
        )
        ET.SubElement(
            device, "Description", {"manufacturer": "cnctwin", "model": "virtual machine"}
        ).text = "cnctwin's virtual 3-axis milling machine"
        elements: dict[str, ET.Element] = {"vm": device}
        layout = (
            ("vm", "Axes", "axes", "axes"),
            ("axes", "Linear", "x", "X"),
            ("axes", "Linear", "y", "Y"),
            ("axes", "Linear", "z", "Z"),
            ("axes", "Rotary", "c", "C"),
            ("vm", "Controller", "cont", "controller"),
            ("cont", "Path", "path", "path"),
        )
        self._add_items(device, "vm")
        for parent, tag, ident, name in layout:
            holder = elements[parent].find("Components")
            if holder is None:
                holder = ET.SubElement(elements[parent], "Components")
            component = ET.SubElement(holder, tag, {"id": ident, "name": name})
            elements[ident] = component
            self._add_items(component, ident)
        return self._bytes(root)

    @staticmethod
    def _add_items(component: ET.Element, ident: str) -> None:
        items = [item for item in DATA_ITEMS if item.component_id == ident]  # the vm's model
        if not items:
            return
        holder = ET.SubElement(component, "DataItems")
        for item in items:
            attrs = {"id": item.id, "type": item.type, "category": item.category}
            if item.sub_type:
                attrs["subType"] = item.sub_type
            if item.units:
                attrs["units"] = item.units
            ET.SubElement(holder, "DataItem", attrs)

    def _streams(self, observations: list[_Observation], next_sequence: int) -> bytes:
        root = self._root("Streams")
        self._header(
            root,
            bufferSize=str(self.buffer_size),
            firstSequence=str(self.first_sequence),
            lastSequence=str(self._next - 1),
            nextSequence=str(next_sequence),
        )
        streams = ET.SubElement(root, "Streams")
        by_device: dict[tuple[str, str], dict[str, dict[str, list[_Observation]]]] = {}
        for obs in sorted(observations, key=lambda o: o.sequence):
            components = by_device.setdefault((obs.item.device, obs.item.device_uuid), {})
            groups = components.setdefault(obs.item.component_id, {})
            groups.setdefault(obs.item.category, []).append(obs)
        for (name, uuid), components in by_device.items():
            device = ET.SubElement(streams, "DeviceStream", {"name": name, "uuid": uuid})
            for ident, groups in components.items():
                self._component_stream(device, ident, groups)
        return self._bytes(root)

    def _component_stream(
        self, device: ET.Element, ident: str, groups: dict[str, list[_Observation]]
    ) -> None:
        first = next(iter(groups.values()))[0].item
        stream = ET.SubElement(
            device,
            "ComponentStream",
            {"component": first.component, "componentId": ident, "name": first.component_name},
        )
        for category in ("SAMPLE", "EVENT", "CONDITION"):
            if category not in groups:
                continue
            group = ET.SubElement(stream, _GROUP_OF_CATEGORY[category])
            for obs in groups[category]:
                self._observation(group, obs)

    @staticmethod
    def _observation(group: ET.Element, obs: _Observation) -> None:
        item = obs.item
        attrs = {
            "dataItemId": item.id,
            "timestamp": obs.timestamp,
            "sequence": str(obs.sequence),
        }
        if item.category == "CONDITION":
            if obs.native_code:
                attrs["nativeCode"] = obs.native_code
            element = ET.SubElement(group, obs.value.title(), {**attrs, "type": item.type})
            element.text = obs.message
            return
        if item.sub_type:
            attrs["subType"] = item.sub_type
        ET.SubElement(group, _element(item.type), attrs).text = obs.value

    def _assets(self) -> bytes:
        root = self._root("Assets")
        self._header(root, assetBufferSize="1024", assetCount="0")
        ET.SubElement(root, "Assets")
        return self._bytes(root)

    def _error(self, err: _RequestError, target: str) -> bytes:
        root = self._root("Error")
        self._header(root, bufferSize=str(self.buffer_size))
        error = ET.SubElement(ET.SubElement(root, "Errors"), err.element)
        if err.parameter is not None:
            name, value, low, high = err.parameter
            parameter = ET.SubElement(error, "QueryParameter", {"name": name})
            ET.SubElement(parameter, "Value").text = value
            if low is not None:
                ET.SubElement(parameter, "Minimum").text = str(low)
            if high is not None:
                ET.SubElement(parameter, "Maximum").text = str(high)
        ET.SubElement(error, "URI").text = target
        ET.SubElement(error, "ErrorMessage").text = err.message
        return self._bytes(root)
