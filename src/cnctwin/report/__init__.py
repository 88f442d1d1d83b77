"""Self-contained HTML reports with interactive plots, opened by any browser offline.

``--report OUT.html`` on ``cnctwin simulate``, ``cnctwin study dexel``, ``cnctwin stability
lobes|roadmap`` and ``cnctwin wear ekf`` writes one file holding plotly.js (from the installed
``plotly`` package), the plots of what the command computed and its ``--json`` result
(docs/reports.md). Each module imports plotly only when a report is written.
"""

from cnctwin.report.document import Report, check_report_path
from cnctwin.report.downsample import Downsampled, minmax_buckets

__all__ = ["Downsampled", "Report", "check_report_path", "minmax_buckets"]
