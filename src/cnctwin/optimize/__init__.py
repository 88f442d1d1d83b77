"""The optimised NC program: feeds (and speeds) per block from force, power, chip-thickness and
stability limits, the program rewritten in its own dialect; the feed and speed that keep the
elastic residual stress within a limit (:func:`search_feed_speed`).

Public API::

    from cnctwin.optimize import FeedLimits, optimize_program, scheduled_speeds

    result = optimize_program(text, "part.ngc", config, FeedLimits(max_force_n=300.0),
                              coefficients=..., density_per_mm=10.0, cycle_s=0.0125)
    result.text            # the rewritten program
    result.summary()       # cycle time before and after, the limit of every block

Units: mm, mm/min, rpm, N, W, s (names say so). See docs/optimize.md.
"""

from cnctwin.optimize.loads import FORCE_METRICS, FeedLimits, ProgramLoads, force_feed_limit
from cnctwin.optimize.program import (
    FEED_STEP,
    MARGIN_MM,
    MIN_PIECE_MM,
    BlockPlan,
    OptimizedProgram,
    optimize_program,
    scheduled_speeds,
)
from cnctwin.optimize.residual_stress import MillingMirs, MirsSearch, search_feed_speed

__all__ = [
    "FEED_STEP",
    "FORCE_METRICS",
    "MARGIN_MM",
    "MIN_PIECE_MM",
    "BlockPlan",
    "FeedLimits",
    "MillingMirs",
    "MirsSearch",
    "OptimizedProgram",
    "ProgramLoads",
    "force_feed_limit",
    "optimize_program",
    "search_feed_speed",
    "scheduled_speeds",
]
