"""A picture of an NC program: the tool tip's path in 3D and from above, with the stock.

The picture shows a 3D view and a top view (XY) side by side. Feed moves (the cutting) are
solid and blue; rapids are thin, light grey and dashed, so they do not dominate. The axes are
limited to the stock (when given, e.g. a configuration's ``[stock]`` box, drawn as an outline)
and the feed moves, plus a margin; rapids that leave this view (to a tool change or the
machine's origin) are clipped at its edge, and a note under the views says how many.

Segments are consumed one at a time. Arcs are drawn as polylines through points exactly on
the arc. A long program is thinned as it streams (every other kept point is dropped each
time the count passes ``max_points``), always keeping each run's first and last point.
This is the only module of :mod:`cnctwin.nc` that uses matplotlib.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from matplotlib.axes import Axes
from matplotlib.figure import Figure

from cnctwin.errors import ConfigError
from cnctwin.nc.segments import PLANE_AXES, MotionKind, Segment, Vec3, arc_sweep_rad

__all__ = ["VIEW_MARGIN", "ToolpathPlot", "draw_top_view", "view_box"]

logger = logging.getLogger(__name__)

#: Largest angle between two drawn points of an arc, rad (5 degrees).
_ARC_STEP_RAD = math.radians(5.0)


@dataclass(slots=True)
class _Run:
    """Consecutive moves of one kind (rapid or feed) forming a connected polyline."""

    rapid: bool
    kept: list[Vec3]
    last: Vec3
    count: int = 1

    def add(self, point: Vec3, stride: int) -> bool:
        """Add a point; True if it was kept."""
        self.last = point
        kept = self.count % stride == 0
        if kept:
            self.kept.append(point)
        self.count += 1
        return kept

    def points(self) -> list[Vec3]:
        return self.kept if self.kept[-1] == self.last else [*self.kept, self.last]


#: Margin around the stock and feed moves in the view, as a fraction of the largest span.
VIEW_MARGIN = 0.05
_FEED_STYLE: dict[str, Any] = {
    "linestyle": "-",
    "linewidth": 0.9,
    "color": "tab:blue",
    "label": "feed",
}
_RAPID_STYLE: dict[str, Any] = {
    "linestyle": "--",
    "linewidth": 0.5,
    "color": "0.65",
    "alpha": 0.8,
    "label": "rapid",
}
_STOCK_STYLE: dict[str, Any] = {
    "linestyle": "-",
    "linewidth": 1.2,
    "color": "0.2",
    "label": "stock",
}

Box = tuple[Vec3, Vec3]


@dataclass
class ToolpathPlot:
    """Collects the tool-tip path of segments and writes it as a PNG.

    Parameters
    ----------
    max_points
        Largest number of points kept (about); beyond it the path is thinned.
    """

    max_points: int = 200_000
    _runs: list[_Run] = field(default_factory=list, init=False)
    _stride: int = field(default=1, init=False)
    _kept: int = field(default=0, init=False)

    def __post_init__(self) -> None:
        if self.max_points < 2:
            raise ConfigError(f"ToolpathPlot max_points must be >= 2; got {self.max_points!r}")

    def add(self, seg: Segment) -> None:
        """Add one segment (dwells add nothing)."""
        if seg.kind == MotionKind.DWELL:
            return
        rapid = seg.kind == MotionKind.RAPID
        start = seg.tcp_start_mm
        run = self._runs[-1] if self._runs else None
        if run is None or run.rapid != rapid or run.last != start:
            run = _Run(rapid=rapid, kept=[start], last=start)
            self._runs.append(run)
            self._kept += 1
        for point in _path_points(seg):
            self._kept += run.add(point, self._stride)
        if self._kept > self.max_points:
            self._thin()

    def polylines(self) -> list[tuple[bool, list[Vec3]]]:
        """The path so far as ``(rapid, points)`` runs of connected tool-tip points in mm."""
        return [(run.rapid, run.points()) for run in self._runs]

    def view_box(self, stock_mm: Box | None = None) -> Box | None:
        """The region the picture shows (:func:`view_box` of the path), mm."""
        return view_box(self.polylines(), stock_mm)

    def figure(self, *, title: str = "", stock_mm: Box | None = None) -> Figure:
        """The picture (module notes): a 3D view and a top view.

        Parameters
        ----------
        title
            Title above the views.
        stock_mm
            Opposite corners of the stock box in the path's coordinates, mm; outlined.
        """
        figure = Figure(figsize=(13.0, 6.0), dpi=100, layout="constrained")
        view3d = figure.add_subplot(1, 2, 1, projection="3d")
        top = figure.add_subplot(1, 2, 2)
        runs = self.polylines()
        box = view_box(runs, stock_mm)
        for rapid, style in ((True, _RAPID_STYLE), (False, _FEED_STYLE)):
            xs, ys, zs = _joined([points for r, points in runs if r == rapid])
            if xs:
                view3d.plot(xs, ys, zs, axlim_clip=True, **style)
        if stock_mm is not None:
            for xs, ys, zs in _box_edges(stock_mm):
                view3d.plot(xs, ys, zs, **{**_STOCK_STYLE, "label": None})
            view3d.plot([], [], [], **_STOCK_STYLE)  # one legend entry
        draw_top_view(top, runs, stock_mm)
        outside = 0 if box is None else _leaving(runs, box, 3)
        if box is not None:
            (x0, y0, z0), (x1, y1, z1) = box
            view3d.set(xlim=(x0, x1), ylim=(y0, y1), zlim=(z0, z1))
            spans = (x1 - x0, y1 - y0, z1 - z0)
            view3d.set_box_aspect([max(v, max(spans) / 20.0) for v in spans])
            view3d.legend(loc="upper left")
        if outside:
            figure.text(
                0.01,
                0.01,
                f"{outside} rapid run(s) leave the view (stock and feed moves) and are "
                "clipped at its edge",
                fontsize="small",
                color="0.3",
            )
        view3d.set(xlabel="X [mm]", ylabel="Y [mm]", zlabel="Z [mm]", title="3D")
        if title:
            figure.suptitle(title)
        return figure

    def save(
        self, path: str | os.PathLike[str], *, title: str = "", stock_mm: Box | None = None
    ) -> None:
        """Write the picture (:meth:`figure`); the format follows the suffix (``.png``)."""
        self.figure(title=title, stock_mm=stock_mm).savefig(os.fspath(path))
        logger.debug("wrote %s: %d runs, %d points kept", path, len(self._runs), self._kept)

    def _thin(self) -> None:
        self._stride *= 2
        for run in self._runs:
            run.kept = run.kept[::2]
        self._kept = sum(len(run.kept) for run in self._runs)
        logger.debug("toolpath thinned to every %d-th point", self._stride)


def view_box(runs: Sequence[tuple[bool, Sequence[Vec3]]], stock_mm: Box | None) -> Box | None:
    """The region a picture shows: the stock box and the points of the runs that are not
    rapid (all points when there are neither), with :data:`VIEW_MARGIN`; mm. None for no
    points and no stock.

    Parameters
    ----------
    runs
        ``(rapid, points)`` polylines of tool-tip points, mm.
    stock_mm
        Opposite corners of the stock box, mm, or None.
    """
    points = [p for rapid, run in runs if not rapid for p in run]
    if stock_mm is not None:
        points += [stock_mm[0], stock_mm[1]]
    if not points:
        points = [p for _, run in runs for p in run]
    if not points:
        return None
    low = [min(p[k] for p in points) for k in range(3)]
    high = [max(p[k] for p in points) for k in range(3)]
    margin = VIEW_MARGIN * max(max(h - lo for lo, h in zip(low, high, strict=True)), 1.0)
    return (
        (low[0] - margin, low[1] - margin, low[2] - margin),
        (high[0] + margin, high[1] + margin, high[2] + margin),
    )


def draw_top_view(
    axes: Axes,
    runs: Sequence[tuple[bool, Sequence[Vec3]]],
    stock_mm: Box | None = None,
    labels: tuple[str, str] = ("feed", "rapid"),
) -> int:
    """Draw runs of tool-tip points from above (XY) on ``axes``, limited to :func:`view_box`.

    Runs flagged True (rapids, or moves in air) are thin, light and dashed; the others solid;
    the stock box is outlined. Returns how many flagged runs leave the view in x or y
    (clipped at its edge).

    Parameters
    ----------
    axes
        2D matplotlib axes.
    runs
        ``(faint, points)`` polylines, mm.
    stock_mm
        Opposite corners of the stock box, mm, or None.
    labels
        Legend labels of the solid and the faint runs.
    """
    for faint, style in ((True, _RAPID_STYLE), (False, _FEED_STYLE)):
        xs, ys, _ = _joined([points for f, points in runs if f == faint])
        if xs:
            axes.plot(xs, ys, **{**style, "label": labels[faint]})
    if stock_mm is not None:
        (x0, y0, _), (x1, y1, _) = stock_mm
        axes.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], **_STOCK_STYLE)
    axes.set(xlabel="X [mm]", ylabel="Y [mm]", title="top view (XY)")
    axes.grid(alpha=0.3)
    box = view_box(runs, stock_mm)
    if box is None:
        return 0
    (x0, y0, _), (x1, y1, _) = box
    axes.set(xlim=(x0, x1), ylim=(y0, y1))
    axes.set_aspect("equal", adjustable="box")
    return _leaving(runs, box, 2)


def _joined(runs: Sequence[Sequence[Vec3]]) -> tuple[list[float], list[float], list[float]]:
    """x, y, z of the runs, one NaN between runs (a gap in one drawn line)."""
    xs: list[float] = []
    ys: list[float] = []
    zs: list[float] = []
    for points in runs:
        for x, y, z in points:
            xs.append(x)
            ys.append(y)
            zs.append(z)
        xs.append(math.nan)
        ys.append(math.nan)
        zs.append(math.nan)
    return xs, ys, zs


def _box_edges(box: Box) -> list[tuple[list[float], list[float], list[float]]]:
    """The twelve edges of an axis-aligned box as (xs, ys, zs) pairs of points."""
    (x0, y0, z0), (x1, y1, z1) = box
    edges = []
    for z in (z0, z1):
        edges += [([x0, x1], [y, y], [z, z]) for y in (y0, y1)]
        edges += [([x, x], [y0, y1], [z, z]) for x in (x0, x1)]
    edges += [([x, x], [y, y], [z0, z1]) for x in (x0, x1) for y in (y0, y1)]
    return edges


def _leaving(runs: Sequence[tuple[bool, Sequence[Vec3]]], box: Box, dims: int) -> int:
    """How many flagged (faint) runs have a point outside the box in its first ``dims`` axes."""
    return sum(
        1
        for faint, points in runs
        if faint and any(not box[0][k] <= p[k] <= box[1][k] for p in points for k in range(dims))
    )


def _path_points(seg: Segment) -> list[Vec3]:
    """Tool-tip points after the start: the end, or points on an arc ending at its end."""
    end = seg.tcp_end_mm
    if seg.kind != MotionKind.ARC or seg.center_mm is None:
        return [end]
    start = seg.tcp_start_mm
    offset = seg.state.tool_offset_mm
    c = seg.center_mm
    center = (c[0] - offset[0], c[1] - offset[1], c[2] - offset[2])
    radius, a0, sweep = arc_sweep_rad(start, end, center, seg.turns, seg.state.plane)
    first_axis, second_axis, normal = PLANE_AXES[seg.state.plane]
    steps = max(2, math.ceil(abs(sweep) / _ARC_STEP_RAD))
    points: list[Vec3] = []
    for i in range(1, steps):
        fraction = i / steps
        angle = a0 + fraction * sweep
        point = [0.0, 0.0, 0.0]
        point[first_axis] = center[first_axis] + radius * math.cos(angle)
        point[second_axis] = center[second_axis] + radius * math.sin(angle)
        point[normal] = start[normal] + fraction * (end[normal] - start[normal])
        points.append((point[0], point[1], point[2]))
    points.append(end)
    return points
