"""The reports of ``cnctwin stability lobes`` and ``cnctwin stability roadmap``."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cnctwin.report.document import Report

if TYPE_CHECKING:
    from cnctwin.dynamics import StabilityRoadmap

__all__ = ["lobes_report", "roadmap_report"]


def lobes_report(path: Path, result: Mapping[str, Any], name: str) -> Path:
    """Write the report of a lobe diagram.

    Parameters
    ----------
    path
        The HTML file.
    result
        The ``cnctwin stability lobes --json`` object: ``spindle_rpm``,
        ``critical_depth_mm`` and ``chatter_frequency_hz`` (null: stable to the search
        limit), ``bifurcation``, ``absolute_depth_mm``, ...
    name
        What the modes came from (the file's stem), for the title.
    """
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    rpm = np.asarray(result["spindle_rpm"], dtype=float)
    depth = np.array([np.nan if v is None else v for v in result["critical_depth_mm"]])
    freq = np.array([np.nan if v is None else v for v in result["chatter_frequency_hz"]])
    order = np.argsort(rpm, kind="stable")
    rpm, depth, freq = rpm[order], depth[order], freq[order]
    kinds = np.asarray(result["bifurcation"])[order]
    report = Report(
        f"Stability lobes: {name}",
        f"cnctwin stability lobes ({result['method']}, {result['operation']}): "
        f"{rpm.size} spindle speeds",
        result,
    )
    report.section(
        "Critical depth of cut and chatter frequency",
        "Cuts deeper than the critical depth chatter (shaded). A gap in the curve: stable up "
        "to the search limit.",
    )
    figure = make_subplots(rows=2, cols=1, shared_xaxes=True, row_heights=(0.7, 0.3))
    top = result["max_depth_mm"] or (
        1.5 * float(np.nanmax(depth)) if np.isfinite(depth).any() else 1.0
    )
    figure.add_trace(
        go.Scatter(
            x=rpm,
            y=np.full(rpm.size, top),
            mode="lines",
            line={"width": 0},
            showlegend=False,
            hoverinfo="skip",
        ),  # fmt: skip
        row=1,
        col=1,
    )
    figure.add_trace(
        go.Scatter(
            x=rpm,
            y=np.where(np.isnan(depth), top, depth),
            mode="lines",
            fill="tonexty",
            fillcolor="rgba(214,39,40,0.15)",
            line={"color": "black"},
            name="critical depth [mm]",
        ),  # fmt: skip
        row=1,
        col=1,
    )
    flip = kinds == "flip"
    if flip.any():
        figure.add_trace(
            go.Scatter(x=rpm[flip], y=depth[flip], mode="markers", name="period doubling (flip)"),
            row=1,
            col=1,
        )
    if result["absolute_depth_mm"] is not None:
        figure.add_hline(y=result["absolute_depth_mm"], line_dash="dash", line_color="grey",
                         annotation_text="ZOA absolute limit", row=1, col=1)  # fmt: skip
    figure.add_trace(
        go.Scatter(x=rpm, y=freq, mode="lines", name="chatter frequency [Hz]"), row=2, col=1
    )
    figure.update_yaxes(title_text="axial depth [mm]", range=[0.0, top], row=1, col=1)
    figure.update_yaxes(title_text="chatter [Hz]", row=2, col=1)
    figure.update_xaxes(title_text="spindle speed [rpm]", row=2, col=1)
    report.figure(figure, height_px=640)
    return report.write(path)


def roadmap_report(
    path: Path, result: Mapping[str, Any], roadmap: StabilityRoadmap, program: str
) -> Path:
    """Write the report of a stability roadmap (after Ward 2021, Fig. 12).

    Parameters
    ----------
    path
        The HTML file.
    result
        The ``cnctwin stability roadmap --json`` object.
    roadmap
        The roadmap it was made from (per engagement, the critical depth over the grid).
    program
        The program's name, for the title.
    """
    import plotly.graph_objects as go

    grid = np.asarray(roadmap.spindle_rpm, dtype=float)
    segments = [s for s in roadmap.segments if s.lobes >= 0]
    report = Report(
        f"Stability roadmap: {program}",
        f"cnctwin stability roadmap ({result['method']}, margin {result['margin']:g}): "
        f"{len(result['segments'])} segments, {len(result['changed_lines'])} lines change speed"
        + "".join(
            f"; T{tool} has no modes: its lines keep their speed"
            for tool in result.get("tools_without_modes", [])
        ),
        result,
    )
    report.section(
        "Speeds along the path",
        "Red: speeds that chatter at the segment's depth times the margin. Black: programmed "
        "speed; blue: scheduled speed.",
    )
    road = go.Figure()
    for seg in segments:
        critical = roadmap.lobes[seg.lobes].critical_depth_mm
        unstable = (critical < roadmap.margin * seg.ap_mm).astype(float)
        end = max(seg.end_s_mm, seg.start_s_mm + 1e-6)
        road.add_trace(
            go.Heatmap(
                x=[seg.start_s_mm, end],
                y=grid,
                z=np.column_stack([unstable, unstable]),
                colorscale=[[0, "rgba(255,255,255,0)"], [1, "rgba(214,39,40,0.6)"]],
                zmin=0,
                zmax=1,
                showscale=False,
                name=f"#{seg.lobes}",
                hoverinfo="skip",
            )  # fmt: skip
        )
    for i, seg in enumerate(segments):
        speeds = [(seg.programmed_rpm, "programmed", "p", "black", 2)]
        if seg.has_stable_speed:
            speeds.append((seg.scheduled_rpm, "scheduled", "s", "#1f77b4", 3))
        for rpm, name, group, colour, width in speeds:
            road.add_trace(
                go.Scatter(
                    x=[seg.start_s_mm, seg.end_s_mm],
                    y=[rpm] * 2,
                    mode="lines",
                    line={"color": colour, "width": width},
                    name=name,
                    legendgroup=group,
                    showlegend=i == 0,
                    hovertemplate=f"line {seg.line}: %{{y:.0f}} rpm<extra></extra>",
                )  # fmt: skip
            )
    road.update_layout(xaxis_title="path length s [mm]", yaxis_title="spindle speed [rpm]")
    report.figure(road)
    report.section(
        "Lobes per engagement",
        "#i: the i-th engagement of the JSON result; x: programmed speed and depth of each "
        "segment.",
    )
    lobes = go.Figure()
    for index in sorted({seg.lobes for seg in segments}):
        lobe = roadmap.lobes[index]
        label = (
            f"#{index}: {math.degrees(lobe.entry_rad):.0f}-"
            f"{math.degrees(lobe.exit_rad):.0f} deg, {lobe.teeth} teeth"
        )
        depth = np.where(np.isfinite(lobe.critical_depth_mm), lobe.critical_depth_mm, np.nan)
        lobes.add_trace(go.Scatter(x=grid, y=depth, mode="lines", name=label))
        mine = [seg for seg in segments if seg.lobes == index]
        lobes.add_trace(
            go.Scatter(
                x=[s.programmed_rpm for s in mine],
                y=[s.ap_mm for s in mine],
                mode="markers",
                marker_symbol="x",
                name=f"{label}: programmed",
            )  # fmt: skip
        )
    lobes.update_layout(xaxis_title="spindle speed [rpm]", yaxis_title="axial depth [mm]")
    report.figure(lobes)
    report.section("Segments")
    report.table(
        [
            [
                row["line"],
                row["start_s_mm"],
                row["end_s_mm"],
                row["ap_mm"],
                row["radial_immersion"],
                row["programmed_rpm"],
                row["programmed_critical_depth_mm"],
                row["scheduled_rpm"],
            ]  # fmt: skip
            for row in result["segments"]
        ],
        [
            "line",
            "s from [mm]",
            "s to [mm]",
            "ap [mm]",
            "ae/D",
            "programmed [rpm]",
            "critical depth there [mm]",
            "scheduled [rpm]",
        ],  # fmt: skip
    )
    return report.write(path)
