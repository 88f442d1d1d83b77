"""The sampler's segment-end samples (``segment_ends="all"``), against closed forms.

With the option, every segment also gives a sample at its end point and end time, labelled
with it; the samples on the cycle grid are those the sampler gives without it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnctwin.errors import InputError
from cnctwin.nc.sampler import AxisLimits, SampleChunk, TrajectorySampler
from cnctwin.nc.segments import MachineState, MotionKind, Segment, Vec3

STATE = MachineState()
RAPID = 6000.0  # mm/min: 100 mm/s
CYCLE = 0.1  # s


def _line(p0: Vec3, p1: Vec3, feed: float, n: int) -> Segment:
    return Segment(MotionKind.LINEAR, n, p0, p1, feed, 1000.0, STATE)


def _program() -> list[Segment]:
    """A rapid, two feed moves ending off the grid, an arc, a dwell and a rapid retract."""
    return [
        Segment(MotionKind.RAPID, 1, (0.0, 0.0, 0.0), (0.0, 0.0, 5.0), 0.0, 0.0, STATE),
        _line((0.0, 0.0, 5.0), (0.0, 0.0, 0.0), 600.0, 2),  # 5 mm at 10 mm/s: ends at 0.55 s
        _line((0.0, 0.0, 0.0), (10.05, 0.0, 0.0), 600.0, 3),  # ends at 1.555 s
        Segment(
            MotionKind.ARC,
            4,
            (10.05, 0.0, 0.0),
            (10.05, 0.0, 0.0),
            600.0,
            1000.0,
            STATE,
            center_mm=(5.05, 0.0, 0.0),
            turns=1,
        ),  # fmt: skip
        Segment(
            MotionKind.DWELL,
            5,
            (10.05, 0.0, 0.0),
            (10.05, 0.0, 0.0),
            0.0,
            1000.0,
            STATE,
            dwell_s=0.25,
        ),  # fmt: skip
        Segment(MotionKind.RAPID, 6, (10.05, 0.0, 0.0), (10.05, 0.0, 5.0), 0.0, 0.0, STATE),
    ]


def _sample(ends: str, chunk: int = 16384, limits: AxisLimits | None = None) -> SampleChunk:
    sampler = TrajectorySampler(
        _program(),
        rapid_mm_min=RAPID,
        cycle_s=CYCLE,
        chunk_samples=chunk,
        limits=limits,
        segment_ends=ends,
    )
    chunks = list(sampler)
    return SampleChunk(*(np.concatenate(parts) for parts in zip(*chunks, strict=True)))


def _end_times() -> list[float]:
    t_arc = 0.55 + 1.005 + 2.0 * math.pi * 5.0 / 10.0
    return [0.05, 0.55, 1.555, t_arc, t_arc + 0.25, t_arc + 0.30]


@pytest.mark.parametrize("chunk", [16384, 3, 1])
def test_ends_are_sampled_at_their_time_and_point(chunk: int) -> None:
    grid = _sample("none")
    both = _sample("all", chunk)
    ends = [float(t) for t in both.t_s if not np.isclose(t / CYCLE, round(t / CYCLE))]
    # The program's segment ends: 0.05, 0.55 and 1.555 s, the arc's (pi s later), the dwell's
    # and the retract's; 0.55 s is off the grid too.
    expected = _end_times()
    assert ends == pytest.approx(expected, abs=1e-9)
    # The grid samples are those without the option.
    on_grid = np.isclose(both.t_s / CYCLE, np.round(both.t_s / CYCLE))
    for name in SampleChunk._fields:
        np.testing.assert_allclose(getattr(both, name)[on_grid], getattr(grid, name))
    # Each end sample is its segment's end point, labelled with it.
    points = [(0, 0, 5), (0, 0, 0), (10.05, 0, 0), (10.05, 0, 0), (10.05, 0, 0), (10.05, 0, 5)]
    for line, (t, point) in enumerate(zip(expected, points, strict=True), start=1):
        i = int(np.argmin(np.abs(both.t_s - t)))
        assert both.line[i] == line
        np.testing.assert_allclose(both.tcp_mm[i], point, atol=1e-9)
    assert both.t_s[-1] == pytest.approx(expected[-1])
    assert np.all(np.diff(both.t_s) > 0.0)


def test_kind_samples_every_end_but_the_tangent_junctions_of_feed_moves() -> None:
    # Rapid -> line -> line -> arc -> dwell -> rapid: the feed moves meet at corners (down,
    # then along x, then the arc starting along y), so every end is sampled, as with "all".
    both = _sample("kind")
    ends = [float(t) for t in both.t_s if not np.isclose(t / CYCLE, round(t / CYCLE))]
    assert ends == pytest.approx(_end_times(), abs=1e-9)
    grid = _sample("none")
    on_grid = np.isclose(both.t_s / CYCLE, np.round(both.t_s / CYCLE))
    np.testing.assert_allclose(both.tcp_mm[on_grid], grid.tcp_mm)
    # A line, a line on from it, and an arc leaving along the same direction (centre below
    # the line: G2 from +x tangent), then a corner: only the corner and the program's end are
    # sampled; the tangent junctions (at 1.025 s and 2.05 s) are spanned.
    arc = Segment(
        MotionKind.ARC, 3, (20.5, 0.0, 0.0), (25.5, -5.0, 0.0), 600.0, 1000.0, STATE,
        center_mm=(20.5, -5.0, 0.0), turns=-1,
    )  # fmt: skip
    segments = [
        _line((0.0, 0.0, 0.0), (10.25, 0.0, 0.0), 600.0, 1),
        _line((10.25, 0.0, 0.0), (20.5, 0.0, 0.0), 600.0, 2),
        arc,
        _line((25.5, -5.0, 0.0), (25.5, -5.0, 1.0), 600.0, 4),
    ]
    t_arc = 2.05 + 0.25 * math.pi
    out = list(TrajectorySampler(segments, rapid_mm_min=RAPID, cycle_s=CYCLE, segment_ends="kind"))
    t = np.concatenate([c.t_s for c in out])
    off = [float(v) for v in t if not np.isclose(v / CYCLE, round(v / CYCLE))]
    assert off == pytest.approx([t_arc, t_arc + 0.1], abs=1e-9)
    # Two rapids in a row: the first one's end is sampled too.
    segments = [
        Segment(MotionKind.RAPID, 1, (0.0, 0.0, 0.0), (0.0, 0.0, 5.5), 0.0, 0.0, STATE),
        Segment(MotionKind.RAPID, 2, (0.0, 0.0, 5.5), (0.0, 0.0, 0.0), 0.0, 0.0, STATE),
    ]
    out = list(TrajectorySampler(segments, rapid_mm_min=RAPID, cycle_s=0.01, segment_ends="kind"))
    t = np.concatenate([c.t_s for c in out])
    np.testing.assert_allclose(t, [0.0, 0.01, 0.02, 0.03, 0.04, 0.05, 0.055, 0.06, 0.07, 0.08,
                                   0.09, 0.1, 0.11])  # fmt: skip


def test_an_end_on_the_grid_is_the_grid_sample() -> None:
    # 5 mm at 100 mm/s then 1 mm at 10 mm/s: ends at 0.05 s and 0.15 s, the grid samples 5
    # and 15 at 10 ms (within rounding): no extra sample, the grid sample is the end's.
    segments = [
        Segment(MotionKind.RAPID, 1, (0.0, 0.0, 0.0), (5.0, 0.0, 0.0), 0.0, 0.0, STATE),
        _line((5.0, 0.0, 0.0), (6.0, 0.0, 0.0), 600.0, 2),
    ]
    cycle = 0.01
    out = list(TrajectorySampler(segments, rapid_mm_min=RAPID, cycle_s=cycle, segment_ends="all"))
    t = np.concatenate([c.t_s for c in out])
    line = np.concatenate([c.line for c in out])
    x = np.concatenate([c.tcp_mm[:, 0] for c in out])
    np.testing.assert_allclose(t, np.arange(16) * cycle)
    assert line[5] == 1 and x[5] == pytest.approx(5.0)  # the rapid's end is sample 5
    assert line[15] == 2 and x[15] == pytest.approx(6.0)


def test_ends_with_acceleration_limits_keep_the_time_of_the_profile() -> None:
    limits = AxisLimits(accel_mm_s2=(500.0, 500.0, 500.0))
    grid = _sample("none", limits=limits)
    both = _sample("all", limits=limits)
    on_grid = np.isclose(both.t_s / CYCLE, np.round(both.t_s / CYCLE))
    np.testing.assert_allclose(both.tcp_mm[on_grid], grid.tcp_mm)
    # The rapid up and the plunge down meet head on: the planner stops there, and that end
    # is sampled at its point, at rest.
    i = int(np.flatnonzero(both.line == 1)[-1])
    np.testing.assert_allclose(both.tcp_mm[i], (0.0, 0.0, 5.0), atol=1e-9)
    assert both.path_speed_mm_min[i] == pytest.approx(0.0, abs=1e-6)


def test_segment_ends_must_be_a_mode() -> None:
    for bad in (True, "every", ["all"]):
        with pytest.raises(InputError, match="segment_ends=.*; give one of 'none', 'kind', 'all'"):
            TrajectorySampler(_program(), rapid_mm_min=RAPID, segment_ends=bad)  # type: ignore[arg-type]
