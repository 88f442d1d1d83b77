"""The report of ``cnctwin study dexel``: heat maps over dexel density x cycle time.

The maps are those of the PNG outputs (:mod:`cnctwin.studies.plots`, after Heide 2025,
Fig. 8-10), interactive: hover a cell for its value. Error maps are coloured by the decimal
logarithm of the value (floored at its resolution, :mod:`cnctwin.studies.score`), as the
values span decades.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cnctwin.report.document import Report
from cnctwin.studies import (
    AE_RESOLUTION_MM,
    FEED_RESOLUTION_PCT,
    PAPER,
    DexelStudy,
    RunResult,
    settings,
    summary_lead,
)

if TYPE_CHECKING:
    import plotly.graph_objects as go

__all__ = ["dexel_study_report"]


def _heatmap(
    study: DexelStudy, values: np.ndarray, title: str, unit: str, floor: float | None
) -> go.Figure:
    """Density (rows) x cycle time (columns) map; log colours from ``floor`` when given."""
    import plotly.graph_objects as go

    colour = np.log10(np.maximum(values, floor)) if floor is not None else values
    text = [[f"{v:.3g}" for v in row] for row in values]
    figure = go.Figure(
        go.Heatmap(
            x=[f"{c * 1e3:g}" for c in study.cycles_s],
            y=[f"{d:g}" for d in study.densities_per_mm],
            z=colour,
            text=text,
            texttemplate="%{text}",
            hovertemplate="cycle %{x} ms, density %{y} /mm: %{text} " + unit + "<extra></extra>",
            colorscale="RdBu_r" if floor is not None else "Viridis",
            colorbar={"title": {"text": f"log10({unit})" if floor is not None else unit}},
        )
    )
    figure.update_layout(
        title=title,
        xaxis={"title": "cycle time [ms]", "type": "category"},
        yaxis={"title": "dexel density [1/mm]", "type": "category"},
    )
    return figure


def dexel_study_report(
    path: Path,
    result: Mapping[str, Any],
    study: DexelStudy,
    results: Sequence[RunResult],
) -> Path:
    """Write the dexel study's report.

    Parameters
    ----------
    path
        The HTML file.
    result
        The study's summary (``cnctwin study dexel --json``).
    study
        The study.
    results
        Its runs.
    """
    runs = {(r.spec.density_per_mm, r.spec.cycle_s, r.spec.feed_mm_min): r for r in results}
    by_setting = {(s.density_per_mm, s.cycle_s): s for s in settings(results)}

    def grid(value: Callable[[float, float], float]) -> np.ndarray:
        return np.array(
            [[value(rho, cycle) for cycle in study.cycles_s] for rho in study.densities_per_mm]
        )

    report = Report(
        "Dexel study: density x cycle time (Heide 2025)",
        f"cnctwin study dexel: {result['study']['runs']} runs. "
        + " ".join(summary_lead(dict(result)))
        + f" (Heide 2025: {PAPER['density_per_mm']:g} /mm, {PAPER['cycle_s'] * 1e3:g} ms.)",
        result,
    )
    report.section(
        "Score S per setting (Heide 2025, Eq. 3)",
        "S = 0.4 ae* + 0.4 vf* + 0.2 T*, each metric min-max normalised over the settings; "
        "the optimum is the least S among the settings that meet the constraints.",
    )
    report.figure(
        _heatmap(study, grid(lambda r, c: by_setting[(r, c)].score), "score S", "S", None)
    )
    report.section("CPU time per setting", "All feeds of a setting together.")
    report.figure(
        _heatmap(study, grid(lambda r, c: by_setting[(r, c)].cpu_s), "CPU time", "s", None)
    )
    for feed in study.feeds_mm_min:
        report.section(f"Feed {feed:g} mm/min")
        report.figure(
            _heatmap(
                study,
                grid(lambda r, c, f=feed: runs[(r, c, f)].delta_ae_mm * 1e3),
                f"mean |delta ae|, vf = {feed:g} mm/min",
                "um",
                AE_RESOLUTION_MM * 1e3,
            )
        )
        report.figure(
            _heatmap(
                study,
                grid(lambda r, c, f=feed: runs[(r, c, f)].feed_deviation_pct),
                f"mean feed deviation, vf = {feed:g} mm/min",
                "%",
                FEED_RESOLUTION_PCT,
            )
        )
    return report.write(path)
