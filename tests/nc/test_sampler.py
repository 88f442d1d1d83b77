"""Tests of the trajectory sampler against closed forms (path length, trapezoidal profiles)."""

from __future__ import annotations

import itertools
import math
import tracemalloc
from collections.abc import Iterator

import numpy as np
import pytest

from cnctwin.errors import ConfigError, InputError, NCError
from cnctwin.nc.sampler import (
    AxisLimits,
    FeedOverride,
    SampleChunk,
    TrajectorySampler,
    sample_program,
)
from cnctwin.nc.segments import (
    MachineState,
    MotionKind,
    Plane,
    Segment,
    Vec3,
    arc_sweep_rad,
    segment_length_mm,
)

STATE = MachineState()
RAPID = 6000.0  # mm/min
# Positions come from a few float operations on numbers of order 100 mm.
POS_TOL_MM = 1e-9


def line(p0: Vec3, p1: Vec3, feed: float, n: int = 1, state: MachineState = STATE) -> Segment:
    return Segment(MotionKind.LINEAR, n, p0, p1, feed, 1000.0, state)


def rapid(p0: Vec3, p1: Vec3, n: int = 1) -> Segment:
    return Segment(MotionKind.RAPID, n, p0, p1, 0.0, 0.0, STATE)


def arc(
    p0: Vec3, p1: Vec3, c: Vec3, turns: int, feed: float, state: MachineState = STATE, n: int = 1
) -> Segment:
    return Segment(MotionKind.ARC, n, p0, p1, feed, 1000.0, state, center_mm=c, turns=turns)


def dwell(p: Vec3, dwell_s: float, n: int = 1) -> Segment:
    return Segment(MotionKind.DWELL, n, p, p, 0.0, 1000.0, STATE, dwell_s=dwell_s)


def polyline_point(vertices: np.ndarray, s: float) -> np.ndarray:
    """Point at arc length s (mm) along a polyline."""
    for a, b in itertools.pairwise(vertices):
        seg = float(np.linalg.norm(b - a))
        if s <= seg:
            return a + (b - a) * (s / seg)
        s -= seg
    return vertices[-1]


def test_polyline_constant_feed_is_exact() -> None:
    verts = np.array([(0, 0, 0), (30, 0, 0), (30, 40, 0), (30, 40, -12.5), (0, 0, 0)], float)
    segs = [
        line(tuple(a), tuple(b), 900.0, n=i + 10)
        for i, (a, b) in enumerate(itertools.pairwise(verts))
    ]
    v = 900.0 / 60.0
    total = sum(float(np.linalg.norm(b - a)) for a, b in itertools.pairwise(verts))
    c, duration = sample_program(segs, rapid_mm_min=RAPID, cycle_s=0.0125)
    assert duration == pytest.approx(total / v, rel=1e-14)
    assert len(c.t_s) == math.ceil(duration / 0.0125)
    np.testing.assert_array_equal(c.t_s, np.arange(len(c.t_s)) * 0.0125)
    # Distance travelled = feed x time, on the geometric path.
    expected = np.array([polyline_point(verts, v * t) for t in c.t_s])
    np.testing.assert_allclose(c.tcp_mm, expected, atol=POS_TOL_MM)
    np.testing.assert_allclose(c.path_speed_mm_min, 900.0)
    np.testing.assert_allclose(np.linalg.norm(c.velocity_mm_s, axis=1), v)
    assert set(c.line.tolist()) == {10, 11, 12, 13}
    assert np.all(c.kind == MotionKind.LINEAR)


@pytest.mark.parametrize("turns", [1, -1, 2, -3])
def test_arc_samples_on_circle_with_angle_linear_in_time(turns: int) -> None:
    # Arc in XY with a tool-length offset: the TCP is the machine point minus the offset.
    state = MachineState(tool_offset_mm=(0.0, 0.0, 25.0), tool=7)
    centre = (10.0, 5.0, 30.0)
    r = 8.0
    p0 = (centre[0] + r, centre[1], 30.0)
    p1 = (centre[0], centre[1] + r, 30.0)
    seg = arc(p0, p1, centre, turns, 1200.0, state=state)
    _, a0, sweep = arc_sweep_rad(p0, p1, centre, turns, Plane.XY)
    v = 20.0
    c, duration = sample_program([seg], rapid_mm_min=RAPID, cycle_s=0.001)
    assert duration == pytest.approx(r * abs(sweep) / v, rel=1e-13)
    assert len(c.t_s) == math.ceil(duration / 0.001)
    dx = c.tcp_mm[:, 0] - centre[0]
    dy = c.tcp_mm[:, 1] - centre[1]
    np.testing.assert_allclose(np.hypot(dx, dy), r, atol=1e-12)
    np.testing.assert_allclose(c.tcp_mm[:, 2], 5.0, atol=1e-12)
    phi = a0 + math.copysign(1.0, sweep) * v * c.t_s / r
    np.testing.assert_allclose(dx, r * np.cos(phi), atol=POS_TOL_MM)
    np.testing.assert_allclose(dy, r * np.sin(phi), atol=POS_TOL_MM)
    np.testing.assert_allclose(np.linalg.norm(c.velocity_mm_s, axis=1), v, rtol=1e-12)
    assert np.all(c.tool == 7)
    assert np.all(c.kind == MotionKind.ARC)


def test_helix_in_zx_plane_has_linear_normal_travel() -> None:
    # G18 (ZX): first axis Z, second X, normal Y. Two turns rising 6 mm along Y.
    state = MachineState(plane=Plane.ZX)
    centre = (0.0, 0.0, 0.0)
    r = 5.0
    p0 = (0.0, 0.0, r)  # z = r, x = 0: angle 0 in the (z, x) frame
    p1 = (0.0, 6.0, r)
    seg = arc(p0, p1, centre, 2, 600.0, state=state)
    v = 10.0
    length = math.hypot(r * 4.0 * math.pi, 6.0)
    assert segment_length_mm(seg) == pytest.approx(length, rel=1e-14)
    c, duration = sample_program([seg], rapid_mm_min=RAPID, cycle_s=0.0125)
    assert duration == pytest.approx(length / v, rel=1e-13)
    z, x, y = c.tcp_mm[:, 2], c.tcp_mm[:, 0], c.tcp_mm[:, 1]
    np.testing.assert_allclose(np.hypot(z, x), r, atol=1e-12)
    angle = np.unwrap(np.arctan2(x, z))
    frac = v * c.t_s / length
    np.testing.assert_allclose(angle, 4.0 * math.pi * frac, atol=1e-9)
    np.testing.assert_allclose(y, 6.0 * frac, atol=POS_TOL_MM)


def test_arc_with_unequal_radii_interpolates_radius_linearly_in_angle() -> None:
    # Start radius 5, end radius 5.02 (as LinuxCNC accepts): r(phi) linear, length = mean r x sweep.
    r0, r1 = 5.0, 5.02
    seg = arc((r0, 0, 0), (0, r1, 0), (0, 0, 0), 1, 600.0)
    c, duration = sample_program([seg], rapid_mm_min=RAPID, cycle_s=0.001)
    sweep = math.pi / 2
    assert duration == pytest.approx(0.5 * (r0 + r1) * sweep / 10.0, rel=1e-13)
    phi = np.arctan2(c.tcp_mm[:, 1], c.tcp_mm[:, 0])
    np.testing.assert_allclose(phi, sweep * 10.0 * c.t_s / (0.5 * (r0 + r1) * sweep), atol=1e-12)
    radius = np.hypot(c.tcp_mm[:, 0], c.tcp_mm[:, 1])
    np.testing.assert_allclose(radius, r0 + (r1 - r0) * phi / sweep, atol=1e-12)


def test_arc_sweep_matches_segments_helper() -> None:
    # The kernel repeats the sweep rule of arc_sweep_rad: durations must agree with
    # segment_length_mm.
    rng = np.random.default_rng(1)
    segs = []
    for i in range(60):
        plane = [Plane.XY, Plane.ZX, Plane.YZ][i % 3]
        state = MachineState(plane=plane)
        centre = tuple(rng.uniform(-5, 5, 3))
        r = rng.uniform(0.5, 4.0)
        a0, a1 = rng.uniform(-math.pi, math.pi, 2)
        if i % 7 == 0:
            a1 = a0  # full circles
        first, second, normal = {Plane.XY: (0, 1, 2), Plane.ZX: (2, 0, 1), Plane.YZ: (1, 2, 0)}[
            plane
        ]
        p0 = list(centre)
        p1 = list(centre)
        p0[first] += r * math.cos(a0)
        p0[second] += r * math.sin(a0)
        p1[first] += r * math.cos(a1)
        p1[second] += r * math.sin(a1)
        p1[normal] += rng.uniform(-2, 2)
        turns = int(rng.choice([-2, -1, 1, 3]))
        segs.append(arc(tuple(p0), tuple(p1), centre, turns, 600.0, state=state))
    for seg in segs:
        _, duration = sample_program([seg], rapid_mm_min=RAPID, cycle_s=0.0125)
        assert duration == pytest.approx(segment_length_mm(seg) / 10.0, rel=1e-12)


def test_sample_count_and_override_half_doubles_time() -> None:
    segs = [line((0, 0, 0), (37.3, 0, 0), 700.0), line((37.3, 0, 0), (37.3, 11.1, 0), 350.0)]
    t_full = 37.3 / (700 / 60) + 11.1 / (350 / 60)
    c1, d1 = sample_program(segs, rapid_mm_min=RAPID, cycle_s=0.0125)
    c2, d2 = sample_program(segs, rapid_mm_min=RAPID, cycle_s=0.0125, feed_override=0.5)
    assert d1 == pytest.approx(t_full, rel=1e-14)
    assert d2 == pytest.approx(2.0 * t_full, rel=1e-14)
    assert len(c1.t_s) == math.ceil(d1 / 0.0125)
    assert len(c2.t_s) == math.ceil(d2 / 0.0125)


def test_time_series_override_mid_segment_matches_piecewise_integral() -> None:
    # 100 mm at 10 mm/s; override 1.0, then 0.5 from 2 s, then 2.0 from 5 s.
    ov = FeedOverride([1.0, 0.5, 2.0], times_s=[0.0, 2.0, 5.0])
    c, duration = sample_program(
        [line((0, 0, 0), (100, 0, 0), 600.0)], rapid_mm_min=RAPID, cycle_s=0.01, feed_override=ov
    )
    t = c.t_s
    dist = np.where(t < 2, 10 * t, np.where(t < 5, 20 + 5 * (t - 2), 35 + 20 * (t - 5)))
    assert duration == pytest.approx(5.0 + 65.0 / 20.0, rel=1e-14)
    np.testing.assert_allclose(c.tcp_mm[:, 0], dist, atol=POS_TOL_MM)
    np.testing.assert_allclose(
        c.path_speed_mm_min, np.where(t < 2, 600, np.where(t < 5, 300, 1200))
    )
    assert ov.at(4.99) == 0.5 and ov.at(5.0) == 2.0 and ov.at(-1.0) == 1.0


def test_override_hold_stops_motion_until_release() -> None:
    ov = FeedOverride([1.0, 0.0, 1.0], times_s=[0.0, 1.0, 3.0])
    c, duration = sample_program(
        [line((0, 0, 0), (20, 0, 0), 600.0)], rapid_mm_min=RAPID, cycle_s=0.01, feed_override=ov
    )
    assert duration == pytest.approx(4.0, rel=1e-14)
    held = (c.t_s >= 1.0) & (c.t_s < 3.0)
    np.testing.assert_allclose(c.tcp_mm[held, 0], 10.0, atol=POS_TOL_MM)
    assert np.all(c.path_speed_mm_min[held] == 0.0)


def test_dwell_holds_position_and_ignores_override() -> None:
    segs = [
        line((0, 0, 0), (10, 0, 0), 600.0, n=1),
        dwell((10, 0, 0), 0.5, n=2),
        line((10, 0, 0), (0, 0, 0), 600.0, n=3),
    ]
    c, duration = sample_program(segs, rapid_mm_min=RAPID, cycle_s=0.01)
    assert duration == pytest.approx(2.5, rel=1e-14)
    during = (c.t_s >= 1.0) & (c.t_s < 1.5)
    assert np.count_nonzero(during) == 50
    np.testing.assert_allclose(c.tcp_mm[during], [[10, 0, 0]] * 50, atol=POS_TOL_MM)
    assert np.all(c.kind[during] == MotionKind.DWELL) and np.all(c.line[during] == 2)
    assert np.all(c.velocity_mm_s[during] == 0.0)
    _, slow = sample_program(segs, rapid_mm_min=RAPID, cycle_s=0.01, feed_override=0.5)
    assert slow == pytest.approx(4.5, rel=1e-14)


def test_rapids_use_rapid_rate_and_rapid_override_only() -> None:
    segs = [rapid((0, 0, 0), (0, 30, 40))]  # 50 mm at 100 mm/s
    c, d = sample_program(segs, rapid_mm_min=RAPID, cycle_s=0.0125, feed_override=0.3)
    assert d == pytest.approx(0.5, rel=1e-14)
    np.testing.assert_allclose(c.path_speed_mm_min, RAPID)
    assert np.all(c.kind == MotionKind.RAPID)
    _, d = sample_program(segs, rapid_mm_min=RAPID, cycle_s=0.0125, rapid_override=0.25)
    assert d == pytest.approx(2.0, rel=1e-14)


def test_zero_length_segments_take_no_time() -> None:
    segs = [
        line((0, 0, 0), (10, 0, 0), 600.0),
        line((10, 0, 0), (10, 0, 0), 600.0),
        Segment(
            MotionKind.LINEAR, 5, (10, 0, 0), (10, 0, 0), 600.0, 0.0, STATE, end_abc_deg=(0, 0, 90)
        ),
        dwell((10, 0, 0), 0.0),
        line((10, 0, 0), (10, 5, 0), 600.0),
    ]
    _, d = sample_program(segs, rapid_mm_min=RAPID)
    assert d == pytest.approx(1.5, rel=1e-14)
    chunk, d = sample_program([], rapid_mm_min=RAPID)
    assert d == 0.0 and len(chunk.t_s) == 0


def test_streaming_in_small_pieces_equals_one_piece() -> None:
    segs = [
        line((0, 0, 0), (3, 1, 0), 500.0),
        arc((3, 1, 0), (5, 3, 0), (5, 1, 0), -1, 400.0),
        rapid((5, 3, 0), (5, 3, 10)),
        dwell((5, 3, 10), 0.07),
        line((5, 3, 10), (0, 0, 0), 800.0),
    ] * 3
    limits = AxisLimits((800.0, 600.0, 400.0), junction_deviation_mm=0.0)
    for lim in (None, limits):
        whole, d = sample_program(segs, rapid_mm_min=RAPID, cycle_s=0.004, limits=lim)
        sampler = TrajectorySampler(
            iter(segs),
            rapid_mm_min=RAPID,
            cycle_s=0.004,
            limits=lim,
            chunk_samples=7,
            batch_segments=2,
            lookahead=2,
        )
        chunks = list(sampler)
        assert all(len(ch.t_s) == 7 for ch in chunks[:-1])
        pieces = SampleChunk(*(np.concatenate(p) for p in zip(*chunks, strict=True)))
        assert sampler.duration_s == pytest.approx(d, rel=1e-14)
        for a, b in zip(whole, pieces, strict=True):
            np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-12)


# --- acceleration-limited planner -------------------------------------------------------


def assert_axis_limits(c: SampleChunk, dt: float, acc: Vec3, vel: Vec3 = (math.inf,) * 3) -> None:
    """Finite differences of the sampled velocity stay within the axis accelerations.

    The velocity is exact at each sample and continuous with an acceleration bounded by a_i,
    so |dv_i| <= a_i dt holds exactly; the tolerance covers rounding and the 1e-9 relative
    speed snapping of the planner.
    """
    dv = np.diff(c.velocity_mm_s, axis=0) / dt
    for i in range(3):
        assert np.max(np.abs(dv[:, i])) <= acc[i] * (1 + 1e-6) + 1e-3, f"axis {i}"
        assert np.max(np.abs(c.velocity_mm_s[:, i])) <= vel[i] * (1 + 1e-12)


def test_trapezoid_on_long_line_matches_closed_form() -> None:
    # From rest to rest: t = L/v + v/a when L > v^2/a.
    a, v, length = 400.0, 50.0, 200.0
    lim = AxisLimits((a, 1000.0, 1000.0))
    c, d = sample_program(
        [line((0, 0, 0), (length, 0, 0), 3000.0)], rapid_mm_min=RAPID, cycle_s=0.001, limits=lim
    )
    assert d == pytest.approx(length / v + v / a, rel=1e-12)
    assert c.path_speed_mm_min.max() == pytest.approx(3000.0, rel=1e-12)
    t = c.t_s
    speed = c.path_speed_mm_min / 60.0
    np.testing.assert_allclose(
        speed, np.minimum.reduce([a * t, np.full_like(t, v), a * (d - t)]), atol=1e-9
    )
    assert_axis_limits(c, 0.001, (a, 1000.0, 1000.0))


def test_diagonal_line_uses_axis_limits() -> None:
    # Along (1, 1, 0)/sqrt(2): path acceleration min(a_i * sqrt 2), speed cap vmax_x * sqrt 2.
    acc = (300.0, 900.0, 900.0)
    vel = (30.0, math.inf, math.inf)
    lim = AxisLimits(acc, velocity_mm_s=vel)
    length = 100.0 * math.sqrt(2.0)
    c, d = sample_program(
        [line((0, 0, 0), (100, 100, 0), 3000.0)], rapid_mm_min=RAPID, cycle_s=0.001, limits=lim
    )
    a_path = 300.0 * math.sqrt(2.0)
    v = 30.0 * math.sqrt(2.0)
    assert d == pytest.approx(length / v + v / a_path, rel=1e-12)
    assert_axis_limits(c, 0.001, acc, vel)


def test_short_line_triangle_profile() -> None:
    # L < v^2/a: peak speed sqrt(a L), t = 2 sqrt(L/a).
    lim = AxisLimits((500.0, 500.0, 500.0))
    c, d = sample_program(
        [line((0, 0, 0), (0, 0, 2.0), 3000.0)], rapid_mm_min=RAPID, cycle_s=0.0005, limits=lim
    )
    assert d == pytest.approx(2.0 * math.sqrt(2.0 / 500.0), rel=1e-12)
    assert c.path_speed_mm_min.max() / 60.0 <= math.sqrt(500.0 * 2.0) * (1 + 1e-12)


def test_corner_speed_follows_junction_deviation() -> None:
    # 90 degree corner: theta = 90 deg, bisector (-1, 1, 0)/sqrt 2, junction acceleration a sqrt 2.
    a, v, length, dev = 500.0, 20.0, 50.0, 0.05
    s = math.sin(math.pi / 4)
    vj = math.sqrt(a * math.sqrt(2.0) * dev * s / (1.0 - s))
    lim = AxisLimits((a, a, a), junction_deviation_mm=dev)
    segs = [
        line((0, 0, 0), (length, 0, 0), 60 * v),
        line((length, 0, 0), (length, length, 0), 60 * v),
    ]
    _, d = sample_program(segs, rapid_mm_min=RAPID, cycle_s=0.001, limits=lim)
    one = v / a + (v - vj) / a + (length - v * v / (2 * a) - (v * v - vj * vj) / (2 * a)) / v
    assert d == pytest.approx(2.0 * one, rel=1e-12)
    # Exact stop with no deviation: two rest-to-rest trapezoids.
    lim0 = AxisLimits((a, a, a), junction_deviation_mm=0.0)
    c, d0 = sample_program(segs, rapid_mm_min=RAPID, cycle_s=0.001, limits=lim0)
    assert d0 == pytest.approx(2.0 * (length / v + v / a), rel=1e-12)
    assert_axis_limits(c, 0.001, (a, a, a))


def test_axis_accelerations_bounded_on_mixed_path() -> None:
    # Corners (exact stop), a tangent arc, a helix, a rapid and a dwell.
    acc = (800.0, 500.0, 300.0)
    vel = (120.0, 100.0, 60.0)
    lim = AxisLimits(acc, velocity_mm_s=vel, junction_deviation_mm=0.0)
    segs = [
        line((0, 0, 0), (40, 0, 0), 4000.0),
        arc((40, 0, 0), (50, 10, 0), (40, 10, 0), 1, 4000.0),  # tangent to the line
        line((50, 10, 0), (50, 30, 0), 4000.0),  # tangent to the arc
        arc((50, 30, 0), (50, 30, -4), (45, 30, 0), -2, 3000.0),  # helix, not tangent
        rapid((50, 30, -4), (0, 0, 20)),
        dwell((0, 0, 20), 0.05),
        line((0, 0, 20), (3, 4, 0), 2000.0),
    ]
    for dt in (0.001, 0.0125):
        c, _ = sample_program(segs, rapid_mm_min=20000.0, cycle_s=dt, limits=lim)
        assert_axis_limits(c, dt, acc, vel)
    # The tangent line -> arc -> line junctions keep their speed (no stop between).
    c, _ = sample_program(segs[:3], rapid_mm_min=RAPID, cycle_s=0.001, limits=lim)
    inner = (c.t_s > 0.2) & (c.t_s < c.t_s[-1] - 0.2)
    assert c.path_speed_mm_min[inner].min() > 1000.0


@pytest.mark.parametrize("turns", [1, -1])
@pytest.mark.parametrize("start_deg", [0.0, 30.0])
def test_arc_speed_limited_by_centripetal_acceleration(start_deg: float, turns: int) -> None:
    # v^2 / r <= sqrt(3)/2 a on a full circle, tangential acceleration a/2. Starting at 30 deg,
    # the end of the run-up passes where tangential and centripetal parts add up on one axis.
    a, r = 200.0, 2.0
    lim = AxisLimits((a, a, a))
    p = (r * math.cos(math.radians(start_deg)), r * math.sin(math.radians(start_deg)), 0.0)
    seg = arc(p, p, (0, 0, 0), turns, 6000.0)
    c, d = sample_program([seg], rapid_mm_min=RAPID, cycle_s=0.0005, limits=lim)
    v = math.sqrt(math.sqrt(3) / 2 * a * r)
    assert c.path_speed_mm_min.max() / 60.0 == pytest.approx(v, rel=1e-12)
    assert d == pytest.approx(2 * math.pi * r / v + v / (0.5 * a), rel=1e-12)
    assert_axis_limits(c, 0.0005, (a, a, a))


def test_override_change_is_reached_within_acceleration() -> None:
    # 300 mm at 50 mm/s, a = 500; override 0.5 from 2 s: decelerate 50 -> 25 in 0.05 s.
    a = 500.0
    lim = AxisLimits((a, a, a))
    ov = FeedOverride([1.0, 0.5], times_s=[0.0, 2.0])
    c, d = sample_program(
        [line((0, 0, 0), (300, 0, 0), 3000.0)],
        rapid_mm_min=RAPID,
        cycle_s=0.001,
        limits=lim,
        feed_override=ov,
    )
    assert d == pytest.approx(10.1, rel=1e-12)
    speed = c.path_speed_mm_min / 60.0
    t = c.t_s
    ramp = (t >= 2.0) & (t < 2.05)
    np.testing.assert_allclose(speed[ramp], 50.0 - a * (t[ramp] - 2.0), atol=1e-9)
    np.testing.assert_allclose(speed[(t >= 2.05) & (t < 10.05)], 25.0, rtol=1e-12)
    assert_axis_limits(c, 0.001, (a, a, a))


# --- streaming memory ----------------------------------------------------------------------


def many_segments(n: int) -> Iterator[Segment]:
    for i in range(n):
        x = float(i % 100)
        yield Segment(
            MotionKind.LINEAR, i + 1, (x, 0.0, 0.0), (x + 1.0, 0.0, 0.0), 6000.0, 1000.0, STATE
        )


def peak_memory(n: int, limits: AxisLimits | None) -> tuple[int, int]:
    tracemalloc.start()
    try:
        count = 0
        for chunk in TrajectorySampler(many_segments(n), rapid_mm_min=RAPID, limits=limits):
            count += len(chunk.t_s)
        return tracemalloc.get_traced_memory()[1], count
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("limits", [None, AxisLimits((1e4, 1e4, 1e4))])
def test_memory_does_not_grow_with_program_length(limits: AxisLimits | None) -> None:
    peak_memory(1000, limits)  # load and compile first
    small, n_small = peak_memory(20_000, limits)
    large, n_large = peak_memory(200_000, limits)
    assert n_large > 9 * n_small
    # 10x the program, bounded buffers: the peak stays the same (loose bound).
    assert large < 1.5 * small + 1_000_000


# --- input validation -------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("values", "times"),
    [
        (-0.1, None),
        ([1.0, 0.5], [0.0, 0.0]),
        ([1.0, 0.5], [1.0, 0.5]),
        ([1.0, 0.0], [0.0, 1.0]),
        ([1.0], [0.0, 1.0]),
        (math.nan, None),
        ([1.0, 2.0], None),
    ],
)
def test_bad_override_raises_input_error(values: object, times: object) -> None:
    with pytest.raises(InputError):
        FeedOverride(values, times)  # type: ignore[arg-type]


def test_bad_parameters_raise_input_error() -> None:
    with pytest.raises(InputError, match="cycle_s"):
        TrajectorySampler([], rapid_mm_min=RAPID, cycle_s=0.0)
    with pytest.raises(InputError, match="rapid_mm_min"):
        TrajectorySampler([], rapid_mm_min=-1.0)
    with pytest.raises(InputError, match="feed_override"):
        TrajectorySampler([], rapid_mm_min=RAPID, feed_override="fast")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="accel_mm_s2"):
        AxisLimits((1.0, 0.0, 1.0))
    with pytest.raises(ConfigError, match="junction_deviation_mm"):
        AxisLimits((1.0, 1.0, 1.0), junction_deviation_mm=-1.0)


def test_feed_move_without_feed_is_an_nc_error_with_its_line() -> None:
    segs = [line((0, 0, 0), (1, 0, 0), 600.0, n=3), line((1, 0, 0), (2, 0, 0), 0.0, n=4)]
    with pytest.raises(NCError) as info:
        sample_program(segs, rapid_mm_min=RAPID)
    assert info.value.line == 4 and "feed_mm_min=0.0" in str(info.value)
    bad_arc = Segment(MotionKind.ARC, 9, (0, 0, 0), (1, 0, 0), 600.0, 0.0, STATE, turns=1)
    with pytest.raises(NCError, match="centre"):
        sample_program([bad_arc], rapid_mm_min=RAPID)
    with pytest.raises(NCError, match=r"dwell_s=-1\.0"):
        sample_program([dwell((0, 0, 0), -1.0, n=2)], rapid_mm_min=RAPID)
