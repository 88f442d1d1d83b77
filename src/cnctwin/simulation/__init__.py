"""Offline simulation: an NC program cut through the stock, step by step, and the machine signals
that cut gives (engagement, forces, spindle load per step)."""

from cnctwin.simulation.cut import COLUMNS, CutStep, StepTable, simulate_cut, step_durations
from cnctwin.simulation.program import (
    ProgramCut,
    ProgramSignals,
    predict_program_signals,
    simulate_program,
)
from cnctwin.simulation.signals import (
    SIGNAL_COLUMNS,
    MachineSignals,
    StepForces,
    axial_forces,
    axial_material,
    drill_band_mm,
    immersion_intervals,
    simulate_signals,
    spindle_drive_parameters,
    step_forces,
)

__all__ = [
    "COLUMNS",
    "SIGNAL_COLUMNS",
    "CutStep",
    "MachineSignals",
    "ProgramCut",
    "ProgramSignals",
    "StepTable",
    "predict_program_signals",
    "simulate_cut",
    "simulate_program",
    "simulate_signals",
    "StepForces",
    "axial_forces",
    "axial_material",
    "drill_band_mm",
    "immersion_intervals",
    "spindle_drive_parameters",
    "step_durations",
    "step_forces",
]
