"""Engagement maps (Ward 2021, Sec. 3.2): the lookup follows the right visit of a point the path
passes twice, the window never moves backwards, it resynchronises after a jump, and the map's
engagement agrees with closed forms and with the live cut at another feed.

Reference values are closed forms: the path parameter of a program fed at one feed F without
acceleration limits is ``F t / 60``; slot widths and depths are the tool diameter and the
programmed depths; a pass over material already removed has no contact; the chip thickness of a
slot is Martellotti's. Tolerances follow from the dexel pitch ``p`` and the steps (mm): widths
are extents of removed dexels (within ``p``), depths come from z rays (float32), a matched path
parameter lies within one map step of the truth (the map's polyline cuts corners by less than a
step), interval ends within ``(sqrt(2) p + p / 2) / r + s / (2 r)`` rad (docs/dexel.md).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnctwin.errors import ConfigError, DataError, InputError, NCError
from cnctwin.geometry import Cutter, DexelStock, cut
from cnctwin.geometry.engagement_map import (
    EngagementMap,
    MapCursor,
    MapMatch,
    MatchStatus,
    _MapWriter,
    load_engagement_map,
    save_engagement_map,
)
from cnctwin.mechanics import ImmersionIntervals
from cnctwin.nc import interpret_file, interpret_text, sample_program
from cnctwin.simulation import COLUMNS, CutStep, simulate_cut

DENSITY = 10.0  # /mm
PITCH = 1.0 / DENSITY  # mm
STEP = 0.1  # mm of path between map locations
FLAT = Cutter.flat(6.0, 12.0, flutes=3)
R = FLAT.radius_mm
D = FLAT.diameter_mm
LIVE_FEED = 1440.0  # mm/min: 0.3 mm per 12.5 ms cycle, three map steps
CYCLE_S = 0.0125
LIVE_STEP = LIVE_FEED / 60.0 * CYCLE_S


def build(program: str, low: tuple[float, ...], high: tuple[float, ...]) -> EngagementMap:
    stock = DexelStock.box(low, high, DENSITY)
    return EngagementMap.build(interpret_text(program), stock, {0: FLAT}, step_mm=STEP)


def live(program: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(positions (n, 3) mm, s_true (n,) mm, line (n,)) of the program sampled at the twin's
    cycle; every move is a G1 at LIVE_FEED, so the path length is LIVE_FEED t / 60."""
    chunk, _ = sample_program(interpret_text(program), rapid_mm_min=6000.0, cycle_s=CYCLE_S)
    return chunk.tcp_mm, chunk.t_s * LIVE_FEED / 60.0, chunk.line


def track(emap: EngagementMap, positions: np.ndarray, **window: float) -> list[MapMatch]:
    cursor = MapCursor(emap, **window)
    return [cursor.lookup(p) for p in positions]


def corners(program: str) -> np.ndarray:
    """Path parameters (mm) of the program's segment ends."""
    lengths = [seg.length_mm for seg in interpret_text(program)]
    return np.cumsum(lengths)


def assert_follows(matches: list[MapMatch], s_true: np.ndarray, lines: np.ndarray,
                   program: str, noise_mm: float = 0.0) -> None:  # fmt: skip
    """Tracking all the way (a global search first), s within a map step (and the position
    noise) of the truth and never decreasing, and the source line of the live sample away from
    corners."""
    assert matches[0].status == MatchStatus.RESYNCED
    assert all(m.status == MatchStatus.TRACKING for m in matches[1:])
    s = np.array([m.s_mm for m in matches])
    assert np.all(np.diff(s) >= 0.0)
    assert np.max(np.abs(s - s_true)) <= STEP + noise_mm + 1e-9
    ends = corners(program)
    clear = np.min(np.abs(s_true[:, None] - ends[None, :]), axis=1) > 2 * STEP
    got = np.array([m.line for m in matches])
    assert np.array_equal(got[clear], lines[clear])


# A slot along +x at y = 20 (line 3), then back along -y at x = 20 (line 6), crossing the first
# at (20, 20); lines 2, 4 and 5 run in the air around the 30 x 30 mm block.
CROSSING = """G21 G90 G94
G1 X0 Y20 Z-2 F{feed}
G1 X40
G1 Y40
G1 X20
G1 Y0
M2
"""
CROSSING_BLOCK = ((5.0, 5.0, -10.0), (35.0, 35.0, 0.0))


@pytest.fixture(scope="module")
def crossing_map() -> EngagementMap:
    return build(CROSSING.format(feed=600), *CROSSING_BLOCK)


@pytest.mark.parametrize("lookahead_mm", [25.0, 100.0])
def test_self_crossing_path_follows_each_visit(crossing_map: EngagementMap,
                                               lookahead_mm: float) -> None:  # fmt: skip
    # Measured positions carry up to 0.02 mm of noise per axis (less than the 0.05 mm tie):
    # at the crossing the second visit may then be nearer than the first, and a 100 mm window
    # holds both visits; the earlier visit must still win.
    program = CROSSING.format(feed=LIVE_FEED)
    exact, s_true, lines = live(program)
    noise = 0.02
    positions = exact + np.random.default_rng(3).uniform(-noise, noise, exact.shape)
    matches = track(crossing_map, positions, lookahead_mm=lookahead_mm)
    assert_follows(matches, s_true, lines, program, noise_mm=math.sqrt(3.0) * noise)
    ae = np.array([m.ae_mm for m in matches])
    x, y = positions[:, 0], positions[:, 1]
    first = lines == 3
    second = lines == 6
    # First visit, inside the block: a full slot, also where the second visit will cross.
    inside = first & (x > 5.0 + R + PITCH) & (x < 35.0 - R - PITCH)
    assert np.all(np.abs(ae[inside] - D) <= PITCH)
    # Second visit, d mm past the crossing's centre (moving -y): the first slot covers
    # 17 <= y <= 23, so the tool meets material only past y = 17: none for d < 0, a chord
    # 2 sqrt(R^2 - (R - d)^2) for 0 < d < R. The map's discrete positions (step s) leave
    # cusps below a pitch, and the chord is taken at d +- (p + s) for the position error of a
    # dexel extent and of the map's interpolation.
    d = 20.0 - y
    before = second & (d > -R + 0.5) & (d < -0.5)
    assert before.sum() >= 5
    assert np.all(ae[before] <= PITCH)
    assert not any(matches[k].contact for k in np.flatnonzero(before))
    past = second & (d > 0.5) & (d < R - 0.5)
    assert past.sum() >= 5

    def chord(dd: np.ndarray) -> np.ndarray:
        return 2.0 * np.sqrt(np.clip(R * R - (R - np.clip(dd, 0.0, R)) ** 2, 0.0, None))

    slack = PITCH + STEP
    assert np.all(ae[past] >= chord(d[past] - slack) - PITCH)
    assert np.all(ae[past] <= chord(d[past] + slack) + PITCH)
    # Without a hint the whole path is searched and the earlier visit wins; with the window
    # past the first visit, the crossing belongs to the second.
    centre = (20.0, 20.0, -2.0)
    found = crossing_map.lookup(centre)
    assert found.status == MatchStatus.RESYNCED and found.line == 3 and found.ae_mm > D - PITCH
    s_second = float(s_true[second][0])
    again = crossing_map.lookup(centre, s_second)
    assert again.status == MatchStatus.TRACKING and again.line == 6 and again.ae_mm <= PITCH
    # 0.01 mm off the first visit, on the second: the window from just before the crossing
    # holds both, and the earlier one is within the tie of the nearest.
    s_first = float(s_true[first & (positions[:, 0] > 19.0)][0])
    noisy = crossing_map.lookup((20.0, 20.01, -2.0), s_first, lookahead_mm=100.0)
    assert noisy.line == 3 and noisy.ae_mm > D - PITCH


# The same slot three times at the same XY: 2 mm deep along +x (line 3), 3 mm deep back along
# -x (line 5), and a spring pass at 3 mm along +x (line 6) over nothing.
PASSES = """G21 G90 G94
G1 X0 Y10 Z-2 F{feed}
G1 X40
G1 Z-3
G1 X0
G1 X40
M2
"""
PASSES_BLOCK = ((5.0, 0.0, -10.0), (35.0, 20.0, 0.0))


@pytest.fixture(scope="module")
def passes_map() -> EngagementMap:
    return build(PASSES.format(feed=600), *PASSES_BLOCK)


@pytest.mark.parametrize("lookahead_mm", [25.0, 100.0])
def test_passes_at_the_same_xy_follow_in_order(passes_map: EngagementMap,
                                               lookahead_mm: float) -> None:  # fmt: skip
    # A 100 mm window holds two or three passes over every point: the earlier visit wins.
    program = PASSES.format(feed=LIVE_FEED)
    positions, s_true, lines = live(program)
    matches = track(passes_map, positions, lookahead_mm=lookahead_mm)
    assert_follows(matches, s_true, lines, program)
    x = positions[:, 0]
    steady = (x > 5.0 + R + PITCH) & (x < 35.0 - R - PITCH)
    ap = np.array([m.ap_mm for m in matches])
    ae = np.array([m.ae_mm for m in matches])
    contact = np.array([m.contact for m in matches])
    for line, depth in ((3, 2.0), (5, 1.0)):
        sel = steady & (lines == line)
        assert sel.sum() > 50
        assert np.all(contact[sel])
        assert np.all(np.abs(ap[sel] - depth) <= 1e-3)  # z rays: float32 of ~10 mm
        assert np.all(np.abs(ae[sel] - D) <= PITCH)
    spring = steady & (lines == 6)
    assert spring.sum() > 50 and not contact[spring].any()


def test_resync_after_a_jump(passes_map: EngagementMap) -> None:
    emap = passes_map
    ends = corners(PASSES.format(feed=600))  # line 2 ends at ends[0], line 3 at ends[1], ...
    cursor = MapCursor(emap, lookahead_mm=5.0)
    cursor.lookup((10.0, 10.0, -2.0))
    s10 = ends[0] + 10.0
    assert cursor.s_mm == pytest.approx(s10, abs=1e-9)
    # 20 mm ahead, beyond the 5 mm window: a global search finds it, on the same pass.
    jump = cursor.lookup((30.0, 10.0, -2.0))
    assert jump.status == MatchStatus.RESYNCED and jump.line == 3
    assert jump.s_mm == pytest.approx(s10 + 20.0, abs=1e-9)
    step = cursor.lookup((31.0, 10.0, -2.0))
    assert step.status == MatchStatus.TRACKING and step.s_mm == pytest.approx(s10 + 21.0)
    # A jump to a point that passes 2 and 3 share: the first visit ahead of the window wins...
    on_second = cursor.lookup((20.0, 10.0, -3.0))
    assert on_second.status == MatchStatus.RESYNCED and on_second.line == 5
    assert on_second.s_mm == pytest.approx(ends[2] + 20.0, abs=1e-9)
    # ... and once past pass 2, the same point is pass 3.
    cursor.reset(ends[3] + 1.0)
    on_third = cursor.lookup((20.0, 10.0, -3.0))
    assert on_third.status == MatchStatus.RESYNCED and on_third.line == 6
    assert not on_third.contact
    # A jump back (a restart) is allowed to a resync, and says so.
    back = cursor.lookup((8.0, 10.0, -2.0))
    assert back.status == MatchStatus.RESYNCED and back.s_mm == pytest.approx(ends[0] + 8.0)
    # Off the path: no engagement, and the window stays where it was.
    before = cursor.s_mm
    off = cursor.lookup((20.0, 10.0, 20.0))
    assert off.status == MatchStatus.OFF_PATH and not off.contact and off.ae_mm == 0.0
    assert off.distance_mm == pytest.approx(20.0 + 2.0, abs=STEP)
    assert cursor.s_mm == before
    assert cursor.lookup((8.2, 10.0, -2.0)).status == MatchStatus.TRACKING


LINE = "G21 G90\nG1 X0 Y10 Z-2 F600\nG1 X60\nM2\n"


@pytest.fixture(scope="module")
def line_map() -> EngagementMap:
    return build(LINE, (100.0, 100.0, -1.0), (101.0, 101.0, 0.0))  # a path in the air


@settings(max_examples=40, deadline=None)
@given(
    moves=st.lists(
        st.tuples(st.floats(-0.3, 2.0), st.floats(-0.05, 0.05), st.floats(-0.05, 0.05)),
        min_size=1,
        max_size=60,
    )
)
def test_window_never_moves_backwards(line_map: EngagementMap,
                                      moves: list[tuple[float, float, float]]) -> None:  # fmt: skip
    # The tool walks along y = 10, z = -2 from x = 5, forward and back, never more than 0.3 mm
    # behind the furthest point reached (with the lateral noise, within the 0.5 mm tolerance):
    # the match never goes back, and it is the furthest point reached so far (the projection on
    # a straight line ignores lateral noise).
    start = float(corners(LINE)[0])
    cursor = MapCursor(line_map, s_mm=start + 5.0, lookahead_mm=5.0, tie_mm=0.05)
    x = furthest = 5.0
    previous = start + 5.0
    for forward, dy, dz in moves:
        x = min(max(x + forward, furthest - 0.3), 59.0)
        furthest = max(furthest, x)
        match = cursor.lookup((x, 10.0 + dy, -2.0 + dz))
        assert match.status == MatchStatus.TRACKING
        assert match.s_mm >= previous
        assert match.s_mm == pytest.approx(start + furthest, abs=1e-9)
        previous = match.s_mm


def test_warm_up_builds_the_search_ahead_of_the_first_lookup() -> None:
    emap = build(LINE, (100.0, 100.0, -1.0), (101.0, 101.0, 0.0))
    assert "_tree" not in emap.__dict__  # built lazily, by the first global search
    emap.warm_up()
    assert "_tree" in emap.__dict__
    start = float(corners(LINE)[0])
    match = emap.lookup((5.0, 10.0, -2.0))  # and the map answers as before
    assert match.status == MatchStatus.RESYNCED
    assert match.s_mm == pytest.approx(start + 5.0, abs=1e-9)


def slot_h_mean_range(fz: float, step: float) -> tuple[float, float]:
    """Range of Martellotti's mean chip thickness fz (integral of max(sin, 0)) / (b - a) of a
    slot whose contact [a, b] has its ends within the angle tolerance of 0 and pi (mm)."""
    tol = (math.sqrt(2.0) * PITCH + 0.5 * PITCH) / R + step / (2.0 * R)
    values = [
        fz * (math.cos(max(a, 0.0)) - math.cos(min(b, math.pi))) / (b - a)
        for a in np.linspace(-tol, tol, 9)
        for b in np.linspace(math.pi - tol, math.pi + tol, 9)
    ]
    return min(values), max(values)


# A full slot 3 mm deep along +x through a 30 x 20 mm block.
SLOT = "G21 G90\nG0 X0 Y10 Z5\nG1 Z-3 F{feed}\nG1 X40\nM2\n"
SLOT_BLOCK = ((5.0, 0.0, -10.0), (35.0, 20.0, 0.0))


def test_map_agrees_with_the_live_cut_on_a_straight_slot(tmp_path: Path) -> None:
    emap = build(SLOT.format(feed=600), *SLOT_BLOCK)
    stock = DexelStock.box(*SLOT_BLOCK, DENSITY)
    steps: list[CutStep] = []
    rows = np.concatenate(list(simulate_cut(
        interpret_text(SLOT.format(feed=LIVE_FEED)), stock, {0: FLAT}, rapid_mm_min=6000.0,
        cycle_s=CYCLE_S, on_step=steps.append,
    )))  # fmt: skip
    assert len(rows) > 0
    cursor = MapCursor(emap)
    matches = {}
    for row_index, row in enumerate(rows):
        matches[row_index] = cursor.lookup(row[1:4])
    steady = [s for s in steps if 5.0 + R + 1.0 < s.tcp_mm[0] < 35.0 - R - 1.0]
    assert len(steady) > 40
    fz = steady[0].feed_per_tooth_mm
    speed_mm_s = LIVE_FEED / 60.0
    map_mrr = []
    for step in steady:
        m = matches[step.index]
        e = step.engagement
        assert m.status == MatchStatus.TRACKING and m.contact and e.contact
        # Width: each within a pitch of D; depth: z rays, float32.
        assert abs(m.ae_mm - D) <= PITCH and abs(e.ae_mm - D) <= PITCH
        assert m.ap_mm == pytest.approx(3.0, abs=1e-3) and e.ap_mm == pytest.approx(3.0, abs=1e-3)
        # Mean chip thickness: Martellotti's 2 fz / pi for a slot, with the interval ends
        # within the angle tolerance of each step (map 0.1 mm, live 0.3 mm).
        for h, s in ((m.h_mean_per_fz * fz, STEP), (e.h_mean_mm, LIVE_STEP)):
            low, high = slot_h_mean_range(fz, s)
            assert low <= h <= high
        assert m.h_max_per_fz == pytest.approx(1.0)
        # The contact hull within [0, pi]: the whole cutting half.
        assert m.entry_rad == pytest.approx(0.0) and m.exit_rad == pytest.approx(math.pi)
        map_mrr.append(m.cut_area_mm2 * speed_mm_s)
    # MRR = vf D ap on average (whole cells: relative p / D), map and live alike.
    expected = speed_mm_s * D * 3.0
    assert np.mean(map_mrr) == pytest.approx(expected, rel=PITCH / D)
    assert np.mean([s.engagement.mrr_mm3_s for s in steady]) == pytest.approx(
        expected, rel=PITCH / D
    )
    # The bands cover the tool from the tip to ap, and the force model takes them (in m).
    m = matches[steady[len(steady) // 2].index]
    bands = emap.slices(m.nearest)
    assert bands.slice_dz_mm.sum() == pytest.approx(3.0, abs=1e-5)
    assert np.all(bands.slice_dz_mm <= 0.5 + 1e-6)
    force = ImmersionIntervals.from_slices(
        bands.slice_height_mm * 1e-3, bands.slice_dz_mm * 1e-3, bands.interval_slice,
        bands.interval_start_rad, bands.interval_end_rad,
    )  # fmt: skip
    assert force.depth_m == pytest.approx(3e-3, abs=1e-8)
    # Save and load: the same arrays and the same lookups.
    path = tmp_path / "slot.npz"
    save_engagement_map(emap, path)
    loaded = load_engagement_map(path)
    assert loaded.step_mm == emap.step_mm and loaded.pitch_mm == emap.pitch_mm
    for name in ("s_mm", "tcp_mm", "table", "band_ptr", "band_lo_mm", "band_hi_mm",
                 "interval_ptr", "interval_start_rad", "interval_end_rad"):  # fmt: skip
        assert np.array_equal(getattr(loaded, name), getattr(emap, name), equal_nan=True), name
    probe = rows[len(rows) // 2, 1:4]
    assert loaded.lookup(probe, m.s_mm - 1.0) == emap.lookup(probe, m.s_mm - 1.0)


def test_path_parameter_is_the_path_length_whatever_the_feed() -> None:
    # A quarter circle of radius 10 between two lines, and a dwell: the map's locations are
    # a step apart in path length (closed form 5 + 5 pi + 10 + the 5 mm rapid) and do not
    # depend on the feed.
    program = "G21 G90\nG0 Z-5\nG1 X5 F{feed}\nG4 P2\nG3 X15 Y10 I0 J10\nG1 Y20\nM2\n"
    block = ((40.0, 40.0, -1.0), (41.0, 41.0, 0.0))
    slow = build(program.format(feed=100), *block)
    fast = build(program.format(feed=5000), *block)
    total = 5.0 + 5.0 + 0.5 * math.pi * 10.0 + 10.0
    assert slow.s_mm == pytest.approx(np.arange(len(slow)) * STEP)
    assert total - STEP < slow.length_mm < total + 1e-9
    assert np.array_equal(slow.tcp_mm, fast.tcp_mm)
    assert np.array_equal(slow.table, fast.table, equal_nan=True)
    # On the arc, every location lies on the circle about (5, 10).
    arc = slow.column("line") == 5
    radius = np.hypot(slow.tcp_mm[arc, 0] - 5.0, slow.tcp_mm[arc, 1] - 10.0)
    assert np.allclose(radius, 10.0, atol=1e-9)


def test_invalid_input_is_rejected(tmp_path: Path, line_map: EngagementMap) -> None:
    stock = DexelStock.box((0.0, 0.0, -1.0), (1.0, 1.0, 0.0), DENSITY)
    with pytest.raises(InputError, match="step_mm"):
        EngagementMap.build(interpret_text(LINE), stock, {0: FLAT}, step_mm=0.0)
    with pytest.raises(NCError, match="T0"):
        EngagementMap.build(interpret_text(LINE), stock, {1: FLAT})
    with pytest.raises(ConfigError, match="no motion"):
        EngagementMap.build(interpret_text("G21\nM2\n"), stock, {0: FLAT})
    with pytest.raises(InputError, match="lookahead_mm"):
        line_map.lookup((0.0, 10.0, -2.0), 0.0, lookahead_mm=0.0)
    with pytest.raises(InputError, match="tolerance_mm"):
        MapCursor(line_map, tolerance_mm=-1.0)
    with pytest.raises(InputError, match="position_mm"):
        line_map.lookup((0.0, math.nan, 0.0))
    with pytest.raises(InputError, match="column"):
        line_map.column("force")
    with pytest.raises(InputError, match="index"):
        line_map.slices(len(line_map))
    with pytest.raises(DataError, match="not a readable"):
        load_engagement_map(tmp_path / "absent.npz")
    path = tmp_path / "bad.npz"
    np.savez(path, format_version=np.int64(1))
    with pytest.raises(DataError, match="not a readable"):
        load_engagement_map(path)
    save_engagement_map(line_map, path)
    with np.load(path) as data:
        fields = dict(data)
    np.savez(path, **{**fields, "format_version": np.int64(99)})
    with pytest.raises(DataError, match="format 99"):
        load_engagement_map(path)
    np.savez(path, **{**fields, "band_ptr": fields["band_ptr"][:-1]})
    with pytest.raises(DataError, match="band"):
        load_engagement_map(path)


@pytest.mark.validation
def test_real_program_with_three_passes_over_one_contour(shared_data: Path) -> None:
    # The KIT notch program (aluminium 2007-T4, data set README): the same contour (a slot, an
    # arc, two lines and a diagonal back) at 6, 12 and 18 mm, 10 mm flat end mill, F350, in a
    # 75 x 150 x 50 mm block. The map (0.1 mm step) is looked up at the live positions every
    # 12.5 ms (0.073 mm apart) and compared with the live dexel cut of the same program.
    program = shared_data / "gcode" / "siemens_kit_dmc60h" / "AL_2007_T4_Notch_Normal.mpf"
    cutters = {0: Cutter.flat(10.0, 22.0, flutes=4)}
    block = ((0.0, 0.0, -50.0), (75.0, 150.0, 0.0))
    emap = EngagementMap.build(
        interpret_file(program), DexelStock.box(*block, DENSITY), cutters, step_mm=STEP
    )
    stock = DexelStock.box(*block, DENSITY)
    before = stock.volume_mm3()
    rows = np.concatenate(list(simulate_cut(
        interpret_file(program), stock, cutters, rapid_mm_min=30000.0, cycle_s=CYCLE_S
    )))  # fmt: skip
    loss = before - stock.volume_mm3()
    column = {name: rows[:, k] for k, name in enumerate(COLUMNS)}
    cursor = MapCursor(emap)
    matches = [cursor.lookup(p) for p in rows[:, 1:4]]
    # Every position tracked (a global search first), in order, on the live sample's line
    # except within a map step of a segment's end (the map's polyline cuts the corner).
    assert matches[0].status == MatchStatus.RESYNCED
    assert all(m.status == MatchStatus.TRACKING for m in matches[1:])
    assert np.all(np.diff([m.s_mm for m in matches]) >= 0.0)
    ends = np.array([seg.tcp_end_mm for seg in interpret_file(program)])
    at_corner = np.min(np.linalg.norm(rows[:, None, 1:4] - ends[None], axis=2), axis=1) <= STEP
    lines = np.array([m.line for m in matches])
    assert np.array_equal(lines[~at_corner], column["line"][~at_corner])
    # Widths agree within two pitches (each within a pitch of the surface) wherever the live
    # width is steady over +-2 cycles (0.15 mm, more than a map step: the map's locations sit
    # elsewhere along a steep entry or exit).
    ae_live = column["ae_mm"]
    ae_map = np.array([m.ae_mm for m in matches])
    contact = column["contact"] > 0
    assert np.mean(contact == np.array([m.contact for m in matches])) > 0.999
    window = np.lib.stride_tricks.sliding_window_view(ae_live, 5)
    steady = np.zeros(ae_live.size, dtype=bool)
    steady[2:-2] = contact[2:-2] & (np.ptp(window, axis=1) <= PITCH)
    assert steady.sum() > 0.9 * contact.sum()
    assert np.max(np.abs(ae_map - ae_live)[steady]) <= 2 * PITCH
    # Volume: the map's cut area times the live path length per cycle adds up to the live
    # stock's loss (both bookkeep removal exactly; the sum samples the area every 0.073 mm).
    area = np.array([m.cut_area_mm2 for m in matches])
    swept = np.sum(area * column["path_speed_mm_min"] / 60.0 * CYCLE_S)
    assert swept == pytest.approx(loss, rel=1e-3)


def test_bands_merge_the_slices_without_loss() -> None:
    # A ball nose 2 mm deep along +x: every slice of the corner has its own radius and
    # intervals, the cylinder above shares them. Each slice of the live engagement must find
    # its own intervals (to float32) in the band that holds its height, and the bands must stand
    # for the same height of tool.
    ball = Cutter.ball(6.0, 12.0, flutes=2)
    stock = DexelStock.box((0.0, 0.0, -10.0), (40.0, 20.0, 0.0), DENSITY)
    previous = None
    for x in np.arange(-4.0, 12.0, 0.2):
        e = cut(stock, ball, (float(x), 10.0, -4.0), previous, 1.0, 1.0)
        previous = (float(x), 10.0, -4.0)
    assert e.slice_height_mm.size > 20
    writer = _MapWriter(STEP, 0.5, stock.grid.pitch_mm[2])
    writer.add_path(np.zeros(1), np.zeros((1, 3)))
    writer.add(e, ball, 1, 0, False)
    bands = writer.finish(stock.grid.pitch_mm).slices(0)
    assert bands.slice_dz_mm.sum() == pytest.approx(e.slice_dz_mm.sum(), abs=1e-5)
    assert len(bands.slice_height_mm) < e.slice_height_mm.size
    lo = bands.slice_height_mm - bands.slice_dz_mm / 2
    hi = bands.slice_height_mm + bands.slice_dz_mm / 2
    for k, height in enumerate(e.slice_height_mm):
        (band,) = np.flatnonzero((lo <= height) & (height <= hi))
        sel = bands.interval_slice == band
        got = np.column_stack([bands.interval_start_rad[sel], bands.interval_end_rad[sel]])
        want = np.array(e.slice_intervals(k))
        assert got.shape == want.shape
        assert np.allclose(got, want, atol=1e-6)
