"""The virtual machine: a physics-consistent simulated CNC that runs NC programs.

Public API::

    from cnctwin.virtual import MachineClock, VirtualMachine, VirtualMachineConfig

    vm = VirtualMachine(VirtualMachineConfig())    # the packaged demo program and machine
    vm.command("feed_override_pct", 80.0)           # applied at once, read back
    while not vm.finished:
        vm.step(vm.tick_s)
    vm.snapshot()                                   # every signal of cnctwin.thread.SIGNALS

    async with MachineClock(vm, vm.tick_s, speed=1.0) as clock:   # real time, in asyncio
        ...

    log = read_replay_log("run.csv", load_replay_map("map.toml"))   # a recorded machine
    replay = ReplayMachine(log)                     # the same interface: step, snapshot, ...

Units: the signals' own (mm, mm/min, rpm, N, N m, A, W, %, s); see docs/virtual-machine.md.
"""

from typing import TYPE_CHECKING

from cnctwin import _lazy
from cnctwin.virtual.clock import SWITCH_S, ClockStats, MachineClock, SteppedOffLoop
from cnctwin.virtual.config import (
    AxisDriveConfig,
    ChatterFault,
    FaultConfig,
    HoleFault,
    NoiseConfig,
    ToolBreakageFault,
    VirtualMachineConfig,
    WearFault,
)
from cnctwin.virtual.exposure import check_exposure, is_loopback
from cnctwin.virtual.faults import FaultEvent, FaultInjector, blank_with_holes
from cnctwin.virtual.machine import VirtualMachine
from cnctwin.virtual.replay import ReplayLog, ReplayMachine, read_replay_log
from cnctwin.virtual.replay_map import ReplayMap, load_replay_map
from cnctwin.virtual.users import ROLES, Role, UserTable, hash_password, load_users

if TYPE_CHECKING:
    from cnctwin.virtual.ads_server import AdsMachineServer
    from cnctwin.virtual.certificates import application_certificate
    from cnctwin.virtual.modbus_server import ModbusMachineServer
    from cnctwin.virtual.mtconnect_agent import MTConnectAgent
    from cnctwin.virtual.opcua_server import OpcUaMachineServer, OpcUaServerSecurity, SecurityMode
    from cnctwin.virtual.spawned import TRANSPORTS, virtual_machine_server

# The servers load asyncua and pymodbus, the child process multiprocessing: imported on
# first use.
_LAZY = {
    "AdsMachineServer": "ads_server",
    "application_certificate": "certificates",
    "ModbusMachineServer": "modbus_server",
    "MTConnectAgent": "mtconnect_agent",
    "OpcUaMachineServer": "opcua_server",
    "OpcUaServerSecurity": "opcua_server",
    "SecurityMode": "opcua_server",
    "TRANSPORTS": "spawned",
    "virtual_machine_server": "spawned",
}

__all__ = [
    "AdsMachineServer",
    "AxisDriveConfig",
    "ChatterFault",
    "ClockStats",
    "FaultConfig",
    "FaultEvent",
    "FaultInjector",
    "HoleFault",
    "MachineClock",
    "ModbusMachineServer",
    "MTConnectAgent",
    "NoiseConfig",
    "OpcUaMachineServer",
    "OpcUaServerSecurity",
    "ROLES",
    "ReplayLog",
    "ReplayMachine",
    "ReplayMap",
    "Role",
    "SWITCH_S",
    "SecurityMode",
    "SteppedOffLoop",
    "TRANSPORTS",
    "ToolBreakageFault",
    "UserTable",
    "VirtualMachine",
    "VirtualMachineConfig",
    "WearFault",
    "application_certificate",
    "blank_with_holes",
    "check_exposure",
    "hash_password",
    "is_loopback",
    "load_replay_map",
    "load_users",
    "read_replay_log",
    "virtual_machine_server",
]

__getattr__, __dir__ = _lazy.exports(__name__, _LAZY)
