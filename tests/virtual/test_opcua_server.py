"""The virtual machine's OPC UA server, seen from a plain asyncua client (the other side).

Each test starts a real server on a free loopback port and talks to it with asyncua's own
client, not with cnctwin's connection, so the node map, data types, access levels and the
write path are checked against the protocol rather than against our client.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Iterator
from typing import Any

import pytest
from asyncua import Client, ua
from opcua_fixtures import FakeMachine, Shared

from cnctwin.errors import ConfigError
from cnctwin.thread.opcua import NAMESPACE_URI, NODE_MAP
from cnctwin.thread.signals import COMMANDS, SIGNALS
from cnctwin.virtual.opcua_server import OpcUaMachineServer


@pytest.fixture(scope="module")
def shared() -> Iterator[Shared]:
    server = Shared(FakeMachine(quantised=True))
    yield server
    server.close()


async def _client(server: Shared) -> Client:
    client = Client(server.endpoint, timeout=5.0)
    await client.connect()
    return client


def test_address_space_follows_the_node_map(shared: Shared) -> None:
    async def body(server: Shared, machine: FakeMachine) -> None:
        client = await _client(server)
        try:
            ns = await client.get_namespace_index(NAMESPACE_URI)
            # The browse path of the Machine Tools layout leads to the documented NodeId.
            node = await client.nodes.objects.get_child(
                [f"{ns}:Machines", f"{ns}:Machine", f"{ns}:Monitoring", f"{ns}:Axes"]
                + [f"{ns}:X", f"{ns}:ActPos"]
            )
            assert node.nodeid == ua.NodeId(NODE_MAP["x_mm"], ns)
            ident = client.get_node(ua.NodeId("Machine.Identification.Manufacturer", ns))
            assert await ident.read_value() == "cnctwin"
            expected_type = {"float": "Double", "int": "Int32", "bool": "Boolean"}
            for name, identifier in NODE_MAP.items():
                var = client.get_node(ua.NodeId(identifier, ns))
                dtype = await var.read_data_type_as_variant_type()
                assert dtype.name == expected_type[SIGNALS[name].kind], name
                access = await var.get_access_level()
                assert (ua.AccessLevel.CurrentWrite in access) == (name in COMMANDS), name
                # Server-side value == client-side value, every signal.
                assert await var.read_value() == pytest.approx(machine.values[name]), name
        finally:
            await client.disconnect()

    shared.run(body)


def test_publish_updates_values_and_subscriptions(shared: Shared) -> None:
    async def body(server: Shared, machine: FakeMachine) -> None:
        client = await _client(server)
        changes: list[Any] = []

        class Handler:
            def datachange_notification(self, node: Any, value: Any, data: Any) -> None:
                changes.append(value)

        try:
            ns = await client.get_namespace_index(NAMESPACE_URI)
            var = client.get_node(ua.NodeId(NODE_MAP["spindle_rpm"], ns))
            sub = await client.create_subscription(10, Handler())
            await sub.subscribe_data_change(var)
            machine.values["spindle_rpm"] = 8123.5
            machine.values["heartbeat"] = 77.0
            server.publish()
            assert await var.read_value() == 8123.5
            beat = client.get_node(ua.NodeId(NODE_MAP["heartbeat"], ns))
            assert await beat.read_value() == 77
            for _ in range(200):
                if 8123.5 in changes:
                    break
                await asyncio.sleep(0.01)
            assert 8123.5 in changes
        finally:
            await client.disconnect()

    shared.run(body)


async def _write(client: Client, ns: int, name: str, variant: ua.Variant) -> ua.StatusCode:
    params = ua.WriteParameters()
    params.NodesToWrite = [
        ua.WriteValue(
            NodeId=ua.NodeId(NODE_MAP[name], ns),
            AttributeId=ua.AttributeIds.Value,
            Value=ua.DataValue(Value=variant),
        )
    ]
    (status,) = await client.uaclient.write(params)
    return status


def test_command_write_applies_through_the_machine_with_read_back(shared: Shared) -> None:
    async def body(server: Shared, machine: FakeMachine) -> None:
        client = await _client(server)
        try:
            ns = await client.get_namespace_index(NAMESPACE_URI)
            double = ua.VariantType.Double
            status = await _write(client, ns, "feed_override_pct", ua.Variant(80.4, double))
            assert status.is_good()
            assert machine.commands == [("feed_override_pct", 80.4)]
            node = client.get_node(ua.NodeId(NODE_MAP["feed_override_pct"], ns))
            assert await node.read_value() == 80.0  # the machine's read-back, not 80.4
            status = await _write(client, ns, "stop", ua.Variant(True, ua.VariantType.Boolean))
            assert status.is_good()
            stop = client.get_node(ua.NodeId(NODE_MAP["stop"], ns))
            assert await stop.read_value() is True
            wear = await _write(client, ns, "tool_radius_wear_mm", ua.Variant(-0.02, double))
            assert wear.is_good()
            assert machine.values["tool_radius_wear_mm"] == -0.02
        finally:
            await client.disconnect()

    shared.run(body)


_INVALID = [
    ("feed_override_pct", ua.Variant(300.0, ua.VariantType.Double), "BadOutOfRange"),
    ("feed_override_pct", ua.Variant(-1.0, ua.VariantType.Double), "BadOutOfRange"),
    ("feed_override_pct", ua.Variant(math.nan, ua.VariantType.Double), "BadOutOfRange"),
    ("spindle_override_pct", ua.Variant(math.inf, ua.VariantType.Double), "BadOutOfRange"),
    ("spindle_override_pct", ua.Variant(40.0, ua.VariantType.Double), "BadOutOfRange"),
    ("tool_length_wear_mm", ua.Variant(5.0, ua.VariantType.Double), "BadOutOfRange"),
    ("feed_override_pct", ua.Variant("fast", ua.VariantType.String), "BadTypeMismatch"),
    ("feed_hold", ua.Variant(b"\x01", ua.VariantType.ByteString), "BadTypeMismatch"),
    ("feed_override_pct", ua.Variant(True, ua.VariantType.Boolean), "BadTypeMismatch"),
    ("feed_hold", ua.Variant(0.5, ua.VariantType.Double), "BadOutOfRange"),
    ("x_mm", ua.Variant(1.0, ua.VariantType.Double), "BadNotWritable"),
    ("heartbeat", ua.Variant(1, ua.VariantType.Int32), "BadNotWritable"),
]


def test_invalid_writes_are_rejected_and_the_server_goes_on(shared: Shared) -> None:
    async def body(server: Shared, machine: FakeMachine) -> None:
        client = await _client(server)
        try:
            ns = await client.get_namespace_index(NAMESPACE_URI)
            before = machine.snapshot()
            for name, variant, expected in _INVALID:
                status = await _write(client, ns, name, variant)
                assert status.name == expected, (name, variant)
                node = client.get_node(ua.NodeId(NODE_MAP[name], ns))
                assert await node.read_value() == pytest.approx(before[name])
            assert machine.commands == []
            # ... and a valid write still goes through afterwards.
            ok = await _write(client, ns, "feed_override_pct", ua.Variant(55.0))
            assert ok.is_good() and machine.commands == [("feed_override_pct", 55.0)]
        finally:
            await client.disconnect()

    shared.run(body)


def test_write_the_machine_refuses_is_bad_and_leaves_the_latch(shared: Shared) -> None:
    async def body(server: Shared, machine: FakeMachine) -> None:
        client = await _client(server)
        try:
            ns = await client.get_namespace_index(NAMESPACE_URI)
            boolean = ua.VariantType.Boolean
            assert (await _write(client, ns, "stop", ua.Variant(True, boolean))).is_good()
            status = await _write(client, ns, "stop", ua.Variant(False, boolean))
            assert status.name == "BadOutOfRange"
            node = client.get_node(ua.NodeId(NODE_MAP["stop"], ns))
            assert await node.read_value() is True
        finally:
            await client.disconnect()

    shared.run(body)


def test_non_finite_integer_signal_is_published_with_bad_status(shared: Shared) -> None:
    async def body(server: Shared, machine: FakeMachine) -> None:
        client = await _client(server)
        try:
            ns = await client.get_namespace_index(NAMESPACE_URI)
            machine.values["program_line"] = math.nan
            machine.values["force_x_n"] = math.nan
            server.publish()
            params = ua.ReadParameters()
            params.NodesToRead = [
                ua.ReadValueId(NodeId=ua.NodeId(NODE_MAP[n], ns), AttributeId=ua.AttributeIds.Value)
                for n in ("program_line", "force_x_n")
            ]
            line, force = await client.uaclient.read(params)
            assert line.StatusCode.name == "BadOutOfRange"
            assert force.StatusCode.is_good() and math.isnan(force.Value.Value)
        finally:
            await client.disconnect()

    shared.run(body)


def test_security_mode_without_certificate_is_a_config_error() -> None:
    from cnctwin.virtual.opcua_server import OpcUaServerSecurity

    with pytest.raises(ConfigError, match="certificate"):
        OpcUaMachineServer(FakeMachine(), security=OpcUaServerSecurity(mode="Sign"))
