"""Program summaries checked against closed forms: squares, circles, helices, feeds."""

from __future__ import annotations

import math
from collections.abc import Iterator

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from cnctwin.errors import ConfigError
from cnctwin.nc.segments import MachineState, MotionKind, Plane, Segment, Vec3, arc_sweep_rad
from cnctwin.nc.summary import arc_extreme_points, summarize

STATE = MachineState(tool=3)


def line(start: Vec3, end: Vec3, feed: float = 600.0, *, state: MachineState = STATE) -> Segment:
    return Segment(MotionKind.LINEAR, 1, start, end, feed, 1000.0, state, file="t.ngc")


def rapid(start: Vec3, end: Vec3, *, state: MachineState = STATE) -> Segment:
    return Segment(MotionKind.RAPID, 1, start, end, 0.0, 1000.0, state, file="t.ngc")


def arc(
    start: Vec3,
    end: Vec3,
    center: Vec3,
    turns: int,
    feed: float = 600.0,
    *,
    state: MachineState = STATE,
) -> Segment:
    return Segment(MotionKind.ARC, 1, start, end, feed, 1000.0, state, center, turns, file="t.ngc")


def test_square_lengths_and_times() -> None:
    corners = [(0.0, 0.0, 0.0), (10.0, 0.0, 0.0), (10.0, 10.0, 0.0), (0.0, 10.0, 0.0)]
    segments = [rapid((0.0, 0.0, 5.0), corners[0])]
    segments += [line(corners[i], corners[(i + 1) % 4]) for i in range(4)]
    result = summarize(iter(segments), rapid_mm_min=3000.0)
    assert result.motion_blocks == 5
    assert result.feed_length_mm == pytest.approx(40.0, rel=1e-15)
    assert result.rapid_length_mm == pytest.approx(5.0, rel=1e-15)
    assert result.machining_time_s == pytest.approx(4.0, rel=1e-15)  # 40 mm at 600 mm/min
    assert result.rapid_time_s == pytest.approx(0.1, rel=1e-15)  # 5 mm at 3000 mm/min
    assert result.total_time_s == pytest.approx(4.1, rel=1e-15)
    assert result.bounds_min_mm == (0.0, 0.0, 0.0)
    assert result.bounds_max_mm == (10.0, 10.0, 5.0)
    assert result.tools == (3,)
    assert result.warnings == ()


def test_full_circle_length_and_exact_box() -> None:
    r = 5.0
    center = (20.0, 30.0, -1.0)
    start = (20.0 + r * math.cos(0.7), 30.0 + r * math.sin(0.7), -1.0)  # not on an axis
    result = summarize([arc(start, start, center, 1)], rapid_mm_min=1000.0)
    assert result.feed_length_mm == pytest.approx(2.0 * math.pi * r, rel=1e-12)
    assert result.machining_time_s == pytest.approx(60.0 * 2.0 * math.pi * r / 600.0, rel=1e-12)
    assert result.bounds_min_mm == pytest.approx((15.0, 25.0, -1.0), abs=1e-12)
    assert result.bounds_max_mm == pytest.approx((25.0, 35.0, -1.0), abs=1e-12)


def test_quarter_arcs_cross_only_the_axes_they_sweep() -> None:
    r = 2.0
    s45 = r * math.sqrt(0.5)
    # CCW from 45 to 135 degrees crosses 90: top of the circle, no other extreme.
    ccw = summarize([arc((s45, s45, 0.0), (-s45, s45, 0.0), (0.0, 0.0, 0.0), 1)], rapid_mm_min=1.0)
    assert ccw.bounds_min_mm == pytest.approx((-s45, s45, 0.0), abs=1e-12)
    assert ccw.bounds_max_mm == pytest.approx((s45, r, 0.0), abs=1e-12)
    assert ccw.feed_length_mm == pytest.approx(math.pi * r / 2.0, rel=1e-12)
    # CW from 45 to -45 degrees crosses 0: right of the circle.
    cw = summarize([arc((s45, s45, 0.0), (s45, -s45, 0.0), (0.0, 0.0, 0.0), -1)], rapid_mm_min=1.0)
    assert cw.bounds_min_mm == pytest.approx((s45, -s45, 0.0), abs=1e-12)
    assert cw.bounds_max_mm == pytest.approx((r, s45, 0.0), abs=1e-12)


def test_helix_two_turns() -> None:
    r, pitch = 4.0, 1.5
    start = (r, 0.0, 0.0)
    end = (r, 0.0, -2.0 * pitch)
    result = summarize([arc(start, end, (0.0, 0.0, 0.0), 2)], rapid_mm_min=1.0)
    assert result.feed_length_mm == pytest.approx(
        math.hypot(4.0 * math.pi * r, 2 * pitch), rel=1e-12
    )
    assert result.bounds_min_mm == pytest.approx((-r, -r, -2.0 * pitch), abs=1e-12)
    assert result.bounds_max_mm == pytest.approx((r, r, 0.0), abs=1e-12)


def test_xz_plane_arc_and_tool_offset() -> None:
    # G18: first axis Z, second X; CCW about +Y from Z+ (angle 0) to X+ (angle 90).
    state = MachineState(plane=Plane.ZX, tool=1, tool_offset_mm=(0.0, 0.0, 50.0))
    start = (0.0, 0.0, 53.0)  # tool tip (0, 0, 3)
    end = (3.0, 0.0, 50.0)  # tool tip (3, 0, 0)
    result = summarize([arc(start, end, (0.0, 0.0, 50.0), 1, state=state)], rapid_mm_min=1.0)
    assert result.bounds_min_mm == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    assert result.bounds_max_mm == pytest.approx((3.0, 0.0, 3.0), abs=1e-12)
    # Clockwise from Z+ to X+ sweeps 270 degrees through X- and Z-.
    cw = summarize([arc(start, end, (0.0, 0.0, 50.0), -1, state=state)], rapid_mm_min=1.0)
    assert cw.bounds_min_mm == pytest.approx((-3.0, 0.0, -3.0), abs=1e-12)
    assert cw.bounds_max_mm == pytest.approx((3.0, 0.0, 3.0), abs=1e-12)


def test_segment_feeds_are_used_as_resolved() -> None:
    # Under G93 the interpreter resolves "F2" (1/min) for a 10 mm move to 20 mm/min.
    state = MachineState(tool=2, programmed_feed=2.0)
    result = summarize(
        [line((0.0, 0.0, 0.0), (10.0, 0.0, 0.0), 20.0, state=state)], rapid_mm_min=1.0
    )
    assert result.machining_time_s == pytest.approx(30.0, rel=1e-15)  # 1 / 2 min


def test_zero_feed_moves_are_counted_and_warned() -> None:
    segments = [
        line((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 0.0),
        line((1.0, 0.0, 0.0), (2.0, 0.0, 0.0), 0.0),
    ]
    result = summarize(segments, rapid_mm_min=1.0)
    assert result.zero_feed_moves == 2
    assert result.machining_time_s == 0.0
    assert result.feed_length_mm == 2.0
    assert result.warnings == (
        "t.ngc:1: 2 feed moves with feed 0 mm/min (the first here); "
        "their machining time is not counted",
    )


def test_dwell_time_tools_and_empty_program() -> None:
    dwell = Segment(
        MotionKind.DWELL, 4, (0.0,) * 3, (0.0,) * 3, 0.0, 0.0, MachineState(), dwell_s=1.5
    )
    no_tool = rapid((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), state=MachineState(tool=0))
    t7 = line((0.0, 0.0, 1.0), (0.0, 0.0, 2.0), state=MachineState(tool=7))
    result = summarize(
        [dwell, t7, no_tool, line((0.0, 0.0, 2.0), (0.0, 0.0, 3.0))], rapid_mm_min=1.0
    )
    assert result.dwell_time_s == 1.5
    assert result.motion_blocks == 3
    assert result.tools == (3, 7)
    empty = summarize([dwell], rapid_mm_min=1.0)
    assert empty.motion_blocks == 0
    assert empty.to_dict()["bounds_mm"] == {"min": None, "max": None}
    assert empty.total_time_s == 1.5


def test_to_dict_keys() -> None:
    data = summarize([line((0.0, 0.0, 0.0), (1.0, 2.0, 3.0))], rapid_mm_min=1.0).to_dict()
    assert data["bounds_mm"] == {"min": [0.0, 0.0, 0.0], "max": [1.0, 2.0, 3.0]}
    assert set(data) == {
        "motion_blocks",
        "feed_length_mm",
        "rapid_length_mm",
        "machining_time_s",
        "rapid_time_s",
        "dwell_time_s",
        "total_time_s",
        "bounds_mm",
        "tools",
        "zero_feed_moves",
        "warnings",
    }


def test_summary_streams() -> None:
    consumed = []

    def produce() -> Iterator[Segment]:
        for i in range(1000):
            consumed.append(i)
            yield line((float(i), 0.0, 0.0), (float(i + 1), 0.0, 0.0))

    assert summarize(produce(), rapid_mm_min=1.0).feed_length_mm == pytest.approx(1000.0)
    assert len(consumed) == 1000


@pytest.mark.parametrize("rate", [0.0, -5.0, math.nan, math.inf])
def test_rapid_rate_must_be_positive(rate: float) -> None:
    with pytest.raises(ConfigError, match="rapid_mm_min must be a positive number"):
        summarize([], rapid_mm_min=rate)


@settings(max_examples=200, deadline=None)
@given(
    a0=st.floats(-math.pi, math.pi),
    a1=st.floats(-math.pi, math.pi),
    turns=st.sampled_from([-2, -1, 1, 2]),
    plane=st.sampled_from(list(Plane)),
)
@example(a0=math.pi, a1=-math.pi, turns=1, plane=Plane.XY)  # start and end 1 ulp across +-pi
def test_arc_box_is_the_sampled_box(a0: float, a1: float, turns: int, plane: Plane) -> None:
    """The exact box contains every point of the arc and is no larger than the dense samples'."""
    from cnctwin.nc.segments import PLANE_AXES

    r = 3.0
    i0, i1, n = PLANE_AXES[plane]
    center = [1.0, 2.0, 3.0]

    def point(angle: float, normal: float) -> Vec3:
        p = list(center)
        p[i0] += r * math.cos(angle)
        p[i1] += r * math.sin(angle)
        p[n] = normal
        return (p[0], p[1], p[2])

    start, end = point(a0, 3.0), point(a1, 4.0)
    seg = arc(start, end, (center[0], center[1], center[2]), turns, state=MachineState(plane=plane))
    result = summarize([seg], rapid_mm_min=1.0)
    _, angle0, sweep = arc_sweep_rad(start, end, seg.center_mm, turns, plane)
    steps = 4000
    samples = [point(angle0 + sweep * k / steps, 3.0 + k / steps) for k in range(steps + 1)]
    # A chord of the samples misses the arc by at most r (1 - cos(step / 2)).
    slack = r * (1.0 - math.cos(abs(sweep) / steps / 2.0)) + 1e-9
    for axis in range(3):
        low = min(p[axis] for p in samples)
        high = max(p[axis] for p in samples)
        assert result.bounds_min_mm[axis] <= low + 1e-9
        assert result.bounds_max_mm[axis] >= high - 1e-9
        assert result.bounds_min_mm[axis] >= low - slack
        assert result.bounds_max_mm[axis] <= high + slack
    assert len(list(arc_extreme_points(seg))) <= 4


def test_travel_limits_warn_once_per_axis_end_with_the_line() -> None:
    # Controlled point = tool tip + tool offset: a tip at z=-5 with a 100 mm tool reads 95.
    state = MachineState(tool_offset_mm=(0.0, 0.0, 100.0))
    moves = [
        Segment(MotionKind.LINEAR, 7, (0.0, 0.0, 100.0), (120.0, 0.0, 95.0), 100.0, 0.0, state),
        Segment(MotionKind.LINEAR, 8, (120.0, 0.0, 95.0), (130.0, 0.0, 95.0), 100.0, 0.0, state),
    ]
    result = summarize(
        moves, rapid_mm_min=1000.0, travel_mm=((0.0, 0.0, 96.0), (100.0, 50.0, 200.0))
    )
    assert result.warnings == (
        "<program>:7: X reaches 120.000 mm, beyond the machine's travel 0.000 .. 100.000 mm "
        "(machine.axes.x)",
        "<program>:7: Z reaches 95.000 mm, beyond the machine's travel 96.000 .. 200.000 mm "
        "(machine.axes.z)",
    )
