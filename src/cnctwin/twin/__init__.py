"""The running twin: the twin cycle (docs/twin.md) against a machine connection.

Public API::

    from cnctwin.twin import RunConfig, load_run_config, run_session

    config = load_run_config("twin.toml")       # physics + [connection] [twin] [[rules]] ...
    summary = asyncio.run(run_session(config, historian=Historian.open("h.sqlite")))

:func:`build_twin` assembles the stages for a connection of your own (e.g. a
:class:`LocalConnection` to an in-process :class:`~cnctwin.virtual.VirtualMachine`);
:class:`MachineServer` and :class:`MachineProcess` serve a virtual machine on loopback.
See docs/twin.md.
"""

from cnctwin.twin.adaptive_feed import AdaptiveFeedConfig
from cnctwin.twin.config import RunConfig, load_run_config
from cnctwin.twin.host import MachineProcess, MachineServer
from cnctwin.twin.local import LocalConnection
from cnctwin.twin.mirs import MirsConfig
from cnctwin.twin.model_stage import ModelStage, load_models
from cnctwin.twin.monitoring import BandResult, ForceBand
from cnctwin.twin.physics import TwinPhysics
from cnctwin.twin.pipeline import Twin, build_twin, signal_names
from cnctwin.twin.roughness import RoughnessConfig
from cnctwin.twin.runtime import RunSummary, TwinRuntime
from cnctwin.twin.session import open_connection, run_session
from cnctwin.twin.settings import (
    ForceBandConfig,
    FormErrorConfig,
    ModelConfig,
    TwinSettings,
    WearConfig,
)
from cnctwin.twin.state import CycleState, TwinEvent
from cnctwin.twin.tool_offset import (
    OFFSET_AXES,
    OffsetWrite,
    apply_correction,
    write_tool_offset,
)

__all__ = [
    "AdaptiveFeedConfig",
    "OFFSET_AXES",
    "BandResult",
    "CycleState",
    "ForceBand",
    "ForceBandConfig",
    "FormErrorConfig",
    "LocalConnection",
    "MachineProcess",
    "MachineServer",
    "MirsConfig",
    "ModelConfig",
    "ModelStage",
    "OffsetWrite",
    "RoughnessConfig",
    "RunConfig",
    "RunSummary",
    "Twin",
    "TwinEvent",
    "TwinPhysics",
    "TwinRuntime",
    "TwinSettings",
    "WearConfig",
    "apply_correction",
    "build_twin",
    "load_models",
    "load_run_config",
    "open_connection",
    "run_session",
    "signal_names",
    "write_tool_offset",
]
