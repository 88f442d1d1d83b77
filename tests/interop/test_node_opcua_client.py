"""cnctwin's virtual machine server read by node-opcua's client (an independent implementation).

The server runs with the OPC 40501 Machine Tools model (as ``cnctwin virtual serve`` does);
tests/interop/read_virtual_machine.js browses ``Objects/Machines/MachineTool`` and reports the
TypeDefinition of each object, which must be the node ids of the Machine Tools specification's
NodeIds.csv (OPC Foundation UA-Nodeset, MachineTool 1.01.1), and the values, which must be the
machine's, in the model's variables and in cnctwin's own tree alike.
"""

from __future__ import annotations

import asyncio
import json
from pathlib import Path

from node_opcua import HERE, require_node_opcua
from opcua_fixtures import FakeMachine
from timeouts import BODY_S

from cnctwin.thread.signals import RunState
from cnctwin.virtual.opcua_server import OpcUaMachineServer
from cnctwin.virtual.users import UserTable

MT = "nsu=http://opcfoundation.org/UA/MachineTool/;i="
#: Object -> numeric id of its type in the specification's NodeIds.csv.
EXPECTED_TYPES = {
    "": 13,  # MachineToolType
    "Identification": 11,  # MachineToolIdentificationType
    "Monitoring": 14,  # MonitoringType
    "Monitoring/MachineTool": 26,  # MachineOperationMonitoringType
    "Monitoring/Spindle": 22,  # SpindleMonitoringType
    "Monitoring/Channel1": 16,  # ChannelMonitoringType
    "Production": 21,  # ProductionType
    "Production/ActiveProgram": 32,  # ProductionActiveProgramType
    "Equipment": 12,  # EquipmentType
    "Notification": 7,  # NotificationType
}

#: Reads of read_virtual_machine.js the lean path answers: the Value of cnctwin's own nodes.
LEAN_READS = [
    "Machine.Monitoring.Channel1.FeedOverride",
    "Machine.Monitoring.Spindle1.Override",
    "Machine.Monitoring.Spindle1.ActSpeed",
    "Machine.Monitoring.Channel1.ChannelState",
]


def test_node_opcua_browses_the_machine_tool_object_and_reads_live_values(
    node_pki: Path,
) -> None:
    node = require_node_opcua()
    machine = FakeMachine()
    machine.values.update(
        feed_override_pct=80.0,
        spindle_override_pct=110.0,
        spindle_rpm=5000.0,
        run_state=float(RunState.FEED_HOLD),
    )

    async def main() -> dict:
        server = OpcUaMachineServer(
            machine, users=UserTable(anonymous="read-only"), machine_tool_model=True
        )
        async with server:
            child = await asyncio.create_subprocess_exec(
                node,
                str(HERE / "read_virtual_machine.js"),
                server.endpoint,
                str(node_pki),
                stdout=asyncio.subprocess.PIPE,
                stderr=asyncio.subprocess.PIPE,
            )
            try:
                out, err = await asyncio.wait_for(child.communicate(), BODY_S)
            finally:
                if child.returncode is None:
                    child.kill()
                    await child.wait()
            assert child.returncode == 0, err.decode()[-2000:]
            # node-opcua checks sequence numbers strictly: its one-value reads of cnctwin's
            # nodes were answered and framed by the lean path (frame_message), between
            # answers framed by asyncua on the same channel
            service = server._server.service  # type: ignore[union-attr]
            assert service is not None and service.answered >= len(LEAN_READS)
            # the report is the one JSON line (node-opcua logs its own lines too)
            (line,) = [x for x in out.decode().splitlines() if x.startswith('{"types"')]
            return json.loads(line)

    found = asyncio.run(main())
    assert found["types"] == {k: f"{MT}{v}" for k, v in EXPECTED_TYPES.items()}
    assert any(name.endswith("MachineTool") for name in found["machines"]), found["machines"]
    values, types = found["values"], found["datatypes"]
    # the model's variables hold the machine's values, the same as cnctwin's own nodes
    assert values["Monitoring/Channel1/FeedOverride"] == 80.0
    assert values["cnctwin:Machine.Monitoring.Channel1.FeedOverride"] == 80.0
    assert values["Monitoring/Spindle/Override"] == 110.0
    assert values["cnctwin:Machine.Monitoring.Spindle1.Override"] == 110.0
    assert values["Monitoring/Spindle/IsRotating"] is True
    assert values["Monitoring/Channel1/ChannelState"] == 1  # Interrupted: the feed hold
    assert values["cnctwin:Machine.Monitoring.Channel1.ChannelState"] == int(RunState.FEED_HOLD)
    assert values["Monitoring/MachineTool/OperationMode"] == 1  # Automatic
    assert types["Monitoring/Channel1/FeedOverride"] == "nsu=http://opcfoundation.org/UA/;i=11"
    assert types["cnctwin:Machine.Monitoring.Spindle1.ActSpeed"] == (
        "nsu=http://opcfoundation.org/UA/;i=11"
    )
    assert types["Monitoring/Spindle/IsRotating"] == "nsu=http://opcfoundation.org/UA/;i=1"
    assert types["Monitoring/Channel1/ChannelState"] == f"{MT}64"  # the ChannelState enum
