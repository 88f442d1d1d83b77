"""A picture of an NC program: the tool tip's path in 3D, feeds solid, rapids dashed.

Segments are consumed one at a time. Arcs are drawn as polylines through points exactly on
the arc. A long program is thinned as it streams (every other kept point is dropped each
time the count passes ``max_points``), always keeping each run's first and last point.
This is the only module of :mod:`cnctwin.nc` that uses matplotlib.
"""

from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass, field

from matplotlib.figure import Figure

from cnctwin.errors import ConfigError
from cnctwin.nc.segments import PLANE_AXES, MotionKind, Segment, Vec3, arc_sweep_rad

__all__ = ["ToolpathPlot"]

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

    def save(self, path: str | os.PathLike[str], *, title: str = "") -> None:
        """Write the picture.

        Parameters
        ----------
        path
            Output file; the format follows its suffix (``.png``).
        title
            Title above the plot.
        """
        figure = Figure(figsize=(8.0, 6.5), dpi=100)
        axes = figure.add_subplot(projection="3d")
        low = [math.inf] * 3
        high = [-math.inf] * 3
        for rapid in (False, True):
            xs: list[float] = []
            ys: list[float] = []
            zs: list[float] = []
            for run_rapid, points in self.polylines():
                if run_rapid != rapid:
                    continue
                for x, y, z in points:
                    xs.append(x)
                    ys.append(y)
                    zs.append(z)
                xs.append(math.nan)  # a gap between runs
                ys.append(math.nan)
                zs.append(math.nan)
            if not xs:
                continue
            for axis, values in enumerate((xs, ys, zs)):
                low[axis] = min(low[axis], min(v for v in values if v == v))
                high[axis] = max(high[axis], max(v for v in values if v == v))
            axes.plot(
                xs,
                ys,
                zs,
                linestyle="--" if rapid else "-",
                linewidth=0.6 if rapid else 0.9,
                color="tab:red" if rapid else "tab:blue",
                label="rapid" if rapid else "feed",
            )
        if self._runs:
            spans = [max(h - lo, 1e-9) for lo, h in zip(low, high, strict=True)]
            axes.set_box_aspect([max(s, max(spans) / 20.0) for s in spans])
            axes.legend(loc="upper left")
        axes.set_xlabel("X [mm]")
        axes.set_ylabel("Y [mm]")
        axes.set_zlabel("Z [mm]")
        if title:
            axes.set_title(title)
        figure.savefig(os.fspath(path))
        logger.debug("wrote %s: %d runs, %d points kept", path, len(self._runs), self._kept)

    def _thin(self) -> None:
        self._stride *= 2
        for run in self._runs:
            run.kept = run.kept[::2]
        self._kept = sum(len(run.kept) for run in self._runs)
        logger.debug("toolpath thinned to every %d-th point", self._stride)


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
