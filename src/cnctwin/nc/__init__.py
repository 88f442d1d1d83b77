"""NC programs: interpretation to motion segments, traces, and trajectory sampling.

Public API::

    from cnctwin.nc import Interpreter, NCSetup, TrajectorySampler

    interp = Interpreter(NCSetup(tools=...))
    for segment in interp.run_file("part.ngc"):   # lazy, constant memory
        ...

Lengths are in mm, feeds in mm/min, spindle speeds in rpm (names say so).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from cnctwin import _lazy
from cnctwin.nc import compiled as _compiled
from cnctwin.nc.compiled import compiled_modules

_compiled.prepare_imports()  # before any compiled module is imported

if TYPE_CHECKING:  # the names as type checkers see them; imported lazily at run time
    from cnctwin.nc.interpreter import Interpreter, interpret_file, interpret_text
    from cnctwin.nc.limits import MAX_PROGRAM_BYTES, MAX_REPEATED_LINES, MAX_SEGMENTS
    from cnctwin.nc.plot import ToolpathPlot, draw_top_view
    from cnctwin.nc.runs import MoveRun
    from cnctwin.nc.sampler import (
        AxisLimits,
        FeedOverride,
        SampleChunk,
        TrajectorySampler,
        sample_program,
    )
    from cnctwin.nc.segments import (
        PLANE_AXES,
        CutterComp,
        FeedMode,
        MachineState,
        MotionKind,
        Plane,
        Segment,
        arc_sweep_rad,
        segment_length_mm,
    )
    from cnctwin.nc.setup import DEFAULT_RAPID_MM_MIN, NCSetup, ToolEntry
    from cnctwin.nc.summary import summarize
    from cnctwin.nc.tool_table import read_tool_table
    from cnctwin.nc.trace import CanonicalMove, canonical_moves, format_trace, trace_text

#: Where each public name lives. Imported on first use, so that importing one submodule
#: (the command line reads programs without sampling them) does not import numpy and numba.
_HOMES = {
    "DEFAULT_RAPID_MM_MIN": "setup",
    "MAX_PROGRAM_BYTES": "limits",
    "MAX_REPEATED_LINES": "limits",
    "MAX_SEGMENTS": "limits",
    "AxisLimits": "sampler",
    "CanonicalMove": "trace",
    "CutterComp": "segments",
    "FeedMode": "segments",
    "FeedOverride": "sampler",
    "Interpreter": "interpreter",
    "MachineState": "segments",
    "MotionKind": "segments",
    "MoveRun": "runs",
    "NCSetup": "setup",
    "PLANE_AXES": "segments",
    "Plane": "segments",
    "SampleChunk": "sampler",
    "Segment": "segments",
    "ToolEntry": "setup",
    "ToolpathPlot": "plot",
    "TrajectorySampler": "sampler",
    "arc_sweep_rad": "segments",
    "canonical_moves": "trace",
    "draw_top_view": "plot",
    "format_trace": "trace",
    "interpret_file": "interpreter",
    "interpret_text": "interpreter",
    "read_tool_table": "tool_table",
    "sample_program": "sampler",
    "segment_length_mm": "segments",
    "summarize": "summary",
    "trace_text": "trace",
}

_resolve, __dir__ = _lazy.exports(__name__, _HOMES)


def __getattr__(name: str) -> Any:
    """A public name, imported on first use; a compiled class gets its docstring back."""
    value = _resolve(name)
    _compiled.keep_docstring(value)
    return value


__all__ = [
    "DEFAULT_RAPID_MM_MIN",
    "MAX_PROGRAM_BYTES",
    "MAX_REPEATED_LINES",
    "MAX_SEGMENTS",
    "PLANE_AXES",
    "AxisLimits",
    "CanonicalMove",
    "CutterComp",
    "FeedMode",
    "FeedOverride",
    "Interpreter",
    "MachineState",
    "MotionKind",
    "MoveRun",
    "NCSetup",
    "Plane",
    "SampleChunk",
    "Segment",
    "ToolEntry",
    "ToolpathPlot",
    "TrajectorySampler",
    "arc_sweep_rad",
    "canonical_moves",
    "compiled_modules",
    "draw_top_view",
    "format_trace",
    "interpret_file",
    "interpret_text",
    "read_tool_table",
    "sample_program",
    "segment_length_mm",
    "summarize",
    "trace_text",
]
