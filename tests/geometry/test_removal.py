"""Material removal: the arctangent, the incremental cut against the full envelope, heap growth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnctwin.geometry import Cutter, DexelStock, remove
from cnctwin.geometry._removal_kernels import fast_atan2


def test_fast_atan2_matches_atan2() -> None:
    angles = np.linspace(-math.pi, math.pi, 20001)
    for radius in (1e-3, 1.0, 250.0):
        for a in angles:
            y, x = radius * math.sin(a), radius * math.cos(a)
            assert abs(fast_atan2(y, x) - math.atan2(y, x)) < 3e-7
    assert fast_atan2(0.0, 0.0) == 0.0


PATH = [
    (12.0 + 7.0 * math.cos(a), 12.0 + 7.0 * math.sin(a), -0.5 - 2.5 * a / (3 * math.pi))
    for a in np.linspace(0.0, 3 * math.pi, 240)
]


@pytest.mark.parametrize(
    "cutter",
    [
        Cutter.flat(5.0, 8.0),
        Cutter.ball(5.0, 8.0),
        Cutter.bull(5.0, 1.0, 8.0),
        Cutter.conical(5.0, 8.0, tip_angle_rad=math.pi / 2),
        Cutter.snub(5.0, 1.5, 8.0),
    ],
    ids=["flat", "ball", "bull", "conical", "snub"],
)
def test_incremental_cut_equals_the_full_envelope(cutter: Cutter) -> None:
    # The stock remembers its last cut and subtracts only the new part of the envelope; a
    # stock that forgets it subtracts the whole envelope every time. Same rays either way.
    fast = DexelStock.box((0.0, 0.0, -6.0), (24.0, 24.0, 0.0), 8.0)
    full = DexelStock.box((0.0, 0.0, -6.0), (24.0, 24.0, 0.0), 8.0)
    removed_fast = removed_full = 0.0
    for position in PATH:
        removed_fast += remove(fast, cutter, position).removed_volume_mm3
        full.last_cut = None
        removed_full += remove(full, cutter, position).removed_volume_mm3
    for axis in ("x", "y", "z"):
        a, b = fast.family_arrays(axis), full.family_arrays(axis)
        assert np.array_equal(a[0], b[0])  # interval counts
        for ray in np.flatnonzero(a[0]):
            ra = a[3][a[1][ray] : a[1][ray] + a[0][ray]]
            rb = b[3][b[1][ray] : b[1][ray] + b[0][ray]]
            assert np.array_equal(ra, rb)
    assert removed_fast == pytest.approx(removed_full, rel=1e-12)


def test_removal_record() -> None:
    stock = DexelStock.box((0.0, 0.0, -5.0), (20.0, 20.0, 0.0), 10.0)
    cutter = Cutter.flat(4.0, 10.0)
    first = remove(stock, cutter, (10.0, 10.0, -1.0))
    # A first cut plunges: the cylinder of radius 2 and depth 1, in whole cells.
    assert first.removed_volume_mm3 == pytest.approx(math.pi * 4.0, rel=0.02)
    assert first.contact.bottom_contact
    assert first.family_removed_mm3[2] == pytest.approx(first.removed_volume_mm3, rel=0.03)
    again = remove(stock, cutter, (10.0, 10.0, -1.0))
    assert again.removed_volume_mm3 == 0.0 and len(again.contact.arc_slice) == 0
    side = remove(stock, cutter, (10.5, 10.0, -1.0), feed_dir=(1.0, 0.0))
    c = side.contact
    assert not c.bottom_contact and not c.above_flutes
    assert c.n_extent_mm[0] == pytest.approx(-2.0, abs=0.1)
    assert c.n_extent_mm[1] == pytest.approx(2.0, abs=0.1)
    assert c.z_extent_mm == pytest.approx((4.0, 5.0), abs=1e-6)
    assert np.all((c.arc_lo_rad >= 0) & (c.arc_lo_rad < 2 * math.pi))
    assert np.all((c.arc_hi_rad >= c.arc_lo_rad) & (c.arc_hi_rad <= c.arc_lo_rad + math.pi))
    outside = remove(stock, cutter, (100.0, 10.0, -1.0))
    assert outside.removed_volume_mm3 == 0.0


@pytest.mark.parametrize(
    ("cutter", "depth"),
    [
        (Cutter.conical(6.0, 10.0, tip_angle_rad=math.pi / 2), 2.2),  # a 90 degree V-bit
        (Cutter.conical(6.0, 12.0, tip_angle_rad=math.radians(30.0)), 6.0),
        (Cutter.conical(2.0, 2.0), 1.6),  # CAMotics' vcarve tool, a cone over its length
        (Cutter.snub(4.0, 2.0, 5.5), 3.0),  # CAMotics' slant_test snub nose
    ],
    ids=["vbit90", "vbit30", "camotics-cone", "snub"],
)
def test_cone_plunge_removes_the_frustum(cutter: Cutter, depth: float) -> None:
    # A plunge to depth d removes the frustum pi d (r_t^2 + r_t r_d + r_d^2) / 3 (r_t the tip
    # radius, r_d the radius at d). The rays along x and y count the slab around the tip
    # whole (half a slab of the flat tip too much, in two families of three); the rest is a
    # midpoint sum of ray lengths that vanish continuously at the rim: O(p^2) per mm^2 of the
    # cone's surface.
    rng = np.random.default_rng(5)
    for density in (10.0, 20.0):
        pitch = 1.0 / density
        for _ in range(4):
            stock = DexelStock.box((0.0, 0.0, -8.0), (16.0, 16.0, 0.0), density)
            x, y = 8.0 + rng.uniform(-0.5, 0.5, 2)
            d = depth + rng.uniform(-0.05, 0.05)
            removal = remove(stock, cutter, (x, y, -d))
            tip, rim = cutter.flat_radius_mm, float(cutter.radius_at(d))
            frustum = math.pi * d * (tip * tip + tip * rim + rim * rim) / 3.0
            lateral = math.pi * (tip + rim) * math.hypot(rim - tip, d)
            tol = pitch / 3.0 * math.pi * tip * tip + pitch * pitch * lateral / 2.0
            assert removal.removed_volume_mm3 == pytest.approx(frustum, abs=tol)
            assert removal.contact.bottom_contact == (cutter.kind == "snub")
