"""Parameter studies: Heide 2025's dexel density x cycle time study of the tri-dexel simulation.

Public API::

    from cnctwin.studies import DexelStudy, run_study, settings, optimum, fit_t_star

    study = DexelStudy.paper()              # Table 2: 5 densities x 8 cycle times x 6 feeds
    results = run_study(study, workers=2)   # one RunResult per run
    scored = settings(results)              # per (density, cycle time), score S (Eq. 2-3)
    best = optimum(scored)                  # least S
    choice = constrained_optimum(scored)    # least S within volume and real-time constraints

Units at this edge: mm, mm/min, s (names say so). See docs/study.md.
"""

from typing import TYPE_CHECKING

from cnctwin import _lazy
from cnctwin.studies.dexel_study import (
    PAPER,
    PAPER_CYCLES_S,
    PAPER_DENSITIES_PER_MM,
    PAPER_FEEDS_MM_MIN,
    PAPER_PROCESS_S,
    DexelStudy,
    RunResult,
    RunSpec,
    SideMillingCut,
    run_one,
)
from cnctwin.studies.runner import default_workers, estimate_wall_s, run_study
from cnctwin.studies.scaling import TStarFit, fit_t_star, t_star
from cnctwin.studies.score import (
    AE_RESOLUTION_MM,
    FEED_RESOLUTION_PCT,
    WEIGHTS,
    Choice,
    Constraints,
    Setting,
    constrained_optimum,
    min_max,
    optimum,
    score,
    settings,
)

if TYPE_CHECKING:
    from cnctwin.studies.report import summary_lead, write_outputs

__all__ = [
    "AE_RESOLUTION_MM",
    "FEED_RESOLUTION_PCT",
    "PAPER",
    "PAPER_CYCLES_S",
    "PAPER_DENSITIES_PER_MM",
    "PAPER_FEEDS_MM_MIN",
    "PAPER_PROCESS_S",
    "WEIGHTS",
    "Choice",
    "Constraints",
    "DexelStudy",
    "RunResult",
    "RunSpec",
    "SideMillingCut",
    "Setting",
    "TStarFit",
    "constrained_optimum",
    "default_workers",
    "estimate_wall_s",
    "fit_t_star",
    "min_max",
    "optimum",
    "run_one",
    "run_study",
    "score",
    "settings",
    "summary_lead",
    "t_star",
    "write_outputs",
]

# The outputs draw their heat maps with matplotlib: imported on first use.
__getattr__, __dir__ = _lazy.exports(
    __name__, {"summary_lead": "report", "write_outputs": "report"}
)
