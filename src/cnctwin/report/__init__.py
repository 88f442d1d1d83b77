"""Self-contained HTML reports with interactive plots, opened by any browser offline.

``--report OUT.html`` on ``cnctwin simulate``, ``cnctwin study dexel``, ``cnctwin stability
lobes|roadmap`` and ``cnctwin wear ekf`` writes one file holding plotly.js (from the installed
``plotly`` package), the plots of what the command computed and its ``--json`` result
(docs/reports.md). Each module imports plotly only when a report is written.
"""

from typing import TYPE_CHECKING

from cnctwin import _lazy
from cnctwin.report.document import Report, check_report_path
from cnctwin.report.downsample import MAX_BUCKETS, Downsampled, minmax_buckets

if TYPE_CHECKING:
    from cnctwin.report.simulation import simulation_report
    from cnctwin.report.stability import lobes_report, roadmap_report
    from cnctwin.report.study import dexel_study_report
    from cnctwin.report.wear import wear_ekf_report

# Each report imports the physics it draws (the dexel stock, the study, the wear twins):
# imported on first use, so that the run browser's downsampling stays light.
_LAZY = {
    "dexel_study_report": "study",
    "lobes_report": "stability",
    "roadmap_report": "stability",
    "simulation_report": "simulation",
    "wear_ekf_report": "wear",
}

__all__ = [
    "MAX_BUCKETS",
    "Downsampled",
    "Report",
    "check_report_path",
    "dexel_study_report",
    "lobes_report",
    "minmax_buckets",
    "roadmap_report",
    "simulation_report",
    "wear_ekf_report",
]

__getattr__, __dir__ = _lazy.exports(__name__, _LAZY)
