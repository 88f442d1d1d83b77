"""The offline process twin: an NC program run through the stock (engagement per step)."""

from cnctwin.process.signals import SIGNAL_COLUMNS, MachineSignals, simulate_signals
from cnctwin.process.simulation import COLUMNS, CutStep, StepTable, simulate_cut

__all__ = [
    "COLUMNS",
    "SIGNAL_COLUMNS",
    "CutStep",
    "MachineSignals",
    "StepTable",
    "simulate_cut",
    "simulate_signals",
]
