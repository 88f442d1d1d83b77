"""Validated, typed configuration loaded from TOML (see docs/configuration.md).

An empty file is a valid configuration: every section has defaults.
"""

from cnctwin.config.base import CoordinateMm, Section, Vec3Mm, resolve_file
from cnctwin.config.loading import describe_validation_error, load_config
from cnctwin.config.machine import (
    MAX_SPINDLE_RPM,
    AxesConfig,
    AxisConfig,
    MachineConfig,
    WorkOffsets,
)
from cnctwin.config.machining import MachiningConfig
from cnctwin.config.material import MaterialConfig
from cnctwin.config.simulation import (
    MAX_CYCLE_MS,
    MAX_DENSITY_PER_MM,
    MIN_CYCLE_MS,
    MIN_DENSITY_PER_MM,
    SimulationConfig,
)
from cnctwin.config.spindle import SpeedControllerConfig, SpindleConfig, SpindleMotorConfig
from cnctwin.config.stock import BoxStock
from cnctwin.config.tools import (
    MAX_FLUTES,
    MAX_TOOL_DIAMETER_MM,
    MAX_TOOL_LENGTH_MM,
    MIN_TOOL_DIAMETER_MM,
    CutterKind,
    ToolConfig,
)

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
    "CoordinateMm",
    "Section",
    "resolve_file",
    "describe_validation_error",
    "MAX_SPINDLE_RPM",
    "MAX_CYCLE_MS",
    "MAX_DENSITY_PER_MM",
    "MIN_CYCLE_MS",
    "MIN_DENSITY_PER_MM",
    "CutterKind",
    "MAX_FLUTES",
    "MAX_TOOL_DIAMETER_MM",
    "MAX_TOOL_LENGTH_MM",
    "MIN_TOOL_DIAMETER_MM",
]
