"""Validated, typed configuration loaded from TOML (see docs/configuration.md).

An empty file is a valid configuration: every section has defaults.
"""

from cnctwin.config.base import Vec3Mm
from cnctwin.config.loading import load_config
from cnctwin.config.machine import AxesConfig, AxisConfig, MachineConfig, WorkOffsets
from cnctwin.config.machining import MachiningConfig
from cnctwin.config.material import MaterialConfig
from cnctwin.config.simulation import SimulationConfig
from cnctwin.config.spindle import SpeedControllerConfig, SpindleConfig, SpindleMotorConfig
from cnctwin.config.stock import BoxStock
from cnctwin.config.tools import ToolConfig

__all__ = [
    "AxesConfig",
    "AxisConfig",
    "BoxStock",
    "MachineConfig",
    "MaterialConfig",
    "SimulationConfig",
    "SpeedControllerConfig",
    "SpindleConfig",
    "SpindleMotorConfig",
    "ToolConfig",
    "MachiningConfig",
    "Vec3Mm",
    "WorkOffsets",
    "load_config",
]
