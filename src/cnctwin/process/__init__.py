"""The offline process twin: an NC program run through the stock (engagement per step)."""

from cnctwin.process.simulation import COLUMNS, CutStep, StepTable, simulate_cut

__all__ = ["COLUMNS", "CutStep", "StepTable", "simulate_cut"]
