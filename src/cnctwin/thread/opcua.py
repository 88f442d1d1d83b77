"""OPC UA client: a :class:`MachineConnection` over asyncua, batched reads, checked writes.

The default mapping is the node map of cnctwin's virtual machine (:data:`NODE_MAP`, laid
out after the OPC UA for Machine Tools companion specification, OPC 40501, with the axis
nodes of OPC 40502 CNC Systems; table in docs/opcua.md). ``[connection] mapping`` overrides
any entry with a NodeId string (``"ns=2;s=Machine.Monitoring.Axes.X.ActPos"``) or a browse
path below the Objects folder (``"2:Machines/2:Machine/2:Monitoring/..."``), so the same
twin runs against another server; ``"none"`` leaves a signal out (a machine without it).

A cycle's :meth:`~OpcUaConnection.read` takes every mapped node from a subscription's cache
(no request in the cycle), or with ``subscription_ms=None`` from one Read service call for all
nodes; docs/_bench_opcua.md compares both. The subscription's publishes of the usual layout
are decoded by :mod:`cnctwin.thread.opcua_publish`, the rest by asyncua. Values that are not
a finite number of a plausible type and range, or arrive with a Bad status, land in
:attr:`Reading.rejected` with a one-line reason instead of raising.
"""

from __future__ import annotations

import asyncio
import logging
import math
import struct
import time
from collections.abc import Awaitable, Iterable, Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from asyncua import ua
from asyncua.client.client import Client
from asyncua.client.ua_client import UaClientState, UASocketProtocol
from asyncua.common.node import Node
from asyncua.common.subscription import (
    DataChangeEvent,
    DataChangeNotif,
    StatusChangeEvent,
    Subscription,
)
from asyncua.common.utils import Buffer
from asyncua.crypto import security_policies
from asyncua.ua.attribute_ids import AttributeIds
from asyncua.ua.ua_binary import nodeid_to_binary, struct_from_binary, struct_to_binary
from asyncua.ua.uaerrors import UaError, UaStatusCodeError
from asyncua.ua.uatypes import EPOCH_AS_FILETIME

from cnctwin.errors import ConfigError, DataError
from cnctwin.thread.config import ConnectionConfig, OpcUaSecurityConfig
from cnctwin.thread.connection import (
    CommandRejected,
    ConnectionLost,
    MachineConnection,
    ReadBack,
    Reading,
    SampleBlock,
    now_s,
)
from cnctwin.thread.opcua_channel import frame_message, plain_message, take_plain_message
from cnctwin.thread.opcua_publish import use_lean_publish
from cnctwin.thread.signals import COMMANDS, SIGNALS
from cnctwin.thread.trust import TrustList

__all__ = [
    "CLIENT_APPLICATION_URI",
    "DEFAULT_SUBSCRIPTION_MS",
    "NAMESPACE_URI",
    "BLOCK_NODE",
    "NODE_MAP",
    "OpcUaConnection",
    "variant_type",
]

logger = logging.getLogger(__name__)

#: Namespace of the virtual machine's nodes (its index is looked up at connect).
NAMESPACE_URI = "urn:cnctwin:virtual-machine"

#: Application URI of the twin's client (the URI its certificate must carry).
CLIENT_APPLICATION_URI = "urn:cnctwin:twin"

#: Publishing interval of the subscription that feeds :meth:`OpcUaConnection.read`, ms (the
#: virtual machine's tick; a server may revise it upward).
DEFAULT_SUBSCRIPTION_MS = 5.0

#: Longest a subscription's restoration (transfer and republish) may take after a reconnect, s.
_RESTORE_S = 10.0

#: Session timeout the client asks for, ms (asyncua servers grant at most 10 min).
_SESSION_TIMEOUT_MS = 600_000

#: The node a machine serves its vibration samples in (node id in the namespace
#: :data:`NAMESPACE_URI`): a ByteString of little-endian float64 ``[first index, rate (Hz),
#: channels, samples row by row...]`` of the newest samples, made when read
#: (cnctwin.virtual.opcua_server; a ByteString is copied whole, where a Double array is
#: coded value by value).
BLOCK_NODE = "Machine.Vibration.Block"

#: What a block read from a machine may hold (it is untrusted): channels, the sampling rate
#: (Hz), the first sample's index and the number of values (16 MiB of float64).
_BLOCK_CHANNELS = (1, 8)
_BLOCK_RATE_HZ = (1.0, 1.0e6)
_BLOCK_FIRST_MAX = 2**53
_BLOCK_VALUES_MAX = 2**21

#: Canonical signal name -> string identifier of its node in :data:`NAMESPACE_URI`.
#: The dotted identifier is also the browse path below ``Objects/Machines``.
NODE_MAP: dict[str, str] = {
    "t_s": "Machine.Production.ActiveProgram.ElapsedTime",
    "program_line": "Machine.Production.ActiveProgram.LineNumber",
    "heartbeat": "Machine.Monitoring.MachineTool.Heartbeat",
    "x_mm": "Machine.Monitoring.Axes.X.ActPos",
    "y_mm": "Machine.Monitoring.Axes.Y.ActPos",
    "z_mm": "Machine.Monitoring.Axes.Z.ActPos",
    "load_x_pct": "Machine.Monitoring.Axes.X.ActLoad",
    "load_y_pct": "Machine.Monitoring.Axes.Y.ActLoad",
    "load_z_pct": "Machine.Monitoring.Axes.Z.ActLoad",
    "feed_mm_min": "Machine.Monitoring.Channel1.ActFeedrate",
    "feed_override_pct": "Machine.Monitoring.Channel1.FeedOverride",
    "feed_hold": "Machine.Monitoring.Channel1.FeedHold",
    "stop": "Machine.Monitoring.Channel1.Stop",
    "emergency_stop": "Machine.Monitoring.Channel1.EmergencyStop",
    "run_state": "Machine.Monitoring.Channel1.ChannelState",
    "work_offset": "Machine.Monitoring.Channel1.ActiveWorkOffset",
    "spindle_rpm": "Machine.Monitoring.Spindle1.ActSpeed",
    "spindle_rpm_command": "Machine.Monitoring.Spindle1.CmdSpeed",
    "spindle_override_pct": "Machine.Monitoring.Spindle1.Override",
    "spindle_torque_nm": "Machine.Monitoring.Spindle1.ActTorque",
    "spindle_current_a": "Machine.Monitoring.Spindle1.ActCurrent",
    "spindle_power_w": "Machine.Monitoring.Spindle1.ActPower",
    "force_x_n": "Machine.Monitoring.Dynamometer.ForceX",
    "force_y_n": "Machine.Monitoring.Dynamometer.ForceY",
    "force_z_n": "Machine.Monitoring.Dynamometer.ForceZ",
    "tool_number": "Machine.Equipment.Tools.ActiveTool.ToolNumber",
    "tool_length_wear_mm": "Machine.Equipment.Tools.ActiveTool.LengthWearOffset",
    "tool_radius_wear_mm": "Machine.Equipment.Tools.ActiveTool.RadiusWearOffset",
}

_VARIANTS = {
    "float": ua.VariantType.Double,
    "int": ua.VariantType.Int32,
    "bool": ua.VariantType.Boolean,
}
_NUMERIC = (bool, int, float)


def variant_type(name: str) -> ua.VariantType:
    """The OPC UA data type of canonical signal ``name`` (Double, Int32 or Boolean)."""
    return _VARIANTS[SIGNALS[name].kind]


#: The answers :meth:`OpcUaConnection._call` decodes.
_Response = TypeVar("_Response", ua.ReadResponse, ua.WriteResponse)


@dataclass(frozen=True)
class _Target:
    """Where a connection reads a signal: the mapping's text and the resolved NodeId."""

    address: str
    node_id: ua.NodeId


@dataclass(frozen=True)
class _Sent:
    """A request on its way: the channel it went on, the future of its answer, what it is, its
    request id on the channel."""

    protocol: UASocketProtocol
    future: asyncio.Future[Any]
    what: str
    request_id: int


class OpcUaConnection(MachineConnection):
    """A machine reached over OPC UA.

    Parameters
    ----------
    config
        ``[connection]`` table: ``endpoint``, ``timeout_s`` (s), backoff, ``security``,
        ``mapping`` (canonical name -> NodeId string or browse path; merged over
        :data:`NODE_MAP`).
    base_dir
        Folder that relative certificate paths of ``config.security`` are resolved against
        (the config file's folder); ``None`` takes the working directory.
    subscription_ms
        A number (default :data:`DEFAULT_SUBSCRIPTION_MS`): the connection subscribes to
        every mapped node with this publishing interval (ms; 0 publishes every change at
        once) and :meth:`read` returns the latest values the server sent, without a request
        (measured 0.09 ms against 1.2 ms for a Read; docs/_bench_opcua.md). A server that
        refuses the subscription falls back to Read. ``None``: :meth:`read` sends one Read
        request for all mapped nodes. :meth:`read_signal` always sends a Read, and a write
        refreshes the cache with the read-back, so ``read()`` after ``write()`` shows it.

    Attributes
    ----------
    heartbeat_s
        ``time.monotonic()`` of the last read in which the ``heartbeat`` signal changed, in s;
        ``None`` before the first. ``now - heartbeat_s`` growing while reads succeed means
        the server answers but the machine behind it is frozen.
    """

    def __init__(
        self,
        config: ConnectionConfig,
        *,
        base_dir: Path | None = None,
        subscription_ms: float | None = DEFAULT_SUBSCRIPTION_MS,
    ) -> None:
        self._init_from_config(config, "opcua", "OPC UA")
        unknown = sorted(set(config.mapping) - set(SIGNALS))
        if unknown:
            raise ConfigError(
                f"[connection] mapping names unknown signal(s) {', '.join(unknown)}; "
                f"valid: {', '.join(SIGNALS)}"
            )
        self.config = config
        self.endpoint = config.endpoint
        self.base_dir = base_dir
        self.addresses: dict[str, str] = {**NODE_MAP, **config.mapping}
        self.heartbeat_s: float | None = None
        self._last_heartbeat: float | None = None
        self._client: Client | None = None
        self._targets: dict[str, _Target] = {}
        # a Read of BLOCK_NODE, once its namespace is known
        self._read_block_request: _Request | None = None
        self._read_all: _Request | None = None
        self._read_one: dict[str, _Request] = {}
        self._write_one: dict[str, _Request] = {}
        if subscription_ms is not None and not (
            math.isfinite(subscription_ms) and subscription_ms >= 0
        ):
            raise ConfigError(f"subscription_ms={subscription_ms!r}; valid: a number >= 0 or None")
        self.subscription_ms = subscription_ms
        self._cache: _Cache | None = None
        self._subscription: Subscription | None = None
        self._delivery: asyncio.Task[None] | None = None  # the subscription's notifications
        self._token: ua.NodeId | None = None
        self._restoring = False
        self._how: str | None = None
        #: write_read_back sends the Read right behind the Write (until a read-back shows
        #: another value than the one written)
        self._pipelined = True

    # Transport hooks ------------------------------------------------------------------
    async def _open(self) -> None:
        client = Client(self.endpoint, timeout=self.timeout_s, watchdog_intervall=5.0)
        client.application_uri = CLIENT_APPLICATION_URI
        client.name = client.description = "cnctwin twin"
        client.session_timeout = _SESSION_TIMEOUT_MS
        await self._apply_security(client, self.config.security)
        try:
            # asyncua's supervisor restores a lost link: ActivateSession of the same session
            # on a new secure channel, TransferSubscriptions and Republish of the missed
            # notifications; a new session only when the server refuses (Part 4, 6.7)
            await client.connect(auto_reconnect=True, reconnect_max_delay=self.backoff.max_s)
        except UaError as err:
            raise ConnectionLost(f"{self.endpoint} refused the session: {err}") from err
        client.connection_lost_callback = self._link_lost
        # the subscription's publishes of the common layout are decoded without asyncua's
        # generic decoder (cnctwin.thread.opcua_publish); the session lives as long as client
        use_lean_publish(client.uaclient.session)
        self._token = client.uaclient.session.authentication_token
        self._client = client
        try:
            self._targets = await self._resolve(client)
        except BaseException:
            await self._close()
            raise
        # the requests are encoded once; each send only fills in its header and value
        self._read_all = _read_request(t.node_id for t in self._targets.values())
        self._read_one = {name: _read_request([t.node_id]) for name, t in self._targets.items()}
        self._write_one = {
            name: _write_request(t.node_id, COMMANDS[name].kind)
            for name, t in self._targets.items()
            if name in COMMANDS
        }
        if self.subscription_ms is not None:
            try:
                self._cache = await self._subscribe(client, self.subscription_ms)
            except UaStatusCodeError as err:  # the server offers no (more) subscriptions
                logger.warning(
                    "no subscription at %s (%s): reading with one Read request per cycle",
                    self.endpoint,
                    err,
                )
            except BaseException:
                await self._close()
                raise

    async def _close(self) -> None:
        self._cache = None
        self._subscription = None
        delivery, self._delivery = self._delivery, None
        if delivery is not None:
            delivery.cancel()
        client, self._client = self._client, None
        if client is None:
            return
        try:
            await client.disconnect()
        except Exception as err:  # closing a dead session must never raise
            logger.debug("disconnect from %s: %s", self.endpoint, err)

    async def _read(self) -> Reading:
        client, request = self._client, self._read_all
        if client is None or request is None:
            raise ConnectionLost("OPC UA client is not open")
        if client.uaclient.state is not UaClientState.CONNECTED:
            raise ConnectionLost(f"session with {self.endpoint} is {client.uaclient.state.value}")
        if self._cache is not None:
            results = [self._cache.values[name] for name in self._targets]
            received = self._cache.received_s
        else:
            results = (await self._call(client, request, ua.ReadResponse, "read")).Results
            received = now_s()
        values: dict[str, float] = {}
        rejected: dict[str, str] = {}
        for (name, target), result in zip(self._targets.items(), results, strict=True):
            value, reason = _checked(name, result)
            if reason is None:
                values[name] = value
            else:
                rejected[name] = f"{target.address}: {reason}"
        beat = values.get("heartbeat")
        if beat is not None and beat != self._last_heartbeat:
            self._last_heartbeat = beat
            self.heartbeat_s = received
        good = [r for r in results if r.StatusCode is None or r.StatusCode.is_good()]
        return Reading(
            values=values,
            received_s=received,
            rejected=rejected,
            source_time_s=_newest(r.SourceTimestamp for r in good),
            server_time_s=_newest(r.ServerTimestamp for r in good),
        )

    async def _reopen(self) -> str:
        """Wait for asyncua's supervisor to restore the link; say how it went.

        Without a client (closed, or never opened) this opens a new session.
        """
        client = self._client
        if client is None:
            await super()._reopen()
            return "new session"
        deadline = now_s() + self.timeout_s
        while client.uaclient.state is not UaClientState.CONNECTED or self._restoring:
            if now_s() > deadline:
                raise ConnectionLost(f"{self.endpoint}: session still being restored")
            await asyncio.sleep(0.005)
        how = self._how or self._session_outcome(client)
        self._how = None
        return how

    async def _link_lost(self, err: Exception) -> None:
        """asyncua's supervisor saw the link drop (it reconnects next): the connection is lost
        now, whether or not a request was under way, and waits for the restoration."""
        logger.warning("OPC UA link to %s lost: %s", self.endpoint, err)
        self._restoring = self._subscription is not None
        if self._client is not None:  # not a close of our own
            self._lost(err)

    def _session_outcome(self, client: Client) -> str:
        token = client.uaclient.session.authentication_token
        kept = self._token is not None and token == self._token
        self._token = token
        return "session re-activated" if kept else "new session (the server refused the old one)"

    def _watch_restore(self, subscription: Subscription) -> None:
        """Record how asyncua restores ``subscription`` after a reconnect (transferred with
        the missed notifications republished, or created anew)."""
        restore, recreate = subscription.restore, subscription.recreate
        recreated = False

        async def recreating() -> None:
            nonlocal recreated
            recreated = True
            await recreate()

        async def watched() -> None:
            nonlocal recreated
            recreated = False
            old_seq = subscription.last_sequence_number or 0
            note = ""
            try:
                # bounded: a server that answers Republish of a message it no longer holds
                # without Bad_MessageNotAvailable (asyncua's own) would keep it going forever
                await asyncio.wait_for(restore(), _RESTORE_S)
            except TimeoutError:
                note = f" (republish cut off after {_RESTORE_S:g} s)"
            finally:
                client = self._client
                session = "" if client is None else self._session_outcome(client)
                if not recreated:
                    replayed = max((subscription.last_sequence_number or 0) - old_seq, 0)
                    sub = f"subscription transferred, {replayed} notification(s) republished"
                else:
                    sub = "subscription created anew (missed notifications lost)"
                self._how = f"{session}; {sub}{note}"
                self._restoring = False

        subscription.restore = watched  # type: ignore[method-assign]
        subscription.recreate = recreating  # type: ignore[method-assign]

    def _start_read_block(self, name: str, since: int) -> Awaitable[SampleBlock]:
        """Send a Read of :data:`BLOCK_NODE` (the newest samples) now; the answer keeps those
        from ``since`` on."""
        client = self._client
        if client is None or client.uaclient.state is not UaClientState.CONNECTED:
            raise ConnectionLost("OPC UA client is not open")
        if name != "vibration":
            raise DataError(f"block {name!r}: an OPC UA machine serves 'vibration' only")
        request = self._read_block_request
        if request is None:
            raise DataError(
                f"block {name!r}: {self.endpoint} serves no {BLOCK_NODE} "
                f"(no namespace {NAMESPACE_URI!r})"
            )
        # the Read built at connect, sent as the cycle's other requests are (_send): none of
        # asyncua's per-request task and timer in the cycle
        (sent,) = self._send(client, (request, b"", f"read of {name}"))
        return self._block(sent, name, since)

    async def _block(self, sent: _Sent, name: str, since: int) -> SampleBlock:
        """The block of the answer to a Read of :data:`BLOCK_NODE` (:meth:`_start_read_block`)."""
        (result,) = (await self._answer(sent, ua.ReadResponse)).Results
        status = result.StatusCode
        if status is not None and not status.is_good():
            raise DataError(
                f"block {name!r}: {self.endpoint} serves no {BLOCK_NODE} ({status.name})"
            )
        packed = result.Value.Value if result.Value is not None else None
        return _decode_block(name, packed, since)

    async def _read_signal(self, name: str) -> float:
        client = self._client
        if client is None:
            raise ConnectionLost("OPC UA client is not open")
        target = self._target(name)
        (read,) = self._send(client, (self._read_one[name], b"", f"read of {name}"))
        return self._feedback(name, target, await self._read_answer(read))

    def _target(self, name: str) -> _Target:
        target = self._targets.get(name)
        if target is None:
            raise ConfigError(f"signal {name!r} is not mapped; valid: {', '.join(self._targets)}")
        return target

    def _feedback(self, name: str, target: _Target, result: ua.DataValue) -> float:
        """A signal's value read by request, checked; DataError when it is garbage."""
        value, reason = _checked(name, result)
        if reason is not None:
            raise DataError(f"machine signal {name!r} at {target.address} unusable: {reason}")
        return value

    def _send(self, client: Client, *requests: tuple[_Request, bytes, str]) -> tuple[_Sent, ...]:
        """Send service requests on the session's secure channel, in this order and in one
        write to the socket; their answers come later (:meth:`_answer`).

        Each is a ``(request, value, what)``: a :class:`_Request` built once, the encoded
        value of a Write (``b""`` for a Read) and what it is for messages. Only the header's
        time stamp, request handle and authentication token and a Write's value change from
        one send to the next, so the request is not encoded anew (:class:`_Request`). Each
        is framed on the session's secure channel with asyncua's request id and sequence
        counter (:func:`~cnctwin.thread.opcua_channel.frame_message`: a plain single chunk
        of policy None directly, anything else by asyncua's chunking, signing and
        encryption), so a request sent later is behind these on the channel; left out are asyncua's
        per-request wrappers (a task and a timer of its own, a wait while its supervisor
        reconnects): the caller's timeout (:class:`MachineConnection`, ``timeout_s``) bounds
        the wait, and a link that is not up fails at once. Two requests in one write reach
        the server in one segment: one system call here and one wake-up there.

        Raises
        ------
        ConnectionLost
            The link is down.
        """
        uaclient = client.uaclient
        protocol = uaclient.protocol
        transport = None if protocol is None else protocol.transport
        if protocol is None or transport is None or uaclient.state is not UaClientState.CONNECTED:
            raise ConnectionLost(
                f"{requests[0][2]} at {self.endpoint}: session is {uaclient.state.value}"
            )
        loop = asyncio.get_running_loop()
        token = protocol.authentication_token
        timeout_ms = int(self.timeout_s * 1000)
        messages: list[bytes] = []
        sent: list[_Sent] = []
        try:
            for request, value, what in requests:
                # asyncua's _send_request, from the encoded request on
                protocol._request_handle += 1
                body = request.encode(token, timeout_ms, protocol._request_handle, value)
                protocol.revolve_security_token()
                request_id = protocol._request_id + 1
                messages.append(frame_message(protocol._connection, body, request_id))
                protocol._request_id = request_id
                future: asyncio.Future[Any] = loop.create_future()
                protocol._callbackmap[request_id] = future
                sent.append(_Sent(protocol, future, what, request_id))
            transport.write(messages[0] if len(messages) == 1 else b"".join(messages))
        except (UaError, ConnectionError) as err:
            for gone in sent:  # never sent: no answer to wait for
                protocol._callbackmap.pop(gone.request_id, None)
            raise ConnectionLost(f"{requests[0][2]} at {self.endpoint}: {err}") from err
        return tuple(sent)

    async def _body(self, sent: _Sent) -> Buffer:
        """The body of the answer to a request of :meth:`_send`, not yet decoded.

        Raises
        ------
        ConnectionLost
            The link went down.
        """
        protocol = sent.protocol
        if type(protocol) is UASocketProtocol:  # a new link (a reconnect makes a new one)
            protocol.__class__ = _PlainAnswers
        try:
            data: Buffer = await sent.future
        except (UaError, ConnectionError) as err:
            raise ConnectionLost(f"{sent.what} at {self.endpoint}: {err}") from err
        return data

    def _decode(self, sent: _Sent, data: Buffer, response_type: type[_Response]) -> _Response:
        """An answer's body decoded whole by asyncua.

        Raises
        ------
        ConnectionLost
            The server answered with a service fault or a Bad service result.
        """
        try:
            sent.protocol.check_answer(data, f" in response to {sent.what}")  # a fault raises
            response: _Response = struct_from_binary(response_type, data)
            response.ResponseHeader.ServiceResult.check()
        except UaError as err:
            raise ConnectionLost(f"{sent.what} at {self.endpoint}: {err}") from err
        return response

    async def _answer(self, sent: _Sent, response_type: type[_Response]) -> _Response:
        """The decoded answer to a request of :meth:`_send` (ConnectionLost as :meth:`_body`
        and :meth:`_decode`)."""
        return self._decode(sent, await self._body(sent), response_type)

    async def _call(
        self, client: Client, request: _Request, response_type: type[_Response], what: str
    ) -> _Response:
        """Send one request (:meth:`_send`) and wait for its decoded answer (:meth:`_answer`)."""
        (sent,) = self._send(client, (request, b"", what))
        return await self._answer(sent, response_type)

    async def _read_answer(self, sent: _Sent) -> ua.DataValue:
        """The value and status of the one node of the answer to a one-node Read of
        :meth:`_send`; the time stamps are left out where the answer has the usual layout
        (:func:`_lean_read_result`), so use :meth:`_answer` where they count."""
        data = await self._body(sent)
        result = _lean_read_result(data)
        if result is None:
            result = self._decode(sent, data, ua.ReadResponse).Results[0]
        return result

    def _send_write(
        self, client: Client, name: str, value: float, *also: tuple[_Request, bytes, str]
    ) -> tuple[_Sent, ...]:
        """Send a Write of command ``name`` (its answer: :meth:`_check_written`), and ``also``
        right behind it in the same socket write (:meth:`_send`)."""
        spec = COMMANDS.get(name)
        if spec is None:
            raise ConfigError(f"{name!r} is not a command; valid: {', '.join(COMMANDS)}")
        if name not in self._targets:
            raise CommandRejected(
                f"{name} is not mapped at {self.endpoint} ([connection] mapping {name} = "
                "'none'); valid: map it to a writable node"
            )
        encoded = _encode_value(spec.kind, value)
        return self._send(client, (self._write_one[name], encoded, f"write of {name}"), *also)

    async def _check_written(self, sent: _Sent, name: str, value: float) -> None:
        """Wait for the answer to a Write of :meth:`_send_write`; CommandRejected on a Bad
        status."""
        data = await self._body(sent)
        status = _lean_write_result(data)
        if status is None:
            (status,) = self._decode(sent, data, ua.WriteResponse).Results
        if not status.is_good():
            spec = COMMANDS[name]
            raise CommandRejected(
                f"machine at {self.endpoint} rejected {name}={value!r} at "
                f"{self._targets[name].address}: {status.name}; valid: {spec.low}..{spec.high} "
                f"{spec.unit}"
            )

    async def _write(self, name: str, value: float) -> None:
        await self._start_write(name, value)

    def _start_write(self, name: str, value: float) -> Awaitable[None]:
        """Send the Write now (:meth:`_send_write`); the answer is awaited by :meth:`_written`."""
        client = self._client
        if client is None:
            raise ConnectionLost("OPC UA client is not open")
        (write,) = self._send_write(client, name, value)
        return self._written(client, write, name, value)

    async def _written(self, client: Client, write: _Sent, name: str, value: float) -> None:
        """Check the answer to a Write (:meth:`_check_written`) and refresh the cache."""
        await self._check_written(write, name, value)
        if self._cache is not None:
            # Refresh the cache with the read-back now, so a read() after the write shows it
            # (the Read sent after the Write's answer: a server may answer a channel's
            # requests in any order, OPC 10000-6 7.1); decoded whole, with its time stamps
            (read,) = self._send(client, (self._read_one[name], b"", f"read-back of {name}"))
            self._cache.values[name] = (await self._answer(read, ua.ReadResponse)).Results[0]

    async def _write_read_back(self, name: str, value: float, pipelined: bool) -> ReadBack:
        """With ``pipelined``, the Write and the Read of its feedback both in flight on the
        secure channel, the Read right behind the Write. A server that handles a channel's
        requests one after the other (asyncua's, so cnctwin's) reads what the Write left. One
        that answers in another order (OPC 10000-6 7.1 allows it; node-opcua often answers
        the Read first) returns the value before, which the caller sees
        (:func:`~cnctwin.thread.measure_latency` reads again); from the first read-back that
        does not show the value written on (such a server, or a machine that applies or
        rounds a command later), the connection sends the Read after the Write's answer. The
        subscription's cache is not touched (:meth:`write` refreshes it)."""
        client = self._client
        if client is None:
            raise ConnectionLost("OPC UA client is not open")
        read_back = (self._read_one[name], b"", f"read-back of {name}")
        t0 = time.perf_counter()
        if pipelined and self._pipelined:  # both in one socket write
            write, read = self._send_write(client, name, value, read_back)
        else:
            (write,), read = self._send_write(client, name, value), None
        try:
            await self._check_written(write, name, value)
        except BaseException:
            if read is not None:  # its answer or failure is not wanted
                read.future.add_done_callback(_dropped)
            raise
        t1 = time.perf_counter()
        result = await self._read_answer(read or self._send(client, read_back)[0])
        t2 = time.perf_counter()
        back = self._feedback(name, self._targets[name], result)
        if read is not None and back != value:
            self._pipelined = False
            logger.info(
                "%s: the read-back of %s sent with the write showed %r, not %r: reading back "
                "after the write's answer from now on",
                self.endpoint,
                name,
                back,
                value,
            )
        return ReadBack(back, t1 - t0, t2 - t1)

    # Helpers --------------------------------------------------------------------------
    async def _apply_security(self, client: Client, security: OpcUaSecurityConfig) -> None:
        if security.username is not None:
            client.set_user(security.username)
            client.set_password(security.password or "")
        if security.policy == "None":
            if security.mode != "None":
                raise ConfigError(
                    f"[connection.security] mode {security.mode!r} needs policy "
                    "'Basic256Sha256'; valid with policy 'None': mode 'None'"
                )
            return
        if security.mode == "None" or not security.certificate or not security.private_key:
            raise ConfigError(
                "[connection.security] policy 'Basic256Sha256' needs mode 'Sign' or "
                "'SignAndEncrypt' and both certificate and private_key "
                f"(got mode={security.mode!r}, certificate={security.certificate!r}, "
                f"private_key={security.private_key!r})"
            )
        if security.server_certificate is None and security.trust_folder is None:
            raise ConfigError(
                "[connection.security] policy 'Basic256Sha256' needs server_certificate (pin "
                "the server's) or trust_folder (certificates to accept); an unknown server "
                "certificate is never accepted (docs/security.md)"
            )
        if security.trust_on_first_use and security.trust_folder is None:
            raise ConfigError(
                "[connection.security] trust_on_first_use = true needs trust_folder (where "
                "the first server certificate seen is kept)"
            )
        if security.trust_folder is not None:
            folder = Path(security.trust_folder).expanduser()
            if not folder.is_absolute() and self.base_dir is not None:
                folder = self.base_dir / folder
            trust = TrustList(folder, "server", first_use=security.trust_on_first_use)
            await trust.load()
            client.certificate_validator = trust
        mode = getattr(ua.MessageSecurityMode, security.mode)
        server_cert = (
            str(self._path(security.server_certificate)) if security.server_certificate else None
        )
        try:
            await client.set_security(
                security_policies.SecurityPolicyBasic256Sha256,
                certificate=str(self._path(security.certificate)),
                private_key=str(self._path(security.private_key)),
                server_certificate=server_cert,
                mode=mode,
            )
        except UaError as err:
            raise ConnectionLost(f"security setup with {self.endpoint}: {err}") from err

    async def _subscribe(self, client: Client, interval_ms: float) -> _Cache:
        """Subscribe to every mapped node; wait for the first value of each."""
        cache = _Cache(self._targets)
        params = ua.CreateSubscriptionParameters(
            RequestedPublishingInterval=ua.Double(interval_ms),
            # a keep-alive about every second when nothing changes
            RequestedLifetimeCount=ua.UInt32(10000),
            RequestedMaxKeepAliveCount=ua.UInt32(max(1, round(1000.0 / max(interval_ms, 1.0)))),
            MaxNotificationsPerPublish=ua.UInt32(10000),
            PublishingEnabled=True,
        )
        # iterator mode: the notifications of a publish are queued and one task (_deliver)
        # applies them all to the cache; a handler would get one asyncio task per changed
        # node, some 40 per publish (unbounded queue: that task always drains it)
        subscription = await client.create_subscription(params, None, queue_maxsize=0)
        self._subscription = subscription
        self._delivery = asyncio.get_running_loop().create_task(_deliver(subscription, cache))
        self._watch_restore(subscription)
        logger.info(
            "subscribed to %d nodes at %s, publishing every %s ms",
            len(self._targets),
            self.endpoint,
            subscription.parameters.RequestedPublishingInterval,
        )
        nodes = [client.get_node(t.node_id) for t in self._targets.values()]
        handles = await subscription.subscribe_data_change(nodes, sampling_interval=ua.Double(0.0))
        for name, handle in zip(self._targets, handles, strict=True):
            if isinstance(handle, ua.StatusCode):  # the server has no such node
                cache.values[name] = ua.DataValue(StatusCode=handle)
        deadline = now_s() + self.timeout_s
        while len(cache.values) < len(self._targets):
            if now_s() > deadline:
                missing = sorted(set(self._targets) - set(cache.values))
                raise ConnectionLost(f"no initial value from {self.endpoint} for {missing}")
            await asyncio.sleep(0.001)
        return cache

    def _path(self, name: str) -> Path:
        path = Path(name).expanduser()
        if not path.is_absolute() and self.base_dir is not None:
            path = self.base_dir / path
        if not path.is_file():
            raise ConfigError(f"[connection.security] file {str(path)!r} not found")
        return path

    async def _resolve(self, client: Client) -> dict[str, _Target]:
        """NodeId of every mapped signal (the default map's namespace looked up by URI); also
        builds the Read of :data:`BLOCK_NODE` in that namespace, so a block read looks nothing
        up."""
        try:
            ns = await client.get_namespace_index(NAMESPACE_URI)
        except ValueError:
            ns = None
        self._read_block_request = (
            None if ns is None else _read_request([ua.NodeId(ua.String(BLOCK_NODE), ua.Int16(ns))])
        )
        targets: dict[str, _Target] = {}
        for name, address in self.addresses.items():
            if address == "none":  # the machine has no such signal (docs/opcua.md, presets)
                continue
            if name not in self.config.mapping:
                if ns is None:
                    raise ConfigError(
                        f"server at {self.endpoint} has no namespace {NAMESPACE_URI!r}; "
                        f"map signal {name!r} in [connection] mapping"
                    )
                targets[name] = _Target(address, ua.NodeId(ua.String(address), ua.Int16(ns)))
            elif _is_node_id(address):
                targets[name] = _Target(address, _parse_node_id(name, address))
            else:
                try:
                    node = await client.nodes.objects.get_child(address.split("/"))
                except UaStatusCodeError as err:
                    raise ConfigError(
                        f"[connection] mapping of {name!r}: browse path {address!r} not found "
                        f"below Objects at {self.endpoint} ({err}); valid: 'ns=2;s=...' or "
                        "'2:Machines/2:Machine/...'"
                    ) from err
                targets[name] = _Target(address, node.nodeid)
        return targets


async def _deliver(subscription: Subscription, cache: _Cache) -> None:
    """Apply the notifications of ``subscription`` (iterator mode) to ``cache`` until it is
    deleted; one wake-up per publish takes every notification it queued."""
    async for event in subscription:
        try:
            if isinstance(event, DataChangeEvent):
                cache.datachange_notification(event.node, event.value, event.data)
            elif isinstance(event, StatusChangeEvent):
                cache.status_change_notification(event.notification)
        except Exception:  # one bad notification must not end the delivery (as a handler's)
            logger.exception("OPC UA notification %r not applied", event)


class _Cache:
    """The latest DataValue of every mapped node, from the subscription's notifications."""

    def __init__(self, targets: Mapping[str, _Target]) -> None:
        self.names: dict[ua.NodeId, list[str]] = {}
        for name, target in targets.items():  # two signals may share a node
            self.names.setdefault(target.node_id, []).append(name)
        self.values: dict[str, ua.DataValue] = {}
        self.received_s = now_s()

    def datachange_notification(self, node: Node, val: Any, data: DataChangeNotif) -> None:
        value = data.monitored_item.Value
        for name in self.names.get(node.nodeid, ()):
            held = self.values.get(name)
            if held is not None and _older(value, held):
                continue  # a republished notification older than what the cache holds
            self.values[name] = value
        self.received_s = now_s()

    def status_change_notification(self, status: ua.StatusChangeNotification) -> None:
        logger.warning("OPC UA subscription status changed: %s", status.Status)


class _PlainAnswers(UASocketProtocol):
    """asyncua's client protocol, which takes the common answer itself: a whole single-chunk
    message of policy None to a request it waits for (:func:`~cnctwin.thread.opcua_channel.
    plain_message`, checked as asyncua checks it) goes to the request's future (asyncua's
    ``_call_callback``) without asyncua's header parsing and chunk objects (issue 17: they
    were about a third of the client's CPU per round trip). Everything else, and everything
    after it in the same segment, is asyncua's (signed or encrypted channels, chunked
    messages, the secure channel's opening and renewal, errors). :meth:`OpcUaConnection._body`
    gives a link's protocol this class."""

    def data_received(self, data: bytes) -> None:
        at = 0
        if not self.receive_buffer:
            connection, waiting = self._connection, self._callbackmap
            while at < len(data):
                message = plain_message(connection, data, at)
                if message is None or message.request_id not in waiting:
                    break
                take_plain_message(connection, message)
                self._call_callback(message.request_id, Buffer(data[message.start : message.end]))
                at = message.end
        if at < len(data):
            super().data_received(data[at:] if at else data)


class _Request:
    """A service request encoded once (issue 17: encoding it anew cost some 12 µs a Read, 14 µs
    a Write of CPU time, of a round trip's few hundred).

    The binary encoding of a request (OPC 10000-6 5.2) is its TypeId, then the RequestHeader:
    AuthenticationToken, Timestamp (Int64, 100 ns ticks since 1601), RequestHandle (UInt32),
    then fields that stay put (ReturnDiagnostics, AuditEntryId, TimeoutHint,
    AdditionalHeader), then the parameters. The encoding asyncua makes of ``request`` is cut
    into the part before the time stamp and the part after the request handle, for the
    session's authentication token and TimeoutHint (made again when either changes); a Write's
    encoded value (:func:`_encode_value`) goes at the end, in place of the ``tail`` bytes of
    the value the request was encoded with.
    """

    def __init__(self, request: ua.ReadRequest | ua.WriteRequest, tail: bytes = b"") -> None:
        self.request = request
        self.tail = tail
        self._key: tuple[ua.NodeId, int] | None = None
        self._head = self._rest = b""

    def encode(self, token: ua.NodeId, timeout_ms: int, handle: int, value: bytes) -> bytes:
        """The request's body for the session's ``token``, with a header stamped now, request
        handle ``handle`` and TimeoutHint ``timeout_ms`` (ms), and a Write's encoded
        ``value``."""
        key = self._key
        if key is None or key[0] is not token or key[1] != timeout_ms:
            self._split(token, timeout_ms)
        ticks = time.time_ns() // 100 + EPOCH_AS_FILETIME
        return b"".join((self._head, _STAMP.pack(ticks, handle), self._rest, value))

    def _split(self, token: ua.NodeId, timeout_ms: int) -> None:
        header = self.request.RequestHeader
        header.AuthenticationToken = token
        header.TimeoutHint = timeout_ms
        whole = struct_to_binary(self.request)
        start = len(nodeid_to_binary(self.request.TypeId)) + len(nodeid_to_binary(token))
        end = len(whole) - len(self.tail)
        if whole[end:] != self.tail:  # asyncua encodes the value otherwise: a bug here
            raise RuntimeError(f"encoding of {type(self.request).__name__} does not end as built")
        self._head, self._rest = whole[:start], whole[start + _STAMP.size : end]
        self._key = (token, timeout_ms)


#: A RequestHeader's Timestamp and RequestHandle.
_STAMP = struct.Struct("<qI")

#: The encoded DataValue of a Write of a bool command and of any other: mask (Value and
#: StatusCode), variant type (Boolean, Double), value, status Good; as asyncua encodes
#: ``ua.DataValue(Value=ua.Variant(value, type))``.
_BOOL_VALUE = struct.Struct("<BB?I")
_DOUBLE_VALUE = struct.Struct("<BBdI")


def _encode_value(kind: str, value: float) -> bytes:
    """The DataValue a Write of a command of ``kind`` sends: Boolean for ``"bool"``, else
    Double."""
    if kind == "bool":
        return _BOOL_VALUE.pack(3, ua.VariantType.Boolean.value, bool(value), 0)
    return _DOUBLE_VALUE.pack(3, ua.VariantType.Double.value, float(value), 0)


#: The start of a response as servers commonly send it (OPC 10000-6 5.2): its TypeId
#: (FourByte NodeId), the ResponseHeader's Timestamp, RequestHandle, ServiceResult, an empty
#: ServiceDiagnostics (mask 0), StringTable (0 or -1 strings) and AdditionalHeader (null
#: NodeId, no body), and the number of Results.
_RESPONSE_START = struct.Struct("<4sqIIBi3si")
_READ_RESPONSE_ID = bytes(nodeid_to_binary(ua.ReadResponse().TypeId))
_WRITE_RESPONSE_ID = bytes(nodeid_to_binary(ua.WriteResponse().TypeId))
#: Variant types a one-value Read answer is decoded without asyncua: scalar Boolean, Int32
#: and Double (the types of :func:`variant_type`), each with how it is packed.
_SCALARS = {
    ua.VariantType.Boolean.value: (struct.Struct("<?"), ua.VariantType.Boolean),
    ua.VariantType.Int32.value: (struct.Struct("<i"), ua.VariantType.Int32),
    ua.VariantType.Double.value: (struct.Struct("<d"), ua.VariantType.Double),
}
_UINT32 = struct.Struct("<I")
_INT32 = struct.Struct("<i")


def _lean_start(data: Buffer, type_id: bytes) -> tuple[bytes, int] | None:
    """The bytes of a response body and where its one Result starts, when the answer is a
    ``type_id`` response with a Good service result, an empty header otherwise and one
    Result; ``None`` for anything else (a fault, diagnostics, another layout), which asyncua
    decodes whole (:meth:`OpcUaConnection._decode`)."""
    body = bytes(data.copy().read(len(data)))
    if len(body) < _RESPONSE_START.size:
        return None
    kind, _, _, service, diagnostics, strings, extra, count = _RESPONSE_START.unpack_from(body)
    if (
        kind != type_id
        or service != 0
        or diagnostics != 0
        or strings not in (0, -1)
        or extra != b"\0\0\0"
        or count != 1
    ):
        return None
    return body, _RESPONSE_START.size


def _lean_end(body: bytes, at: int) -> bool:
    """Whether ``body`` ends at ``at`` with no DiagnosticInfos (0 or -1 of them)."""
    return len(body) == at + 4 and _INT32.unpack_from(body, at)[0] in (0, -1)


def _lean_write_result(data: Buffer) -> ua.StatusCode | None:
    """The one status of a WriteResponse (:func:`_lean_start`); ``None``: decode it whole."""
    start = _lean_start(data, _WRITE_RESPONSE_ID)
    if start is None:
        return None
    body, at = start
    if not _lean_end(body, at + 4):
        return None
    return ua.StatusCode(ua.UInt32(_UINT32.unpack_from(body, at)[0]))


def _lean_read_result(data: Buffer) -> ua.DataValue | None:
    """The one DataValue of a ReadResponse, its value (a scalar of :data:`_SCALARS`) and
    status without the time stamps (:func:`_lean_start`); ``None``: decode it whole.

    The value is not checked here: :func:`_checked` does, as for one asyncua decodes.
    """
    start = _lean_start(data, _READ_RESPONSE_ID)
    if start is None:
        return None
    body, at = start
    if len(body) < at + 2:
        return None
    mask = body[at]
    if mask & ~0x0F or not mask & 0x01:  # picoseconds, or no value: asyncua decodes it
        return None
    scalar = _SCALARS.get(body[at + 1])
    if scalar is None:  # another type, an array: asyncua decodes it
        return None
    packer, variant_type_ = scalar
    at += 2
    if len(body) < at + packer.size:
        return None
    (raw,) = packer.unpack_from(body, at)
    at += packer.size
    status = 0
    if mask & 0x02:
        if len(body) < at + 4:
            return None
        (status,) = _UINT32.unpack_from(body, at)
        at += 4
    at += 8 * ((mask >> 2) & 1) + 8 * ((mask >> 3) & 1)  # source and server time stamps
    if not _lean_end(body, at):
        return None
    return ua.DataValue(
        Value=ua.Variant(raw, variant_type_), StatusCode=ua.StatusCode(ua.UInt32(status))
    )


def _read_request(node_ids: Iterable[ua.NodeId]) -> _Request:
    """A Read of the Value of ``node_ids``, with both time stamps."""
    request = ua.ReadRequest()
    request.Parameters.TimestampsToReturn = ua.TimestampsToReturn.Both
    request.Parameters.NodesToRead = [
        ua.ReadValueId(NodeId=node_id, AttributeId=AttributeIds.Value) for node_id in node_ids
    ]
    return _Request(request)


def _write_request(node_id: ua.NodeId, kind: str) -> _Request:
    """A Write of the Value of ``node_id``, a command of ``kind``; each send brings its
    value (:func:`_encode_value`)."""
    request = ua.WriteRequest()
    if kind == "bool":
        variant = ua.Variant(False, ua.VariantType.Boolean)
    else:
        variant = ua.Variant(0.0, ua.VariantType.Double)
    value = ua.DataValue(Value=variant)
    request.Parameters.NodesToWrite = [
        ua.WriteValue(NodeId=node_id, AttributeId=AttributeIds.Value, Value=value)
    ]
    return _Request(request, _encode_value(kind, 0.0))


def _dropped(future: asyncio.Future[Any]) -> None:
    """Take the outcome of a request whose answer nobody waits for (no "never retrieved")."""
    if not future.cancelled():
        future.exception()


def _posix_s(stamp: datetime | None) -> float | None:
    """A DataValue time stamp as POSIX s (asyncua's naive datetimes are UTC)."""
    if stamp is None:
        return None
    if stamp.tzinfo is None:
        stamp = stamp.replace(tzinfo=UTC)
    return stamp.timestamp()


def _newest(stamps: Any) -> float | None:
    """The latest of some DataValue time stamps, POSIX s; ``None`` when none is set.

    The latest is found among the datetimes (all of one kind: asyncua decodes every stamp as
    UTC) and only it is converted, once per reading instead of once per signal.
    """
    times = [t for t in stamps if t is not None]
    return _posix_s(max(times)) if times else None


def _older(new: ua.DataValue, held: ua.DataValue) -> bool:
    a, b = _posix_s(new.SourceTimestamp), _posix_s(held.SourceTimestamp)
    return a is not None and b is not None and a < b


def _is_node_id(address: str) -> bool:
    return address.split("=", 1)[0] in {"ns", "i", "s", "g", "b", "nsu"}


def _parse_node_id(name: str, address: str) -> ua.NodeId:
    try:
        return ua.NodeId.from_string(address)
    except (ValueError, UaError) as err:
        raise ConfigError(
            f"[connection] mapping of {name!r}: {address!r} is not a NodeId ({err}); "
            "valid: 'ns=2;s=Machine.X' or a browse path '2:Machines/2:Machine/...'"
        ) from err


def _checked(name: str, result: ua.DataValue) -> tuple[float, str | None]:
    """A read value as float, or the reason it is garbage."""
    status = result.StatusCode
    if status is not None and not status.is_good():
        return math.nan, f"status {status.name}"
    raw: Any = result.Value.Value if result.Value is not None else None
    if isinstance(raw, str | bytes) or not isinstance(raw, _NUMERIC):
        return math.nan, f"wrong type {type(raw).__name__} (value {raw!r:.40}), expected a number"
    value = float(raw)
    if not math.isfinite(value):
        return math.nan, f"non-finite value {value!r}"
    spec = SIGNALS[name]
    if (spec.low is not None and value < spec.low) or (spec.high is not None and value > spec.high):
        return math.nan, f"value {value!r} outside {spec.low}..{spec.high} {spec.unit}"
    return value, None


def _decode_block(name: str, packed: object, since: int) -> SampleBlock:
    """The samples of a :data:`BLOCK_NODE` value from index ``since`` on, checked.

    The value comes from the machine and is not trusted: a ByteString of little-endian
    float64 ``[first index, rate (Hz), channels, samples row by row...]`` whose header is
    finite and within :data:`_BLOCK_CHANNELS`, :data:`_BLOCK_RATE_HZ` and
    :data:`_BLOCK_FIRST_MAX`, at most :data:`_BLOCK_VALUES_MAX` values, whole rows of finite
    samples.

    Raises
    ------
    DataError
        Naming the block, the node and what is wrong.
    """
    where = f"block {name!r}: {BLOCK_NODE}"
    if not isinstance(packed, bytes):
        raise DataError(f"{where} holds {type(packed).__name__}; expected a ByteString")
    if len(packed) % 8 or not 24 <= len(packed) <= 8 * _BLOCK_VALUES_MAX:
        raise DataError(
            f"{where} of {len(packed)} bytes; expected whole float64 values, "
            f"3 to {_BLOCK_VALUES_MAX}"
        )
    values = np.frombuffer(packed, dtype="<f8")
    first, rate, channels = (float(v) for v in values[:3])
    low, high = _BLOCK_CHANNELS
    if not (math.isfinite(channels) and channels.is_integer() and low <= channels <= high):
        raise DataError(f"{where}: {channels!r} channels; valid: whole numbers {low} to {high}")
    if not (math.isfinite(rate) and _BLOCK_RATE_HZ[0] <= rate <= _BLOCK_RATE_HZ[1]):
        raise DataError(
            f"{where}: rate {rate!r} Hz; valid: {_BLOCK_RATE_HZ[0]:g} to {_BLOCK_RATE_HZ[1]:g}"
        )
    if not (math.isfinite(first) and first.is_integer() and 0 <= first < _BLOCK_FIRST_MAX):
        raise DataError(f"{where}: first index {first!r}; valid: whole numbers >= 0")
    if (values.size - 3) % int(channels):
        raise DataError(f"{where}: {values.size - 3} samples are not whole rows of {channels:g}")
    samples = values[3:].reshape(-1, int(channels))
    if not np.isfinite(samples).all():
        raise DataError(f"{where}: a sample is not a finite number")
    skip = min(max(since - int(first), 0), samples.shape[0])
    return SampleBlock(name, int(first) + skip, rate, samples[skip:])
