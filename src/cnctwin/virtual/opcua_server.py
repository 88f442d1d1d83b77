"""OPC UA server of the virtual machine (asyncua): publishes its signals, applies commands.

The address space follows the OPC UA for Machine Tools companion specification (OPC 40501)
where it has a place for a signal — ``Objects/Machines/Machine`` with ``Identification``,
``Monitoring`` (``MachineTool``, ``Channel1``, ``Spindle1``), ``Production/ActiveProgram``
and ``Equipment/Tools`` — and takes the axis nodes (``ActPos``, ``ActLoad``) from OPC 40502
CNC Systems. The variables are plain BaseDataVariables with string NodeIds in the namespace
:data:`~cnctwin.thread.opcua.NAMESPACE_URI`; the map is :data:`~cnctwin.thread.opcua.NODE_MAP`
and docs/opcua.md.

Writes from clients to a command node go through ``source.command(name, value)`` and the node
then holds the machine's read-back; a write that is not a finite number in the command's
range (or that the machine refuses) is answered with ``BadOutOfRange`` or
``BadTypeMismatch`` per node, and writes to any other node of the machine with
``BadNotWritable``. The server never raises out of a client's write.

Access (docs/security.md): the user manager is cnctwin's own (:mod:`cnctwin.virtual.users`);
there is no administrator. Only an ``"operator"`` session may write, and only the command
nodes (``BadUserAccessDenied`` otherwise); the node management services (AddNodes,
DeleteNodes, AddReferences, DeleteReferences), server registration and method calls are
refused to every session with ``BadUserAccessDenied``. With Sign or SignAndEncrypt, client
certificates are checked against a trust folder (:class:`~cnctwin.thread.trust.TrustList`).
"""

from __future__ import annotations

import asyncio
import logging
import math
import socket
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import UTC
from pathlib import Path
from typing import Any, Literal, Protocol

import numpy as np
from asyncua import Server, ua
from asyncua.common.utils import ServiceError
from asyncua.crypto.permission_rules import USER_TYPES, PermissionRuleset, User, UserRole
from asyncua.server.address_space import AttributeService, AttributeValue
from asyncua.server.user_managers import UserManager

from cnctwin import __version__
from cnctwin.errors import CnctwinError, ConfigError
from cnctwin.thread import (
    BLOCK_NODE,
    COMMANDS,
    NAMESPACE_URI,
    NODE_MAP,
    SIGNALS,
    TrustList,
    variant_type,
)
from cnctwin.virtual.exposure import check_exposure
from cnctwin.virtual.machine_tool import add_machine_tool, mirror_value
from cnctwin.virtual.opcua_lean import LeanServer, LeanService, MachineNode
from cnctwin.virtual.users import UserTable
from cnctwin.virtual.vibration import BLOCK_NAME

__all__ = [
    "SERVER_APPLICATION_URI",
    "MachineSource",
    "OpcUaMachineServer",
    "OpcUaServerSecurity",
    "SecurityMode",
    "free_port",
]

logger = logging.getLogger(__name__)

#: Application URI of the virtual machine's server (the URI its certificate must carry).
SERVER_APPLICATION_URI = "urn:cnctwin:virtual-machine:server"

_IDENTIFICATION = {
    "Manufacturer": "cnctwin",
    "Model": "virtual 3-axis milling machine",
    "SerialNumber": "VM-0001",
    "SoftwareRevision": __version__,
}


class MachineSource(Protocol):
    """What a machine server serves: the virtual machine, or a test's fake."""

    def snapshot(self) -> Mapping[str, float]:
        """Current value of every read signal, by canonical name."""
        ...

    def command(self, name: str, value: float) -> None:
        """Apply a command; raise :class:`~cnctwin.errors.CnctwinError` if invalid."""
        ...


#: Message security of the endpoint (policy Basic256Sha256 unless ``"None"``).
SecurityMode = Literal["None", "Sign", "SignAndEncrypt"]


@dataclass(frozen=True)
class OpcUaServerSecurity:
    """Security of the server's endpoint.

    Attributes
    ----------
    mode
        ``"None"`` (loopback demos), ``"Sign"`` or ``"SignAndEncrypt"`` (both with policy
        Basic256Sha256).
    certificate, private_key
        The server's certificate (DER or PEM) and private key (PEM); required unless mode is
        ``"None"``.
    trust_folder
        Folder of the client certificates (or their CAs) to accept (``.der``/``.pem``);
        required unless mode is ``"None"`` (:class:`~cnctwin.thread.trust.TrustList`).
    """

    mode: SecurityMode = "None"
    certificate: Path | None = None
    private_key: Path | None = None
    trust_folder: Path | None = None


@dataclass
class _Session(User):
    """An activated client session: its user (``None``: anonymous) and whether it may
    command the machine."""

    operator: bool = False


class _TableUsers(UserManager):
    """asyncua user manager over a :class:`~cnctwin.virtual.users.UserTable`."""

    def __init__(self, table: UserTable) -> None:
        self._table = table

    def get_user(
        self,
        iserver: Any,
        username: str | None = None,
        password: str | None = None,
        certificate: Any = None,
    ) -> User | None:
        role = self._table.role_of(username, password)
        if role is None:
            logger.warning("OPC UA login refused: %s", username or "anonymous session")
            return None
        return _Session(role=UserRole.User, name=username, operator=role == "operator")


#: Services any activated session may use: sessions, browsing, reading, subscriptions and
#: writes (which the attribute service then restricts); never node management, server
#: registration or method calls.
_SESSION_SERVICES = frozenset(
    ua.NodeId(t)
    for t in (*USER_TYPES, ua.ObjectIds.BrowseNextRequest_Encoding_DefaultBinary)
    if t != ua.ObjectIds.CallRequest_Encoding_DefaultBinary
)


class _Ruleset(PermissionRuleset):
    """Which services a session may call: those of :data:`_SESSION_SERVICES`, and only once
    activated by :class:`_TableUsers` (asyncua answers the rest with BadUserAccessDenied)."""

    def check_validity(self, user: User, action_type_id: ua.NodeId, body: Any) -> bool:
        return isinstance(user, _Session) and action_type_id in _SESSION_SERVICES


class _MachineAttributeService(AttributeService):
    """Write service: an operator's writes of command nodes go to the source; every other
    client write is refused. The server's own internal writes (its clock) pass. Read
    service: the vibration block's value is made when it is read (:meth:`OpcUaMachineServer.
    block_value`)."""

    def read(self, params: ua.ReadParameters) -> list[ua.DataValue]:
        results = super().read(params)
        block = self._machine.block_node
        if block is not None:
            for index, item in enumerate(params.NodesToRead):
                if item.NodeId == block and item.AttributeId == ua.AttributeIds.Value:
                    results[index] = self._machine.block_value()
        return results

    def __init__(self, server: OpcUaMachineServer, base: AttributeService, internal: User) -> None:
        super().__init__(base._aspace)
        self._machine = server
        self._internal = internal

    async def write(
        self, params: ua.WriteParameters, user: User | None = None
    ) -> list[ua.StatusCode]:
        if user is not None and user is self._internal:
            return await super().write(params, user)
        results: list[ua.StatusCode] = []
        for item in params.NodesToWrite:
            name = self._machine.name_of(item.NodeId)
            refused = write_refusal(user, name, item.NodeId, item.AttributeId)
            if refused is not None:
                results.append(refused)
            else:
                assert name is not None
                value = item.Value.Value.Value if item.Value.Value is not None else None
                results.append(self._machine.command_status(name, value))
        return results


def write_refusal(
    user: User | None, name: str | None, node_id: ua.NodeId, attribute_id: int
) -> ua.StatusCode | None:
    """Why a client session's write of ``attribute_id`` of ``node_id`` (the machine's signal
    ``name``, ``None``: not one) is refused, or ``None`` if it goes to the machine: only an
    operator writes, and only the Value of a command node (``BadUserAccessDenied``,
    ``BadNotWritable``). The one place both write paths ask (asyncua's service and
    :mod:`cnctwin.virtual.opcua_lean`)."""
    operator = isinstance(user, _Session) and user.operator
    if not operator or name is None:
        logger.warning(
            "OPC UA write of %s by %s refused: not an operator's command node",
            node_id.to_string(),
            getattr(user, "name", None) or "an anonymous session",
        )
        return _status(ua.StatusCodes.BadUserAccessDenied)
    if attribute_id != ua.AttributeIds.Value or name not in COMMANDS:
        return _status(ua.StatusCodes.BadNotWritable)
    return None


class OpcUaMachineServer:
    """OPC UA server for a machine source. Use as ``async with``.

    Parameters
    ----------
    source
        Has ``snapshot()`` and ``command(name, value)``
        (:class:`~cnctwin.virtual.machine.VirtualMachine`, or a fake).
    host
        Interface to listen on.
    port
        TCP port; 0 picks a free one (see :attr:`endpoint`).
    security
        Endpoint security; default: policy None.
    users
        Users, roles and what an anonymous session may do; default: no users, anonymous
        read-only. Passwords travel encrypted only with Sign or SignAndEncrypt.
    insecure
        Allow policy None on a non-loopback ``host`` (refused otherwise,
        :func:`~cnctwin.virtual.exposure.check_exposure`).
    machine_tool_model
        Also load the OPC 40501 Machine Tools information model and serve
        ``Objects/Machines/MachineTool`` of ``MachineToolType`` with live values
        (:mod:`cnctwin.virtual.machine_tool`; a start takes about 2 s longer).

    Notes
    -----
    Call :meth:`publish` after each step of the machine (the machine clock's listener); it
    writes every changed value into the address space in one pass, without network traffic,
    and subscriptions see the change.
    """

    def __init__(
        self,
        source: MachineSource,
        host: str = "127.0.0.1",
        port: int = 0,
        security: OpcUaServerSecurity | None = None,
        users: UserTable | None = None,
        insecure: bool = False,
        machine_tool_model: bool = False,
    ) -> None:
        self.source = source
        self.machine_tool_model = machine_tool_model
        self._mirrors: dict[str, list[Any]] = {}
        self.users = users or UserTable()
        self.security = security or OpcUaServerSecurity()
        _check_complete(self.security)
        if not self.users.accounts and self.users.anonymous is None:
            raise ConfigError(
                "the OPC UA server has no users and refuses anonymous sessions: nobody could "
                "connect; add [users.NAME] tables to the users file or set anonymous"
            )
        check_exposure(host, "opcua", secured=self.security.mode != "None", insecure=insecure)
        self.host = host
        self.port = port or free_port(host)
        self.endpoint = f"opc.tcp://{host}:{self.port}/cnctwin"
        self.namespace_index = 0
        self._server: Server | None = None
        self._names: dict[ua.NodeId, str] = {}
        #: The vibration block's node (a source with a ``block`` method), else ``None``.
        self.block_node: ua.NodeId | None = None
        self._published: dict[str, Any] = {}
        self._slots: dict[str, AttributeValue] = {}
        self._tasks: set[asyncio.Task[None]] = set()

    # Lifecycle ------------------------------------------------------------------------
    async def __aenter__(self) -> OpcUaMachineServer:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

    async def start(self) -> None:
        """Build the address space and listen; ConfigError on incomplete security."""
        security = self.security
        tokens: list[type] = [ua.UserNameIdentityToken] if self.users.accounts else []
        if self.users.anonymous is not None:
            tokens.append(ua.AnonymousIdentityToken)
        server = LeanServer(user_manager=_TableUsers(self.users))
        server.allow_remote_admin(False)
        await server.init()
        server.set_endpoint(self.endpoint)
        server.set_server_name("cnctwin virtual machine")
        await server.set_application_uri(SERVER_APPLICATION_URI)
        server.set_security_policy([_policy(security.mode)], permission_ruleset=_Ruleset())
        server.set_identity_tokens(tokens)
        if security.mode != "None":
            assert security.trust_folder and security.certificate and security.private_key
            trust = TrustList(security.trust_folder, "client")
            await trust.load()
            server.set_certificate_validator(trust)
            await server.load_certificate(str(security.certificate))
            await server.load_private_key(str(security.private_key))
        self.namespace_index = await server.register_namespace(NAMESPACE_URI)
        await self._build(server)
        if self.machine_tool_model:
            self._mirrors = await add_machine_tool(server, self.namespace_index, _IDENTIFICATION)
        iserver = server.iserver
        iserver.attribute_service = _MachineAttributeService(
            self, iserver.attribute_service, iserver.isession.user
        )
        _answer_republish_by_the_spec(iserver.subscription_service)
        # the common Read and Write of the machine's variables skip asyncua's generic
        # decoding, dispatch and encoding (cnctwin.virtual.opcua_lean; issue 17)
        nodes = [
            MachineNode(name, node_id, self._slots[name]) for node_id, name in self._names.items()
        ]
        server.service = LeanService(nodes, write_refusal, self.command_status)
        await server.start()
        self._server = server
        self.publish()
        logger.info("OPC UA machine server listening at %s (%s)", self.endpoint, security.mode)

    @property
    def clients(self) -> int:
        """Clients connected now (open TCP connections; 0 when not listening)."""
        if self._server is None or self._server.bserver is None:
            return 0
        return len(self._server.bserver.clients)

    async def stop(self) -> None:
        """Stop listening and drop every session."""
        server, self._server = self._server, None
        if server is not None:
            # asyncua's clock task sleeps 1 s between updates of ServerStatus/CurrentTime and
            # stop() waits for it; cancel it so a stop (and a restart) takes milliseconds.
            clock = server.iserver.time_task
            if clock is not None:
                clock.cancel()
                server.iserver.time_task = None
            await server.stop()
            self._published.clear()

    # Publishing -----------------------------------------------------------------------
    def publish(self, snapshot: Mapping[str, float] | None = None) -> None:
        """Write the changed values of ``snapshot`` into the address space.

        Parameters
        ----------
        snapshot
            Canonical name -> value in the signal's unit; default ``source.snapshot()``. A
            non-finite value of an integer or boolean signal is published with status
            ``BadOutOfRange`` (a Double carries NaN as is, for the client to reject).

        Notes
        -----
        Synchronous, no network traffic: it replaces the stored DataValues and schedules the
        data-change callbacks of any subscription (asyncua's own write path does the same,
        one awaited call per node).
        """
        if self._server is None:
            return
        snap = self.source.snapshot() if snapshot is None else snapshot
        stamp = ua.DateTime.now(UTC)
        notify: list[tuple[dict[int, Any], int, ua.DataValue]] = []
        for name, value in snap.items():
            slot = self._slots.get(name)
            before = self._published.get(name, _UNSET)
            if slot is None or before == value or (before != before and value != value):
                continue  # unchanged (NaN, a value not known, stays unknown)
            self._published[name] = value
            data = _data_value(name, value, stamp)
            slot.value = data
            notify.extend(
                (slot.datachange_callbacks, handle, data) for handle in slot.datachange_callbacks
            )
            for mirror in self._mirrors.get(name, ()):  # the Machine Tools model's variables
                mirrored = mirror_value(mirror, value, stamp)
                if mirrored is not None:
                    mirror.slot.value = mirrored
                    notify.extend(
                        (mirror.slot.datachange_callbacks, handle, mirrored)
                        for handle in mirror.slot.datachange_callbacks
                    )
        if notify:  # one task per publish runs every subscription's callbacks
            task = asyncio.get_running_loop().create_task(_notify(notify))
            self._tasks.add(task)
            task.add_done_callback(self._tasks.discard)

    # Commands -------------------------------------------------------------------------
    def name_of(self, node_id: ua.NodeId) -> str | None:
        """Canonical name of a mapped node of this machine, else ``None``."""
        return self._names.get(node_id)

    def command_status(self, name: str, raw: object) -> ua.StatusCode:
        """Validate a client's write of ``raw`` to command ``name``, apply it, publish the
        read-back.

        Returns
        -------
        ua.StatusCode
            Good, or BadTypeMismatch / BadOutOfRange / BadInternalError; never raises.
        """
        spec = COMMANDS[name]
        boolean = spec.kind == "bool"
        if not isinstance(raw, bool | int | float) or (isinstance(raw, bool) and not boolean):
            logger.warning("OPC UA write of %s rejected: %r is not a %s", name, raw, spec.kind)
            return _status(ua.StatusCodes.BadTypeMismatch)
        value = float(raw)
        low = -math.inf if spec.low is None else spec.low
        high = math.inf if spec.high is None else spec.high
        if not (math.isfinite(value) and low <= value <= high) or (
            boolean and value not in (0.0, 1.0)
        ):
            logger.warning("OPC UA write of %s=%r rejected: outside %s..%s", name, raw, low, high)
            return _status(ua.StatusCodes.BadOutOfRange)
        try:
            self.source.command(name, value)
        except CnctwinError as err:
            logger.warning("OPC UA write of %s=%r refused by the machine: %s", name, raw, err)
            return _status(ua.StatusCodes.BadOutOfRange)
        except Exception:
            logger.exception("OPC UA write of %s=%r failed in the machine", name, raw)
            return _status(ua.StatusCodes.BadInternalError)
        readback = self.source.snapshot().get(name, value)
        self.publish({name: readback})
        return _status(ua.StatusCodes.Good)

    # Address space --------------------------------------------------------------------
    async def _build(self, server: Server) -> None:
        ns = self.namespace_index
        machines = await server.nodes.objects.add_folder(
            _node_id("Machines", ns), ua.QualifiedName("Machines", ns)
        )
        folders: dict[str, Any] = {}

        async def parent(path: tuple[str, ...]) -> Any:
            if not path:
                return machines
            key = ".".join(path)
            if key not in folders:
                above = await parent(path[:-1])
                folders[key] = await above.add_object(
                    _node_id(key, ns), ua.QualifiedName(path[-1], ns)
                )
            return folders[key]

        for label, text in _IDENTIFICATION.items():
            node = await parent(("Machine", "Identification"))
            await node.add_variable(
                _node_id(f"Machine.Identification.{label}", ns),
                ua.QualifiedName(label, ns),
                ua.Variant(text, ua.VariantType.String),
            )
        snapshot = self.source.snapshot()
        for name, identifier in NODE_MAP.items():
            parts = tuple(identifier.split("."))
            node = await parent(parts[:-1])
            vtype = variant_type(name)
            value = snapshot.get(name, 0.0)
            # a value not known yet (NaN) gets its status when start() publishes
            initial = _coerce(name, value if math.isfinite(value) else 0.0)
            variable = await node.add_variable(
                _node_id(identifier, ns),
                ua.QualifiedName(parts[-1], ns),
                ua.Variant(initial, vtype),
                datatype=_DATATYPES[vtype],
            )
            spec = SIGNALS[name]
            await variable.write_attribute(
                ua.AttributeIds.Description,
                ua.DataValue(ua.Variant(ua.LocalizedText(f"{spec.description} [{spec.unit}]"))),
            )
            if spec.writable:
                await variable.set_writable(True)
            self._names[variable.nodeid] = name
            self._slots[name] = server.iserver.aspace[variable.nodeid].attributes[
                ua.AttributeIds.Value
            ]
        if callable(getattr(self.source, "block", None)):  # a machine with a vibration sensor
            vibration = await parent(tuple(BLOCK_NODE.split(".")[:-1]))
            node = await vibration.add_variable(
                _node_id(BLOCK_NODE, ns),
                ua.QualifiedName(BLOCK_NODE.split(".")[-1], ns),
                ua.Variant(np.zeros(3, "<f8").tobytes(), ua.VariantType.ByteString),
                datatype=ua.NodeId(ua.Int32(ua.ObjectIds.ByteString)),
            )
            self.block_node = node.nodeid

    def block_value(self) -> ua.DataValue:
        """The value of :data:`~cnctwin.thread.BLOCK_NODE`, made when read: the machine's last
        :data:`BLOCK_WINDOW_S` of vibration samples as a ByteString of little-endian float64,
        ``[first index, rate (Hz), channels, samples row by row...]``
        (cnctwin.virtual.vibration); ``BadNoData`` without them."""
        read = self.source.block  # type: ignore[attr-defined]
        try:
            count = read(BLOCK_NAME, 2**62).first_index  # an empty block: the samples taken
            block = read(BLOCK_NAME, count - 1)
            block = read(BLOCK_NAME, count - math.ceil(BLOCK_WINDOW_S * block.rate_hz))
        except CnctwinError:
            return ua.DataValue(StatusCode=_status(ua.StatusCodes.BadNoData))
        samples = np.asarray(block.samples, dtype=np.float64)
        head = np.array([block.first_index, block.rate_hz, samples.shape[1]], dtype="<f8")
        data = np.concatenate((head, samples.ravel())).astype("<f8").tobytes()
        packed = ua.Variant(data, ua.VariantType.ByteString)
        now = ua.DateTime.now(UTC)
        return ua.DataValue(packed, SourceTimestamp=now, ServerTimestamp=now)


_UNSET = object()
#: Seconds of the newest vibration samples a read of the block node returns (a reader slower
#: than this between two reads loses samples, and says so: ``chatter_gap``).
BLOCK_WINDOW_S = 0.1
_DATATYPES = {
    ua.VariantType.Double: ua.NodeId(ua.Int32(ua.ObjectIds.Double)),
    ua.VariantType.Int32: ua.NodeId(ua.Int32(ua.ObjectIds.Int32)),
    ua.VariantType.Boolean: ua.NodeId(ua.Int32(ua.ObjectIds.Boolean)),
}


def _check_complete(security: OpcUaServerSecurity) -> None:
    """ConfigError if a secured endpoint lacks its certificate, key or trust folder."""
    _policy(security.mode)
    if security.mode == "None":
        return
    if security.certificate is None or security.private_key is None:
        raise ConfigError(
            f"OPC UA security mode {security.mode!r} needs a server certificate and "
            f"private key (--certificate, --private-key; got {security.certificate}, "
            f"{security.private_key})"
        )
    if security.trust_folder is None:
        raise ConfigError(
            f"OPC UA security mode {security.mode!r} needs a trust folder with the "
            "certificates of the clients to accept (--trust FOLDER)"
        )


def _policy(mode: str) -> ua.SecurityPolicyType:
    policies = {
        "None": ua.SecurityPolicyType.NoSecurity,
        "Sign": ua.SecurityPolicyType.Basic256Sha256_Sign,
        "SignAndEncrypt": ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt,
    }
    if mode not in policies:
        raise ConfigError(f"OPC UA security mode {mode!r}; valid: {', '.join(policies)}")
    return policies[mode]


def _coerce(name: str, value: float) -> float | int | bool:
    """``value`` as the Python type of the signal's variant (ValueError if not finite)."""
    kind = SIGNALS[name].kind
    if kind == "float":
        return float(value)
    if not math.isfinite(value):
        raise ValueError(f"{name}={value!r} is not finite")
    return bool(value) if kind == "bool" else int(round(value))


def _data_value(name: str, value: float, stamp: ua.DateTime) -> ua.DataValue:
    try:
        variant = ua.Variant(_coerce(name, value), variant_type(name))
    except (TypeError, ValueError):
        return ua.DataValue(
            StatusCode=_status(ua.StatusCodes.BadOutOfRange),
            SourceTimestamp=stamp,
            ServerTimestamp=stamp,
        )
    # the machine's tick is the source time; the server holds the value from then on
    return ua.DataValue(variant, SourceTimestamp=stamp, ServerTimestamp=stamp)


def _answer_republish_by_the_spec(service: Any) -> None:
    """Answer a Republish of a message the server no longer holds with Bad_MessageNotAvailable
    (OPC UA Part 4, 5.13.6). asyncua's server answers it with an empty message and Good, on
    which a client that republishes until that status (asyncua's, after a reconnection) never
    stops."""
    republish = service.republish

    def answer(params: ua.RepublishParameters) -> ua.NotificationMessage:
        subscription = service.subscriptions.get(params.SubscriptionId)
        if subscription is None:
            raise ServiceError(ua.StatusCodes.BadSubscriptionIdInvalid)
        if params.RetransmitSequenceNumber not in subscription._not_acknowledged_results:
            raise ServiceError(ua.StatusCodes.BadMessageNotAvailable)
        return republish(params)

    service.republish = answer


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port on ``host`` that nothing listens on now (the OS picks it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind((host, 0))
        return int(probe.getsockname()[1])


async def _notify(calls: list[tuple[dict[int, Any], int, ua.DataValue]]) -> None:
    """Run asyncua's data-change callbacks (subscriptions) for published values.

    Each call names the node's callback table and the handle, looked up when its turn comes: a
    client that deleted its monitored item (or disconnected) since the publish has no callback
    left, and its handle is skipped (asyncua's callback would fail on the missing item).
    """
    for callbacks, handle, data in calls:
        callback = callbacks.get(handle)
        if callback is None:
            continue
        try:
            await callback(handle, data)
        except Exception:
            logger.exception("OPC UA data-change callback failed")


def _status(code: int) -> ua.StatusCode:
    return ua.StatusCode(ua.UInt32(code))


def _node_id(identifier: str, ns: int) -> ua.NodeId:
    return ua.NodeId(ua.String(identifier), ua.Int16(ns))
