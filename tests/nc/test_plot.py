"""Tool-path pictures: exact arc points, thinning of long paths, the PNG."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import pytest

from cnctwin.errors import ConfigError
from cnctwin.nc.plot import ToolpathPlot
from cnctwin.nc.segments import MachineState, MotionKind, Segment

OFFSET = MachineState(tool_offset_mm=(0.0, 0.0, 100.0))


def feed(start, end, kind=MotionKind.LINEAR, center=None, turns=0) -> Segment:
    return Segment(kind, 1, start, end, 500.0, 0.0, OFFSET, center, turns)


def test_arc_points_lie_on_the_circle_at_the_tool_tip() -> None:
    plot = ToolpathPlot()
    plot.add(feed((5.0, 0.0, 100.0), (5.0, 0.0, 98.0), MotionKind.ARC, (0.0, 0.0, 100.0), 1))
    [(rapid, points)] = plot.polylines()
    assert not rapid
    assert points[0] == (5.0, 0.0, 0.0)
    assert points[-1] == (5.0, 0.0, -2.0)
    assert len(points) >= 72  # at most 5 degrees apart
    for x, y, z in points:
        assert math.hypot(x, y) == pytest.approx(5.0, rel=1e-12)
        assert -2.0 <= z <= 0.0


def test_runs_split_by_kind_and_gaps() -> None:
    plot = ToolpathPlot()
    plot.add(Segment(MotionKind.RAPID, 1, (0.0, 0.0, 110.0), (0.0, 0.0, 101.0), 0.0, 0.0, OFFSET))
    plot.add(feed((0.0, 0.0, 101.0), (0.0, 0.0, 100.0)))
    plot.add(feed((0.0, 0.0, 100.0), (1.0, 0.0, 100.0)))
    plot.add(feed((2.0, 0.0, 100.0), (3.0, 0.0, 100.0)))  # not where the last ended
    assert [rapid for rapid, _ in plot.polylines()] == [True, False, False]
    assert plot.polylines()[1][1] == [(0.0, 0.0, 1.0), (0.0, 0.0, 0.0), (1.0, 0.0, 0.0)]


def test_long_paths_are_thinned_keeping_the_ends() -> None:
    plot = ToolpathPlot(max_points=100)
    for i in range(1000):
        plot.add(feed((float(i), 0.0, 100.0), (float(i + 1), 0.0, 100.0)))
    [(_, points)] = plot.polylines()
    assert len(points) <= 101
    assert points[0] == (0.0, 0.0, 0.0)
    assert points[-1] == (1000.0, 0.0, 0.0)
    xs = [p[0] for p in points]
    assert xs == sorted(xs)
    steps = {b - a for a, b in itertools.pairwise(xs[:-1])}
    assert len(steps) == 1  # evenly thinned


def test_png_is_written(tmp_path: Path) -> None:
    plot = ToolpathPlot()
    plot.add(feed((0.0, 0.0, 100.0), (10.0, 5.0, 99.0)))
    out = tmp_path / "path.png"
    plot.save(out, title="t")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    empty = tmp_path / "empty.png"
    ToolpathPlot().save(empty)
    assert empty.stat().st_size > 0


def test_max_points_must_be_useful() -> None:
    with pytest.raises(ConfigError, match="max_points must be >= 2; got 1"):
        ToolpathPlot(max_points=1)
