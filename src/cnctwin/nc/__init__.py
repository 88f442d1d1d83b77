"""NC programs: interpretation to motion segments, traces, and trajectory sampling.

Public API::

    from cnctwin.nc import Interpreter, NCSetup, TrajectorySampler

    interp = Interpreter(NCSetup(tools=...))
    for segment in interp.run_file("part.ngc"):   # lazy, constant memory
        ...

Lengths are in mm, feeds in mm/min, spindle speeds in rpm (names say so).
"""

from cnctwin.nc.interpreter import Interpreter, interpret_file, interpret_text
from cnctwin.nc.sampler import (
    AxisLimits,
    FeedOverride,
    SampleChunk,
    TrajectorySampler,
    sample_program,
)
from cnctwin.nc.segments import (
    CutterComp,
    FeedMode,
    MachineState,
    MotionKind,
    Plane,
    Segment,
    arc_sweep_rad,
    segment_length_mm,
)
from cnctwin.nc.setup import NCSetup, ToolEntry
from cnctwin.nc.trace import CanonicalMove, canonical_moves, format_trace

__all__ = [
    "AxisLimits",
    "CanonicalMove",
    "CutterComp",
    "FeedMode",
    "FeedOverride",
    "Interpreter",
    "MachineState",
    "MotionKind",
    "NCSetup",
    "Plane",
    "SampleChunk",
    "Segment",
    "ToolEntry",
    "TrajectorySampler",
    "arc_sweep_rad",
    "canonical_moves",
    "format_trace",
    "interpret_file",
    "interpret_text",
    "sample_program",
    "segment_length_mm",
]
