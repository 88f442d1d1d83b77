"""Engagement against closed forms: slot, straight walls (up and down milling), entering and
leaving corners, a ramp, a ball nose at depth; volume conservation.

Tolerances follow from the grid pitch ``p`` and the step ``s`` (mm): contact angles are sampled
where rays cross the tool's circle, at most ``sqrt(2) p`` apart, and widened by half a pitch,
so an interval end lies within ``sqrt(2) p / r`` of the truth on the inside; the discrete
positions (Heide 2025, Sec. 2.2) let contact reach ``s / (2 r)`` beyond a wall the tool has
just left. Widths of cut are extents of removed dexels, within a pitch.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnctwin.errors import InputError
from cnctwin.geometry import Cutter, DexelStock, Engagement, cut
from cnctwin.geometry.engagement import cut_path

DENSITY = 10.0  # /mm
PITCH = 1.0 / DENSITY  # mm
CYCLE_S = 0.0125
STEP = 0.2  # mm per cycle: 960 mm/min
FZ = 0.05  # mm
FLAT = Cutter.flat(6.0, 12.0, flutes=3)
R = FLAT.radius_mm


def angle_tol(r: float, step: float = STEP) -> float:
    """Bound on an interval end's error (rad) on a circle of radius r (module notes)."""
    return (math.sqrt(2.0) * PITCH + 0.5 * PITCH) / r + step / (2.0 * r)


def along_x(stock: DexelStock, cutter: Cutter, x0: float, x1: float, y: float, z: float,
            step: float = STEP) -> list[Engagement]:  # fmt: skip
    """Cut positions x0, x0 + step, ... <= x1 at (y, z); the engagement of each."""
    out = []
    previous = None
    for x in np.arange(x0, x1 + 1e-9, step):
        position = (float(x), y, z)
        out.append(cut(stock, cutter, position, previous, FZ, CYCLE_S))
        previous = position
    return out


def merged(e: Engagement, index: int) -> list[tuple[float, float]]:
    """Slice `index`'s intervals with those near 2 pi shifted below 0, joined: (lo, hi) rad."""
    pieces = sorted(
        (a - 2 * math.pi, b - 2 * math.pi) if a > 1.5 * math.pi else (a, b)
        for a, b in e.slice_intervals(index)
    )
    out: list[tuple[float, float]] = []
    for a, b in pieces:
        if out and a <= out[-1][1] + 1e-12:
            out[-1] = (out[-1][0], max(out[-1][1], b))
        else:
            out.append((a, b))
    return out


def h_mean_range(lo: float, hi: float, tol: float) -> tuple[float, float]:
    """Range of Martellotti's mean chip thickness fz (integral of max(sin, 0)) / (hi - lo)
    over contact intervals whose ends are within tol of [lo, hi] rad."""

    def h_mean(a: float, b: float) -> float:
        a0, b0 = max(a, 0.0), min(b, math.pi)
        return FZ * (math.cos(a0) - math.cos(b0)) / (b - a)

    values = [h_mean(a, b) for a in np.linspace(lo - tol, lo + tol, 9)
              for b in np.linspace(hi - tol, hi + tol, 9)]  # fmt: skip
    return min(values), max(values)


def assert_contact(e: Engagement, lo: float, hi: float, tol: float) -> None:
    """Every slice is in contact over [lo, hi] rad, within tol at each end."""
    assert len(e.slice_height_mm) > 0
    for index in range(len(e.slice_height_mm)):
        (got,) = merged(e, index)
        assert got[0] == pytest.approx(lo, abs=tol), (index, got)
        assert got[1] == pytest.approx(hi, abs=tol), (index, got)


def test_full_slot_engages_half_the_tool() -> None:
    stock = DexelStock.box((0.0, 0.0, -10.0), (40.0, 20.0, 0.0), DENSITY)
    steps = along_x(stock, FLAT, -4.0, 20.0, 10.0, -3.0)
    e = steps[-1]
    assert e.contact and not e.bottom_contact and not e.above_flutes
    assert e.feed_mm_min == pytest.approx(STEP / CYCLE_S * 60.0)
    assert e.feed_dir == (1.0, 0.0)
    assert e.ae_mm == pytest.approx(6.0, abs=PITCH)
    assert e.ap_mm == pytest.approx(3.0, abs=1e-4)  # z rays run along the axis: float32 only
    assert e.slice_height_mm.min() >= 0.0 and e.slice_dz_mm.sum() == pytest.approx(3.0)
    assert_contact(e, 0.0, math.pi, angle_tol(R))
    # Chip thickness h = fz sin(phi) over [0, pi]: mean 2 fz / pi, maximum fz.
    assert e.h_max_mm == pytest.approx(FZ)
    low, high = h_mean_range(0.0, math.pi, angle_tol(R))
    assert low <= e.h_mean_mm <= high
    assert low < 2.0 * FZ / math.pi < high
    # MRR = feed x D x ap, on average over the steady steps (whole cells: relative p / D).
    steady = np.mean([s.mrr_mm3_s for s in steps[-60:]])
    assert steady == pytest.approx(STEP / CYCLE_S * 6.0 * 3.0, rel=PITCH / 6.0)


def test_full_slot_is_one_interval_at_any_position_and_direction() -> None:
    # Over many tool positions relative to the grid, feed directions, densities, diameters and
    # steps, every slice of a full slot is in contact over one interval [0, pi] (the x rays'
    # and the y rays' contact points meet at 45 degrees to the grid without a gap).
    rng = np.random.default_rng(3)
    for _ in range(60):
        angle = rng.uniform(0.0, 2.0 * math.pi)
        density = float(rng.choice([7.0, 10.0, 13.0]))
        cutter = Cutter.flat(float(rng.uniform(1.5, 8.0)), 6.0)
        r = cutter.radius_mm
        step = float(rng.uniform(0.02, 0.6))
        stock = DexelStock.box((0.0, 0.0, -3.0), (24.0, 24.0, 0.0), density)
        centre = 12.0 + rng.uniform(-0.5, 0.5, 2)
        feed = np.array([math.cos(angle), math.sin(angle)])
        n = math.ceil((2.0 * r + 1.0) / step)
        previous = None
        for k in range(n, -1, -1):
            position = (*(centre - k * step * feed), -1.5)
            e = cut(stock, cutter, position, previous, FZ, CYCLE_S)
            previous = position
        pitch = 1.0 / density
        tol = (math.sqrt(2.0) * pitch + 0.5 * pitch) / r + step / (2.0 * r)
        assert len(e.slice_height_mm) > 0
        for index in range(len(e.slice_height_mm)):
            (got,) = merged(e, index)
            assert got[0] == pytest.approx(0.0, abs=tol), (angle, density, r, step, got)
            assert got[1] == pytest.approx(math.pi, abs=tol), (angle, density, r, step, got)


def test_walls_of_earlier_passes_are_not_contact() -> None:
    # A slot 3 mm deep, then the next 3 mm layer along the same line, its positions shifted
    # by 0.037 mm: the second pass meets the first one's walls tangentially and takes off
    # only the cusps (at most s^2 / 8R = 0.0017 mm) the first one left between positions. Its
    # engagement is a full slot 3 mm deep, not 6: no contact above 3 mm.
    stock = DexelStock.box((0.0, 0.0, -10.0), (40.0, 20.0, 0.0), DENSITY)
    along_x(stock, FLAT, -4.0, 30.0, 10.0, -3.0)
    second = along_x(stock, FLAT, -3.963, 30.0, 10.0, -6.0)
    for e in second[60:110]:  # x from 8 to 18 mm: the steady part
        assert e.ap_mm == pytest.approx(3.0, abs=1e-4)
        assert e.ae_mm == pytest.approx(6.0, abs=PITCH)
        assert np.all(e.slice_height_mm < 3.0)
        assert_contact(e, 0.0, math.pi, angle_tol(R))
    # A third pass retracing the second at its depth takes off only cusps: material, no cut.
    v0 = stock.volume_mm3()
    third = along_x(stock, FLAT, -3.911, 30.0, 10.0, -6.0)
    removed = sum(e.removed_volume_mm3 for e in third)
    assert 0.0 < removed == pytest.approx(v0 - stock.volume_mm3(), rel=1e-9)
    for e in third[60:110]:
        assert e.ae_mm == 0.0 and e.ap_mm == 0.0 and len(e.interval_slice) == 0
    # A half-depth slot beside an earlier full-depth one, touching its wall (y = 13) with the
    # right side of the tool (phi = pi): a full slot 3 mm deep.
    stock = DexelStock.box((0.0, 0.0, -10.0), (40.0, 30.0, 0.0), DENSITY)
    along_x(stock, FLAT, -4.0, 30.0, 10.0, -6.0)
    beside = along_x(stock, FLAT, -3.963, 30.0, 16.0, -3.0)
    for e in beside[60:110]:
        assert e.ap_mm == pytest.approx(3.0, abs=1e-4)
        assert e.ae_mm == pytest.approx(6.0, abs=PITCH)
        assert_contact(e, 0.0, math.pi, angle_tol(R))


@pytest.mark.parametrize("ae", [0.6, 1.8, 3.0, 4.5])
@pytest.mark.parametrize("side", ["up", "down"])
def test_straight_wall_immersion(ae: float, side: str) -> None:
    # Feed +x along y = 10; up milling has the wall on the left of the feed (+y), down milling
    # on the right (-y) (clockwise spindle, Altintas 2012, Sec. 2.2).
    if side == "up":
        stock = DexelStock.box((0.0, 10.0 + R - ae, -10.0), (40.0, 30.0, 0.0), DENSITY)
    else:
        stock = DexelStock.box((0.0, -10.0, -10.0), (40.0, 10.0 - R + ae, 0.0), DENSITY)
    e = along_x(stock, FLAT, -4.0, 20.0, 10.0, -4.0)[-1]
    phi_e = math.acos(1.0 - 2.0 * ae / FLAT.diameter_mm)
    lo, hi = (0.0, phi_e) if side == "up" else (math.pi - phi_e, math.pi)
    assert e.ae_mm == pytest.approx(ae, abs=PITCH)
    assert e.ap_mm == pytest.approx(4.0, abs=1e-4)
    assert_contact(e, lo, hi, angle_tol(R))
    # Martellotti's mean chip thickness fz (cos phi_st - cos phi_ex) / (phi_ex - phi_st), and
    # the largest, fz sin(phi_e) (fz past pi / 2).
    low, high = h_mean_range(lo, hi, angle_tol(R))
    assert low <= e.h_mean_mm <= high
    peak_angle = min(phi_e + angle_tol(R), math.pi / 2)
    assert FZ * math.sin(min(phi_e - angle_tol(R), math.pi / 2)) <= e.h_max_mm
    assert e.h_max_mm <= FZ * math.sin(peak_angle) + 1e-12


def test_entering_a_block_face() -> None:
    # The face x = 10: contact where the periphery is past it, sin(phi) >= (10 - x_c) / R.
    stock = DexelStock.box((10.0, 0.0, -10.0), (40.0, 20.0, 0.0), DENSITY)
    steps = along_x(stock, FLAT, 5.0, 8.6, 10.0, -3.0)
    x_c = 8.6
    u = (10.0 - x_c) / R
    e = steps[-1]
    assert_contact(e, math.asin(u), math.pi - math.asin(u), angle_tol(R))
    assert e.ae_mm == pytest.approx(2.0 * math.sqrt(R * R - (10.0 - x_c) ** 2), abs=PITCH)


def test_entering_and_leaving_a_corner() -> None:
    # A block x in [10, 20], y >= 10 + R - ae, cut by passes along y = 10 (up milling): the
    # wall's band cos(phi) >= 1 - 2 ae / D, cut by the faces x = 10 and x = 20.
    ae = 1.8
    phi_e = math.acos(1.0 - 2.0 * ae / FLAT.diameter_mm)
    box = ((10.0, 10.0 + R - ae, -10.0), (20.0, 30.0, 0.0))
    entering = along_x(DexelStock.box(*box, DENSITY), FLAT, 5.0, 8.4, 10.0, -3.0)[-1]
    u = (10.0 - 8.4) / R  # material where the periphery is past x = 10: sin(phi) >= u
    assert math.asin(u) < phi_e
    assert_contact(entering, math.asin(u), phi_e, angle_tol(R))
    leaving = along_x(DexelStock.box(*box, DENSITY), FLAT, 5.0, 19.0, 10.0, -3.0)[-1]
    v = (20.0 - 19.0) / R  # material where the periphery is before x = 20: sin(phi) <= v
    assert math.asin(v) < phi_e
    assert_contact(leaving, 0.0, math.asin(v), angle_tol(R))
    gone = along_x(DexelStock.box(*box, DENSITY), FLAT, 5.0, 23.2, 10.0, -3.0)[-1]
    assert not gone.contact and len(gone.interval_slice) == 0 and gone.ae_mm == 0.0


def test_ramp_depth_bottom_and_volume() -> None:
    # Ramp from z = 0 at x = 8 down to z = -2 at x = 28 (5.7 deg), then stop.
    stock = DexelStock.box((0.0, 0.0, -10.0), (40.0, 20.0, 0.0), DENSITY)
    v0 = stock.volume_mm3()
    xs = np.arange(8.0, 28.0 + 1e-9, STEP)
    previous = None
    removed = 0.0
    last = None
    for x in xs:
        position = (float(x), 10.0, -2.0 * (x - 8.0) / 20.0)
        last = cut(stock, FLAT, position, previous, FZ, CYCLE_S)
        removed += last.removed_volume_mm3
        previous = position
    assert last is not None and last.bottom_contact
    assert last.ap_mm == pytest.approx(2.0, abs=1e-4)
    (top,) = merged(last, len(last.slice_height_mm) - 1)  # the top slice cuts a full slot
    assert top[0] == pytest.approx(0.0, abs=angle_tol(R))
    assert top[1] == pytest.approx(math.pi, abs=angle_tol(R))
    # Swept volume of the ramp: at a height d' below the top the tool covered a stadium of
    # length (1 - d'/d) 20 mm: integral = R d L + pi R^2 d. The discrete positions cover less
    # by up to R s d (the stadium's rear end lags a step) and the walls are within half a
    # pitch in one family of three.
    expected = R * 2.0 * 20.0 + math.pi * R * R * 2.0
    tol = R * STEP * 2.0 + 0.5 * PITCH * (2 * 20.0 + 2 * math.pi * R) * 2.0 / 3.0
    assert removed == pytest.approx(expected, abs=tol)
    assert v0 - stock.volume_mm3() == pytest.approx(removed, rel=1e-9)


def test_ball_nose_at_depth() -> None:
    ball = Cutter.ball(6.0, 12.0)
    depth = 1.5
    stock = DexelStock.box((0.0, 0.0, -10.0), (40.0, 20.0, 0.0), DENSITY)
    steps = along_x(stock, ball, -4.0, 20.0, 10.0, -depth)
    e = steps[-1]
    assert e.ap_mm == pytest.approx(depth, abs=1e-4)
    width = 2.0 * math.sqrt(2.0 * R * depth - depth * depth)
    assert e.ae_mm == pytest.approx(width, abs=PITCH)
    assert not e.bottom_contact  # a ball has no flat bottom face
    # Each slice: the ball's circle of radius r(h), engaged over [0, pi] (a slot at every
    # height), and r(h) is the sphere's.
    np.testing.assert_allclose(
        e.slice_radius_mm, np.sqrt(R * R - (R - e.slice_height_mm) ** 2), atol=1e-12
    )
    for index, r in enumerate(e.slice_radius_mm):
        if r < 1.0:
            continue  # near the tip the sampling tolerance exceeds the quarter turn
        (got,) = merged(e, index)
        assert got[0] == pytest.approx(0.0, abs=angle_tol(r, STEP))
        assert got[1] == pytest.approx(math.pi, abs=angle_tol(r, STEP))
    # h_max = fz sin(kappa) at the top of the cut, sin(kappa) = r / R.
    top = e.slice_radius_mm.max()
    assert e.h_max_mm == pytest.approx(FZ * top / R, rel=1e-9)
    assert top == pytest.approx(width / 2, abs=PITCH)
    # MRR = feed x the circular segment's area.
    area = R * R * math.acos((R - depth) / R) - (R - depth) * math.sqrt(
        2.0 * R * depth - depth * depth
    )
    steady = np.mean([s.mrr_mm3_s for s in steps[-60:]])
    assert steady == pytest.approx(STEP / CYCLE_S * area, rel=2 * PITCH / width)


@pytest.mark.parametrize(
    "cutter",
    [
        Cutter.conical(6.0, 10.0, tip_angle_rad=math.pi / 2),
        Cutter.conical(6.0, 10.0, tip_angle_rad=math.pi / 3),
        Cutter.snub(6.0, 2.0, 10.0, tip_angle_rad=math.pi / 2),
    ],
    ids=["vbit90", "vbit60", "snub90"],
)
def test_v_groove(cutter: Cutter) -> None:
    # A cone at depth d engraves a groove of width 2 (r_t + d tan(theta/2)) and cross-section
    # d (2 r_t + d tan(theta/2)); every slice cuts a slot, and sin(kappa) = cos(theta/2).
    depth = 2.037
    stock = DexelStock.box((0.0, 0.0, -10.0), (40.0, 20.0, 0.0), DENSITY)
    steps = along_x(stock, cutter, -4.0, 20.0, 10.013, -depth)
    e = steps[-1]
    slope = math.tan(0.5 * cutter.tip_angle_rad)
    tip = cutter.flat_radius_mm
    width = 2.0 * (tip + depth * slope)
    # The top slab's rays sit half a pitch below the top, where the groove is p tan(theta/2)
    # narrower, and the rays across the feed lie within a pitch of its edges.
    assert e.ae_mm == pytest.approx(width, abs=PITCH * (1.0 + slope))
    # A pointed tip below the z ray nearest the axis (within p / sqrt(2)) is not sampled.
    unseen = 0.0 if tip > 0.0 else PITCH / math.sqrt(2.0) / slope
    assert depth - unseen - 1e-4 <= e.ap_mm <= depth + 1e-4
    assert not e.bottom_contact  # moving sideways, the snub's flat tip only bounds the floor
    assert e.h_max_mm == pytest.approx(FZ * math.cos(0.5 * cutter.tip_angle_rad), rel=1e-9)
    np.testing.assert_allclose(
        e.slice_radius_mm, tip + e.slice_height_mm * slope, rtol=1e-12, atol=1e-12
    )
    for index, r in enumerate(e.slice_radius_mm):
        if r < 2.0 * STEP:
            continue  # circles smaller than the step are new material all round
        (got,) = merged(e, index)
        assert got[0] == pytest.approx(0.0, abs=angle_tol(r))
        assert got[1] == pytest.approx(math.pi, abs=angle_tol(r))
    # MRR = feed x cross-section, less the cusps the discrete positions leave on both walls:
    # s^2 / (8 r) across at radius r, (2/3) of that on average, integrated up the wall from
    # where the circles stop overlapping (r = s/2; below that at most the whole width).
    area = depth * (2.0 * tip + depth * slope)
    floor = max(tip, 0.5 * STEP)
    rim = tip + depth * slope
    cusps = 2.0 * (2.0 / 3.0) * STEP**2 / 8.0 * math.log(rim / floor) / slope
    cusps += (0.5 * STEP) ** 2 / slope if tip < 0.5 * STEP else 0.0
    steady = np.mean([s.mrr_mm3_s for s in steps[-60:]])
    feed_mm_s = STEP / CYCLE_S
    assert feed_mm_s * (area * (1.0 - PITCH / width) - cusps) <= steady
    assert steady <= feed_mm_s * area * (1.0 + PITCH / width)


def test_plunge_removes_the_envelope() -> None:
    # A ball plunged 2 mm: the spherical cap pi d^2 (3R - d) / 3; a flat plunge: the cylinder.
    for cutter, expected in (
        (Cutter.ball(6.0, 12.0), math.pi * 4.0 * (9.0 - 2.0) / 3.0),
        (FLAT, math.pi * 9.0 * 2.0),
    ):
        stock = DexelStock.box((0.0, 0.0, -10.0), (20.0, 20.0, 0.0), 20.0)
        e = cut(stock, cutter, (10.0, 10.0, -2.0), (10.0, 10.0, 1.0), FZ, CYCLE_S)
        # The disc's area in whole cells, within half a pitch of its rim in one family of three.
        tol = 0.5 * 0.05 * 2 * math.pi * R * 2.0
        assert e.removed_volume_mm3 == pytest.approx(expected, abs=tol)
        assert e.feed_dir == (1.0, 0.0)  # no horizontal move: the default frame
        assert e.bottom_contact == (cutter.kind == "flat")


def test_material_above_the_flutes_is_flagged() -> None:
    short = Cutter.flat(6.0, 2.0)
    stock = DexelStock.box((0.0, 0.0, -10.0), (20.0, 20.0, 0.0), DENSITY)
    e = along_x(stock, short, -4.0, 5.0, 10.0, -3.0)[-1]
    assert e.above_flutes
    assert e.ap_mm == pytest.approx(2.0, abs=1e-4)


def test_volume_is_conserved_along_a_winding_path() -> None:
    stock = DexelStock.box((0.0, 0.0, -8.0), (30.0, 30.0, 0.0), DENSITY, capacity=1)
    before = {axis: stock.volume_mm3(axis) for axis in "xyz"}
    total = 0.0
    previous = None
    t = np.linspace(0.0, 4.0 * math.pi, 600)
    for k, angle in enumerate(t):
        z = -1.0 - 3.0 * k / len(t)
        position = (15.0 + 9.0 * math.cos(angle), 15.0 + 9.0 * math.sin(angle), z)
        for cutter in (FLAT, Cutter.ball(4.0, 10.0)):
            total += cut(stock, cutter, position, previous, FZ, CYCLE_S).removed_volume_mm3
        previous = position
    lost = np.mean([before[a] - stock.volume_mm3(a) for a in "xyz"])
    assert total == pytest.approx(lost, rel=1e-9)
    assert stock.overflow_rays("x") + stock.overflow_rays("y") > 0  # capacity 1 overflowed


def test_invalid_arguments_are_rejected() -> None:
    stock = DexelStock.box((0.0, 0.0, -1.0), (1.0, 1.0, 0.0), 2.0)
    with pytest.raises(InputError, match="feed_per_tooth_mm=-1"):
        cut(stock, FLAT, (0, 0, 0), None, -1.0, CYCLE_S)
    with pytest.raises(InputError, match="cycle_s=0"):
        cut(stock, FLAT, (0, 0, 0), None, FZ, 0.0)
    with pytest.raises(InputError, match="position_mm="):
        cut(stock, FLAT, (0, math.nan, 0), None, FZ, CYCLE_S)
    with pytest.raises(InputError, match="previous_position_mm="):
        cut(stock, FLAT, (0, 0, 0), (1, 2), FZ, CYCLE_S)


def test_cut_path_equals_cut_position_by_position() -> None:
    # Batch and streaming: one compiled call over a winding descending path gives the same
    # engagement, field by field, as a call of cut() per position, and the same stock.
    t = np.linspace(0.0, 3.0 * math.pi, 300)
    path = np.column_stack(
        [15.0 + 8.0 * np.cos(t), 15.0 + 8.0 * np.sin(t), -0.5 - 2.5 * t / (3 * math.pi)]
    )
    fz = np.linspace(0.02, 0.08, len(path))
    for cutter in (FLAT, Cutter.ball(4.0, 10.0), Cutter.conical(6.0, 10.0, tip_angle_rad=1.2)):
        a = DexelStock.box((0.0, 0.0, -8.0), (30.0, 30.0, 0.0), DENSITY, capacity=1)
        b = DexelStock.box((0.0, 0.0, -8.0), (30.0, 30.0, 0.0), DENSITY, capacity=1)
        batch = cut_path(a, cutter, path[1:], path[0], fz[1:], CYCLE_S)
        assert len(batch.contact) == len(path) - 1
        for i in range(1, len(path)):
            one = cut(b, cutter, path[i], path[i - 1], float(fz[i]), CYCLE_S)
            other = batch.engagement(i - 1)
            for name in Engagement._fields:
                x, y = getattr(one, name), getattr(other, name)
                if isinstance(x, np.ndarray):
                    assert np.array_equal(x, y), (i, name)
                else:
                    assert x == y or (x != x and y != y), (i, name, x, y)
        assert batch.contact.any() and a.volume_mm3() == b.volume_mm3()
        assert a.overflow_rays("x") + a.overflow_rays("y") > 0  # capacity 1 overflowed
    with pytest.raises(InputError, match="positions_mm of shape"):
        cut_path(a, FLAT, np.zeros((3, 2)), None, FZ, CYCLE_S)
    with pytest.raises(InputError, match="feed_per_tooth_mm"):
        cut_path(a, FLAT, np.zeros((3, 3)), None, [FZ, -1.0, FZ], CYCLE_S)
