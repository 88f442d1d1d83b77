"""Security of the virtual machine's OPC UA server, proven refusal by refusal over loopback.

A real asyncua client (software the project did not write) tries what an intruder would:
log in as ``admin``, delete the Stop node, add nodes and references, write Stop as a read-only
user or anonymously, connect with a certificate the server does not trust. Each is refused
with the OPC UA status the standard names, and the twin can still stop the machine after.
"""

from __future__ import annotations

import asyncio
import shutil
from collections.abc import Awaitable, Callable
from pathlib import Path

import pytest
from asyncua import Client, ua
from asyncua.crypto import security_policies
from opcua_fixtures import TIMEOUT_S, FakeMachine
from pki import certificate

from cnctwin.errors import ConfigError
from cnctwin.thread.config import ConnectionConfig, OpcUaSecurityConfig
from cnctwin.thread.connection import CommandRejected, ConnectionLost
from cnctwin.thread.opcua import CLIENT_APPLICATION_URI, NAMESPACE_URI, NODE_MAP, OpcUaConnection
from cnctwin.virtual.opcua_server import OpcUaMachineServer, OpcUaServerSecurity
from cnctwin.virtual.users import Account, UserTable, hash_password

STOP = NODE_MAP["stop"]


def run(body: Callable[[], Awaitable[None]]) -> None:
    async def main() -> None:
        await asyncio.wait_for(body(), TIMEOUT_S)

    asyncio.run(main())


def users(anonymous: str | None = "read-only") -> UserTable:
    return UserTable(
        {
            "twin": Account("operator", hash_password("op-pass")),
            "viewer": Account("read-only", hash_password("view-pass")),
        },
        anonymous,  # type: ignore[arg-type]
    )


def connection(server: OpcUaMachineServer, username: str | None, password: str | None = None):
    security = OpcUaSecurityConfig(username=username, password=password)
    return OpcUaConnection(
        ConnectionConfig(endpoint=server.endpoint, timeout_s=5.0, security=security),
        subscription_ms=None,
    )


async def session(server: OpcUaMachineServer, user: str | None, password: str = "") -> Client:
    client = Client(server.endpoint, timeout=5.0)
    if user is not None:
        client.set_user(user)
        client.set_password(password)
    await client.connect()
    return client


async def stop_node(client: Client) -> ua.NodeId:
    ns = await client.get_namespace_index(NAMESPACE_URI)
    return ua.NodeId(ua.String(STOP), ua.Int16(ns))


def test_admin_with_any_password_is_refused_and_cannot_delete_stop() -> None:
    async def body() -> None:
        machine = FakeMachine()
        async with OpcUaMachineServer(machine, users=users()) as server:
            # asyncua's own default user manager made "admin" (any password) an administrator
            for password in ("", "admin", "anything"):
                with pytest.raises(ua.UaStatusCodeError) as refused:
                    await session(server, "admin", password)
                assert refused.value.code == ua.StatusCodes.BadUserAccessDenied
            # an operator, anonymous: the node management services are refused to everyone
            for user, password in (("twin", "op-pass"), (None, "")):
                client = await session(server, user, password)
                try:
                    stop = client.get_node(await stop_node(client))
                    with pytest.raises(ua.UaStatusCodeError) as refused:
                        await client.delete_nodes([stop], recursive=True)
                    assert refused.value.code == ua.StatusCodes.BadUserAccessDenied
                    with pytest.raises(ua.UaStatusCodeError) as refused:
                        await client.nodes.objects.add_folder(ua.NodeId("Evil", 2), "Evil")
                    assert refused.value.code == ua.StatusCodes.BadUserAccessDenied
                    ref = ua.AddReferencesItem(
                        SourceNodeId=ua.NodeId(ua.ObjectIds.ObjectsFolder),
                        ReferenceTypeId=ua.NodeId(ua.ObjectIds.Organizes),
                        IsForward=True,
                        TargetNodeId=stop.nodeid,
                    )
                    with pytest.raises(ua.UaStatusCodeError) as refused:
                        await client.uaclient.add_references([ref])
                    assert refused.value.code == ua.StatusCodes.BadUserAccessDenied
                    gone = ua.DeleteReferencesItem(
                        SourceNodeId=ua.NodeId(ua.ObjectIds.ObjectsFolder),
                        ReferenceTypeId=ua.NodeId(ua.ObjectIds.Organizes),
                        IsForward=True,
                        TargetNodeId=ua.NodeId(ua.ObjectIds.Server),
                        DeleteBidirectional=True,
                    )
                    with pytest.raises(ua.UaStatusCodeError) as refused:
                        await client.uaclient.delete_references([gone])
                    assert refused.value.code == ua.StatusCodes.BadUserAccessDenied
                    assert await stop.read_value() is False  # still there
                finally:
                    await client.disconnect()
            # ... and the twin can still stop the machine
            async with connection(server, "twin", "op-pass") as twin:
                await twin.write("stop", 1.0)
            assert machine.commands == [("stop", 1.0)]

    run(body)


def test_only_operators_write_and_only_the_command_nodes() -> None:
    async def body() -> None:
        machine = FakeMachine()
        async with OpcUaMachineServer(machine, users=users()) as server:
            for user, password in (("viewer", "view-pass"), (None, None)):
                async with connection(server, user, password) as twin:
                    assert (await twin.read()).values["x_mm"] == machine.values["x_mm"]
                    with pytest.raises(CommandRejected, match="BadUserAccessDenied"):
                        await twin.write("stop", 1.0)
            assert machine.commands == []
            client = await session(server, "twin", "op-pass")
            try:
                stop = await stop_node(client)
                ns = stop.NamespaceIndex
                position = ua.NodeId(ua.String(NODE_MAP["x_mm"]), ua.Int16(ns))
                status = ua.NodeId(ua.ObjectIds.Server_ServerStatus_State)
                for node, expected in (
                    (position, ua.StatusCodes.BadNotWritable),
                    (status, ua.StatusCodes.BadUserAccessDenied),
                ):
                    value = ua.DataValue(ua.Variant(1.0, ua.VariantType.Double))
                    params = ua.WriteParameters(
                        NodesToWrite=[
                            ua.WriteValue(
                                NodeId=node, AttributeId=ua.AttributeIds.Value, Value=value
                            )
                        ]
                    )
                    (result,) = await client.uaclient.write(params)
                    assert result.value == expected
                # a description (not a value) of the Stop node: not writable either
                text = ua.DataValue(ua.Variant(ua.LocalizedText("pwned")))
                params = ua.WriteParameters(
                    NodesToWrite=[
                        ua.WriteValue(
                            NodeId=stop, AttributeId=ua.AttributeIds.Description, Value=text
                        )
                    ]
                )
                (result,) = await client.uaclient.write(params)
                assert result.value == ua.StatusCodes.BadNotWritable
            finally:
                await client.disconnect()
            async with connection(server, "twin", "op-pass") as twin:
                await twin.write("feed_override_pct", 80.0)
            assert machine.commands == [("feed_override_pct", 80.0)]

    run(body)


def test_wrong_password_unknown_user_and_refused_anonymous() -> None:
    async def body() -> None:
        async with OpcUaMachineServer(FakeMachine(), users=users(anonymous=None)) as server:
            for user, password in (("twin", "wrong"), ("nobody", "op-pass"), ("twin", "")):
                with pytest.raises(ConnectionLost, match="BadUserAccessDenied"):
                    await connection(server, user, password).connect()
            with pytest.raises(ConnectionLost, match="BadIdentityTokenRejected"):
                await connection(server, None).connect()

    run(body)


# Certificates ----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def pki(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """server, twin (trusted by the server), expired (trusted, but expired) and stranger (not
    trusted) certificates, and the server's trust folder."""
    folder = tmp_path_factory.mktemp("pki")
    certificate(folder, "server", "server")
    certificate(folder, "other-server", "server")
    twin, _ = certificate(folder, "twin", "client")
    certificate(folder, "stranger", "client")
    expired, _ = certificate(folder, "expired", "client", expired=True)
    (folder / "trusted-clients").mkdir()
    shutil.copy(twin, folder / "trusted-clients")
    shutil.copy(expired, folder / "trusted-clients")
    return folder


def secured(pki: Path, name: str = "server") -> OpcUaServerSecurity:
    return OpcUaServerSecurity(
        "SignAndEncrypt",
        pki / f"{name}-cert.pem",
        pki / f"{name}-key.pem",
        pki / "trusted-clients",
    )


def twin_config(server: OpcUaMachineServer, client: str = "twin", **security: object):
    settings = OpcUaSecurityConfig(
        policy="Basic256Sha256",
        mode="SignAndEncrypt",
        certificate=f"{client}-cert.pem",
        private_key=f"{client}-key.pem",
        username="twin",
        password="op-pass",
        **security,  # type: ignore[arg-type]
    )
    return ConnectionConfig(endpoint=server.endpoint, timeout_s=5.0, security=settings)


def test_server_refuses_a_client_certificate_not_in_its_trust_folder(pki: Path) -> None:
    async def body() -> None:
        machine = FakeMachine()
        async with OpcUaMachineServer(machine, security=secured(pki), users=users()) as server:
            pinned = {"server_certificate": "server-cert.pem"}
            async with OpcUaConnection(twin_config(server, **pinned), base_dir=pki) as twin:
                await twin.write("stop", 1.0)
            stranger = OpcUaConnection(twin_config(server, "stranger", **pinned), base_dir=pki)
            with pytest.raises(ConnectionLost, match="BadCertificateUntrusted"):
                await stranger.connect()
            expired = OpcUaConnection(twin_config(server, "expired", **pinned), base_dir=pki)
            with pytest.raises(ConnectionLost, match="BadCertificateTimeInvalid"):
                await expired.connect()
            # the same refusal for a bare asyncua client with a self-signed certificate
            client = Client(server.endpoint, timeout=5.0)
            client.application_uri = CLIENT_APPLICATION_URI
            await client.set_security(
                security_policies.SecurityPolicyBasic256Sha256,
                str(pki / "stranger-cert.pem"),
                str(pki / "stranger-key.pem"),
                server_certificate=str(pki / "server-cert.pem"),
            )
            with pytest.raises(ua.UaStatusCodeError) as refused:
                await client.connect()
            assert refused.value.code == ua.StatusCodes.BadCertificateUntrusted
            assert machine.commands == [("stop", 1.0)]

    run(body)


def test_twin_refuses_a_server_certificate_it_does_not_trust(pki: Path, tmp_path: Path) -> None:
    trusted = tmp_path / "trusted-servers"
    trusted.mkdir()
    shutil.copy(pki / "other-server-cert.pem", trusted)

    async def body() -> None:
        async with OpcUaMachineServer(
            FakeMachine(), security=secured(pki), users=users()
        ) as server:
            folder = {"trust_folder": str(trusted)}
            with pytest.raises(ConnectionLost, match="BadCertificateUntrusted"):
                await OpcUaConnection(twin_config(server, **folder), base_dir=pki).connect()
            # pinned to another server's certificate: refused too
            pinned = {"server_certificate": "other-server-cert.pem"}
            with pytest.raises(ConnectionLost):
                await OpcUaConnection(twin_config(server, **pinned), base_dir=pki).connect()
            # neither pinned nor a trust folder: a configuration error, not "accept any"
            with pytest.raises(ConfigError, match="server_certificate .* or trust_folder"):
                await OpcUaConnection(twin_config(server), base_dir=pki).connect()
            shutil.copy(pki / "server-cert.pem", trusted)
            async with OpcUaConnection(twin_config(server, **folder), base_dir=pki) as twin:
                await twin.read()

    run(body)


def test_trust_on_first_use_keeps_the_first_server_and_refuses_another(
    pki: Path, tmp_path: Path
) -> None:
    first_use = {"trust_folder": str(tmp_path), "trust_on_first_use": True}

    async def body() -> None:
        async with OpcUaMachineServer(
            FakeMachine(), security=secured(pki), users=users()
        ) as server:
            async with OpcUaConnection(twin_config(server, **first_use), base_dir=pki) as twin:
                await twin.read()
            (saved,) = tmp_path.iterdir()
            assert saved.name.startswith("first-use-")
        # another server (another certificate) at the same address: refused
        async with OpcUaMachineServer(
            FakeMachine(), port=server.port, security=secured(pki, "other-server"), users=users()
        ) as impostor:
            conn = OpcUaConnection(twin_config(impostor, **first_use), base_dir=pki)
            with pytest.raises(ConnectionLost, match="BadCertificateUntrusted"):
                await conn.connect()
        assert len(list(tmp_path.iterdir())) == 1

    run(body)
