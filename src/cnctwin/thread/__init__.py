"""The digital thread: one :class:`MachineConnection` interface over industrial protocols.

The transports (:class:`OpcUaConnection`, :class:`ModbusConnection`) load asyncua and pymodbus;
they are imported on first use so that the signal catalogue and the connection interface stay
light for the modules that only need those.
"""

from typing import TYPE_CHECKING, Any

from cnctwin.thread.connection import (
    Backoff,
    CommandRejected,
    ConnectionLost,
    ConnectionState,
    MachineConnection,
    Reading,
)
from cnctwin.thread.signals import COMMANDS, SIGNALS, RunState, SignalSpec

if TYPE_CHECKING:
    from cnctwin.thread.modbus import ModbusConnection
    from cnctwin.thread.opcua import OpcUaConnection

_LAZY = {"ModbusConnection": "cnctwin.thread.modbus", "OpcUaConnection": "cnctwin.thread.opcua"}

__all__ = [
    "COMMANDS",
    "SIGNALS",
    "Backoff",
    "CommandRejected",
    "ConnectionLost",
    "ConnectionState",
    "MachineConnection",
    "ModbusConnection",
    "OpcUaConnection",
    "Reading",
    "RunState",
    "SignalSpec",
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
