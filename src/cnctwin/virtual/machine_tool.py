"""The OPC UA for Machine Tools information model (OPC 40501-1) in the virtual machine's server.

:func:`add_machine_tool` imports the OPC Foundation's NodeSet2 files shipped in
``cnctwin/virtual/nodesets`` (DI, Machinery, IA, Machine Tools; their README gives versions and
license) and instantiates ``Objects/Machines/MachineTool``, an object of ``MachineToolType``
(``nsu=http://opcfoundation.org/UA/MachineTool/;i=13``) with its mandatory components
(Identification, Monitoring/MachineTool, Production/ActiveProgram, Equipment, Notification)
and a ``SpindleMonitoringType`` ``Spindle`` and a ``ChannelMonitoringType`` ``Channel1``
under Monitoring. Their variables hold the machine's live values: the server's
:meth:`~cnctwin.virtual.opcua_server.OpcUaMachineServer.publish` writes each
:data:`MIRRORS` entry from its canonical signal. The cnctwin tree ``Objects/Machines/Machine``
(:data:`~cnctwin.thread.opcua.NODE_MAP`) stays as it is; commands go through it.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from importlib import resources
from typing import Any

from asyncua import Server, ua
from asyncua.common.instantiate_util import instantiate
from asyncua.server.address_space import AttributeValue

from cnctwin.thread import RunState

__all__ = [
    "MACHINERY_URI",
    "MACHINE_TOOL_URI",
    "MIRRORS",
    "NODESETS",
    "add_machine_tool",
    "mirror_value",
]

#: Namespace of OPC 40501-1 Machine Tools.
MACHINE_TOOL_URI = "http://opcfoundation.org/UA/MachineTool/"
#: Namespace of OPC 40001-1 Machinery (the ``Machines`` folder, ``i=1001``).
MACHINERY_URI = "http://opcfoundation.org/UA/Machinery/"
_DI_URI = "http://opcfoundation.org/UA/DI/"
#: The NodeSet2 files, in import order (each needs the ones before it).
NODESETS = (
    "Opc.Ua.Di.NodeSet2.xml",
    "Opc.Ua.Machinery.NodeSet2.xml",
    "Opc.Ua.IA.NodeSet2.xml",
    "Opc.Ua.MachineTool.NodeSet2.xml",
)

# ChannelState of OPC 40501-1 (Active 0, Interrupted 1, Reset 2) from cnctwin's RunState
_CHANNEL_STATE = {
    RunState.RUNNING: 0,
    RunState.FEED_HOLD: 1,
}
# CurrentState of the active program's ProductionProgramStateMachineType
_PROGRAM_STATE = {
    RunState.IDLE: "Initializing",
    RunState.RUNNING: "Running",
    RunState.FEED_HOLD: "Interrupted",
    RunState.STOPPED: "Aborted",
    RunState.FINISHED: "Ended",
    RunState.FAULT: "Aborted",
}


def _channel_state(value: float) -> ua.Variant:
    return ua.Variant(_CHANNEL_STATE.get(RunState(int(value)), 2), ua.VariantType.Int32)


def _program_state(value: float) -> ua.Variant:
    return ua.Variant(ua.LocalizedText(_PROGRAM_STATE[RunState(int(value))], "en"))


def _double(value: float) -> ua.Variant:
    return ua.Variant(float(value), ua.VariantType.Double)


def _rotating(value: float) -> ua.Variant:
    return ua.Variant(abs(value) > 0.0, ua.VariantType.Boolean)


#: Canonical signal -> (browse path below the MachineTool object, in the Machine Tools
#: namespace unless prefixed "0:"; value of the signal -> Variant of the model's variable).
MIRRORS: dict[str, list[tuple[tuple[str, ...], Callable[[float], ua.Variant]]]] = {
    "feed_override_pct": [(("Monitoring", "Channel1", "FeedOverride"), _double)],
    "run_state": [
        (("Monitoring", "Channel1", "ChannelState"), _channel_state),
        (("Production", "ActiveProgram", "State", "0:CurrentState"), _program_state),
    ],
    "spindle_override_pct": [(("Monitoring", "Spindle", "Override"), _double)],
    "spindle_rpm": [(("Monitoring", "Spindle", "IsRotating"), _rotating)],
}


def _path(mt: int, path: tuple[str, ...]) -> list[str]:
    """Browse names of a path, in the Machine Tools namespace unless one names its own."""
    return [p if ":" in p else f"{mt}:{p}" for p in path]


@dataclass
class _Mirror:
    """One model variable fed from a signal: its value slot and the conversion."""

    slot: AttributeValue
    convert: Callable[[float], ua.Variant]


async def add_machine_tool(
    server: Server, ns: int, identification: dict[str, str]
) -> dict[str, list[Any]]:
    """Import the NodeSets and add the MachineTool object; return its live variables.

    Parameters
    ----------
    server
        An initialised asyncua server, not yet started.
    ns
        Namespace index of the instance nodes (the virtual machine's).
    identification
        Manufacturer, Model, SerialNumber, SoftwareRevision (strings) for Identification.

    Returns
    -------
    dict
        Canonical signal -> the mirrors :meth:`publish` writes (value slots and conversions).
    """
    folder = resources.files("cnctwin.virtual") / "nodesets"
    # asyncua warns that it cannot classify DI's UpdateBehavior (an OptionSet over UInt32,
    # which no variable here uses); keep that out of the server's log
    importer = logging.getLogger("asyncua.common.xmlimporter")
    level = importer.level
    importer.setLevel(logging.ERROR)
    try:
        for name in NODESETS:
            with resources.as_file(folder / name) as path:
                await server.import_xml(str(path))
    finally:
        importer.setLevel(level)
    mt = await server.get_namespace_index(MACHINE_TOOL_URI)
    machinery = await server.get_namespace_index(MACHINERY_URI)
    machines = server.get_node(ua.NodeId(1001, machinery))
    (machine, *_) = await instantiate(
        machines,
        server.get_node(ua.NodeId(13, mt)),
        nodeid=ua.NodeId("MachineTool", ns),
        bname=ua.QualifiedName("MachineTool", ns),
        dname=ua.LocalizedText("MachineTool"),
        idx=ns,
        instantiate_optional=False,
    )
    monitoring = await machine.get_child(f"{mt}:Monitoring")
    spindle, *_ = await instantiate(
        monitoring,
        server.get_node(ua.NodeId(22, mt)),  # SpindleMonitoringType
        nodeid=ua.NodeId("MachineTool.Monitoring.Spindle", ns),
        bname=ua.QualifiedName("Spindle", mt),
        idx=ns,
        instantiate_optional=False,
    )
    await spindle.add_variable(
        ua.NodeId("MachineTool.Monitoring.Spindle.Override", ns),
        ua.QualifiedName("Override", mt),
        ua.Variant(100.0, ua.VariantType.Double),
    )
    await instantiate(
        monitoring,
        server.get_node(ua.NodeId(16, mt)),  # ChannelMonitoringType
        nodeid=ua.NodeId("MachineTool.Monitoring.Channel1", ns),
        bname=ua.QualifiedName("Channel1", mt),
        idx=ns,
        instantiate_optional=False,
    )
    constants: list[tuple[tuple[str, ...], ua.Variant]] = [
        (("Monitoring", "Spindle", "Name"), ua.Variant("S1")),
        (("Monitoring", "Channel1", "Name"), ua.Variant("Channel 1")),
        (("Monitoring", "Channel1", "ChannelMode"), ua.Variant(0, ua.VariantType.Int32)),
        (("Monitoring", "MachineTool", "OperationMode"), ua.Variant(1, ua.VariantType.Int32)),
        (("Production", "ActiveProgram", "Name"), ua.Variant("demo_twin.ngc")),
        (("Production", "ActiveProgram", "0:NumberInList"), ua.Variant(0, ua.VariantType.UInt16)),
    ]
    for path, variant in constants:
        node = await machine.get_child(_path(mt, path))
        await node.write_value(variant)
    di = await server.get_namespace_index(_DI_URI)
    ident = await machine.get_child(f"{di}:Identification")  # DI's Identification AddIn
    for label, text in identification.items():
        try:
            node = await ident.get_child(f"{di}:{label}")
        except ua.UaStatusCodeError:
            continue  # an optional property the instance does not have
        localized = await node.read_data_type_as_variant_type() == ua.VariantType.LocalizedText
        await node.write_value(ua.Variant(ua.LocalizedText(text) if localized else text))
    mirrors: dict[str, list[Any]] = {}
    aspace = server.iserver.aspace
    for signal, targets in MIRRORS.items():
        for path, convert in targets:
            node = await machine.get_child(_path(mt, path))
            slot = aspace[node.nodeid].attributes[ua.AttributeIds.Value]
            mirrors.setdefault(signal, []).append(_Mirror(slot, convert))
    return mirrors


def mirror_value(mirror: Any, value: float, stamp: ua.DateTime) -> ua.DataValue | None:
    """The DataValue of a model variable for the signal's ``value``; ``None`` if not finite."""
    if not math.isfinite(value):
        return None
    try:
        variant = mirror.convert(value)
    except (ValueError, KeyError):
        return None
    return ua.DataValue(variant, SourceTimestamp=stamp, ServerTimestamp=stamp)
