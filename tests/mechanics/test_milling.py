"""Milling forces against closed forms: Altintas' mean forces, straight-flute waveforms,
numerical integration along a helical edge, material-removal power, and runout."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from cnctwin.errors import InputError
from cnctwin.geometry import Cutter
from cnctwin.mechanics import (
    CuttingCoefficients,
    ImmersionIntervals,
    flat_end_mill_mean_forces,
    immersion_angles,
    mean_forces,
    milling_forces,
)

# Coefficients of the order of an aluminium alloy (N/mm^2, N/mm), axial terms included.
K = CuttingCoefficients.from_n_mm(800.0, 300.0, 150.0, 25.0, 20.0, 10.0)
OMEGA = 6000.0 * 2.0 * math.pi / 60.0
FZ = 0.08e-3


def _components(m: object) -> np.ndarray:
    return np.array([m.fx_n, m.fy_n, m.fz_n, m.torque_nm, m.power_w])  # type: ignore[attr-defined]


@pytest.mark.parametrize(
    ("width_mm", "down"), [(20.0, False), (5.0, False), (5.0, True), (10.0, True), (15.0, False)]
)
def test_closed_form_mean_agrees_with_the_numerical_integration(
    width_mm: float, down: bool
) -> None:
    # Issue 4: Altintas' closed-form mean forces of a flat end mill against the mean of the
    # waveform summed over 4 teeth x 50 helical slices x 360 angles. The rectangle rule over a
    # revolution misplaces the entry/exit kinks by at most one 1-degree step, far below 0.5 %.
    cutter = Cutter.flat(20.0, 30.0, flutes=4, helix_rad=math.radians(35.0))
    entry, exit_ = immersion_angles(cutter.diameter_m, width_mm * 1e-3, down)
    closed = _components(
        flat_end_mill_mean_forces(K, 4, cutter.radius_m, entry, exit_, 0.004, FZ, OMEGA)
    )
    cut = ImmersionIntervals.from_depths(
        cutter, width_mm * 1e-3, 0.004, down_milling=down, slices=50
    )
    numeric = _components(milling_forces(cutter, K, cut, FZ, OMEGA, steps=360).mean())
    scale = np.abs(closed).copy()
    scale[:3] = np.linalg.norm(closed[:3])  # a small component is judged against the force
    assert np.all(np.abs(numeric - closed) <= 0.005 * scale), (numeric, closed)
    # The general closed form (per slice, any engagement) is the same integral.
    general = _components(mean_forces(cutter, K, cut, FZ, OMEGA))
    np.testing.assert_allclose(general, closed, rtol=1e-9, atol=1e-9)


def test_slot_means_match_the_textbook_slot_formulas() -> None:
    # Altintas 2012, ch. 2, slot (0..pi): Fx = -N a Krc c / 4 - N a Kre / pi,
    # Fy = N a Ktc c / 4 + N a Kte / pi, and with Fz = -Fa: Fz = -N a Kac c / pi - N a Kae / 2.
    n, a, c = 3, 0.005, 0.1e-3
    m = flat_end_mill_mean_forces(K, n, 0.01, 0.0, math.pi, a, c, OMEGA)
    assert m.fx_n == pytest.approx(-n * a * K.krc * c / 4 - n * a * K.kre / math.pi)
    assert m.fy_n == pytest.approx(n * a * K.ktc * c / 4 + n * a * K.kte / math.pi)
    assert m.fz_n == pytest.approx(-n * a * K.kac * c / math.pi - n * a * K.kae / 2)
    # Torque R * sum(Ft): the mean of (Ktc c sin(phi) + Kte) a over 0..pi, N teeth.
    assert m.torque_nm == pytest.approx(
        0.01 * n * a * (2 * K.ktc * c + math.pi * K.kte) / (2 * math.pi)
    )
    assert m.power_w == pytest.approx(m.torque_nm * OMEGA)


def test_straight_flute_single_tooth_waveform_is_the_elemental_force() -> None:
    # Zero helix, one tooth, slot: F(phi) = a [-(Ktc h + Kte) cos - (Krc h + Kre) sin,
    # (Ktc h + Kte) sin - (Krc h + Kre) cos, -(Kac h + Kae)] with h = c sin(phi) on 0 < phi < pi.
    a = 0.003
    cutter = Cutter.flat(16.0, 20.0, flutes=1, helix_rad=0.0)
    wave = milling_forces(
        cutter, K, ImmersionIntervals.from_angles(0.0, math.pi, a, slices=7), FZ, OMEGA
    )
    phi = wave.angle_rad
    cutting = (phi > 0) & (phi < math.pi)
    h = FZ * np.sin(phi)
    ft = np.where(cutting, (K.ktc * h + K.kte) * a, 0.0)
    fr = np.where(cutting, (K.krc * h + K.kre) * a, 0.0)
    fa = np.where(cutting, (K.kac * h + K.kae) * a, 0.0)
    np.testing.assert_allclose(wave.fx_n, -ft * np.cos(phi) - fr * np.sin(phi), atol=1e-9)
    np.testing.assert_allclose(wave.fy_n, ft * np.sin(phi) - fr * np.cos(phi), atol=1e-9)
    np.testing.assert_allclose(wave.fz_n, -fa, atol=1e-9)
    np.testing.assert_allclose(wave.torque_nm, ft * cutter.radius_m, atol=1e-12)


def test_helical_waveform_matches_quadrature_along_the_edge() -> None:
    # Fx(theta) = sum_j integral over z of the elemental force at
    # phi_j(z) = theta + j p - z tan(b) / R, integrated here by adaptive quadrature. The slice
    # sum (midpoint rule) can be wrong by at most half a slice wherever a tooth's edge crosses
    # an interval bound (two per tooth).
    d, n, beta, a, slices = 0.012, 3, math.radians(40.0), 0.010, 200
    cutter = Cutter.flat(12.0, 20.0, flutes=n, helix_rad=beta)
    entry, exit_ = immersion_angles(d, 0.004, down_milling=True)
    wave = milling_forces(
        cutter, K, ImmersionIntervals.from_angles(entry, exit_, a, slices), FZ, OMEGA, steps=72
    )
    r = d / 2

    def dfx(z: float, theta: float) -> float:
        total = 0.0
        for j in range(n):
            phi = (theta + j * 2 * math.pi / n - z * math.tan(beta) / r) % (2 * math.pi)
            if entry <= phi <= exit_:
                h = FZ * math.sin(phi)
                total += -(K.ktc * h + K.kte) * math.cos(phi) - (K.krc * h + K.kre) * math.sin(phi)
        return total

    # Largest elemental force per unit length (h <= c), times half a slice, per crossing.
    per_length = math.hypot(K.ktc * FZ + K.kte, K.krc * FZ + K.kre)
    bound = n * 2 * per_length * (a / slices) / 2
    errors, forces = [], []
    for i in range(0, 72, 5):
        exact, _ = quad(dfx, 0.0, a, args=(wave.angle_rad[i],), limit=200)
        assert abs(wave.fx_n[i] - exact) <= bound, (i, wave.fx_n[i], exact)
        errors.append(wave.fx_n[i] - exact)
        forces.append(exact)
    # Crossing errors of either sign mostly cancel: well under 0.5 % in the RMS.
    assert np.sqrt(np.mean(np.square(errors))) < 0.005 * np.sqrt(np.mean(np.square(forces)))


@pytest.mark.parametrize(("kind", "corner_mm"), [("ball", 6.0), ("bull", 2.0)])
def test_shear_power_equals_ktc_times_removal_rate(kind: str, corner_mm: float) -> None:
    # The shear part of the cutting power is Ktc times the material removal rate, whatever the
    # tool's shape: sum(h db v) over the edge is the chip volume per unit time. With only Ktc,
    # P = Ktc ae_area vf, the area being the cutter's cross-section below ap in a slot.
    d, ap, n = 0.012, 0.004, 2
    cutter = Cutter(
        kind,  # type: ignore[arg-type]
        12.0,
        20.0,
        corner_radius_mm=corner_mm,
        flutes=n,
        helix_rad=math.radians(30),
    )
    only_ktc = CuttingCoefficients(ktc=K.ktc, krc=0.0)
    cut = ImmersionIntervals.from_depths(cutter, d, ap, slices=400)
    rc, r = cutter.corner_radius_m, d / 2
    # Cross-section of the tool envelope (in the plane normal to the feed) up to height ap.
    if kind == "ball":
        area = r**2 * math.acos((r - ap) / r) - (r - ap) * math.sqrt(2 * r * ap - ap**2)
    else:
        corner = rc**2 * math.pi / 4 + (r - rc) * rc  # one side: quarter disc + flat strip
        area = 2 * corner + 2 * r * (ap - rc)
    vf = FZ * n * OMEGA / (2 * math.pi)
    mean = mean_forces(cutter, only_ktc, cut, FZ, OMEGA)
    assert mean.power_w == pytest.approx(K.ktc * area * vf, rel=2e-3)
    wave = milling_forces(cutter, only_ktc, cut, FZ, OMEGA, steps=360).mean()
    assert wave.power_w == pytest.approx(mean.power_w, rel=5e-3)


def test_ball_end_mean_forces_agree_with_the_waveform() -> None:
    # Two implementations of the lead-angle projection (Lee & Altintas 1996): the exact
    # integral over phi and the sum over angles; the axial force of a ball end mill is pushed
    # up (+z) by the radial force near the tip.
    cutter = Cutter.ball(10.0, 20.0, flutes=2, helix_rad=math.radians(30))
    cut = ImmersionIntervals.from_depths(cutter, 0.003, 0.002, down_milling=True, slices=60)
    closed = _components(mean_forces(cutter, K, cut, FZ, OMEGA))
    numeric = _components(milling_forces(cutter, K, cut, FZ, OMEGA, steps=720).mean())
    scale = np.abs(closed).copy()
    scale[:3] = np.linalg.norm(closed[:3])
    assert np.all(np.abs(numeric - closed) <= 0.005 * scale), (numeric, closed)


def test_ball_slices_follow_the_sphere() -> None:
    r = 0.005
    cutter = Cutter.ball(10.0, 20.0, flutes=2, helix_rad=0.3)
    geo = cutter.slices(np.linspace(0.0, 1.5 * r, 31))
    # On the sphere r(z) = sqrt(R^2 - (R - z)^2) and sin(kappa) = r(z) / R; above it a cylinder.
    sphere = geo.z_m < r
    np.testing.assert_allclose(
        geo.radius_m[sphere], np.sqrt(r**2 - (r - geo.z_m[sphere]) ** 2), rtol=1e-12
    )
    np.testing.assert_allclose(np.sin(geo.kappa_rad), geo.radius_m / r, rtol=1e-12)
    # Profile length: a quarter circle plus the cylinder part.
    assert geo.width_m.sum() == pytest.approx(r * math.pi / 2 + 0.5 * r)
    np.testing.assert_allclose(geo.lag_rad, geo.z_m * math.tan(0.3) / r)


def test_runout_can_leave_one_tooth_out_of_the_cut() -> None:
    # Kline & DeVor 1983: with two teeth and a radius difference 2 rho >= c, the small tooth
    # never reaches the material and the large one cuts a chip 2 c sin(phi): the cutter acts as
    # a one-tooth cutter at twice the feed per tooth.
    c = 0.02e-3
    two = Cutter("flat", 10.0, 20.0, flutes=2, helix_rad=0.5, runout_mm=0.015)
    one = Cutter.flat(10.0, 20.0, flutes=1, helix_rad=0.5)
    cut = ImmersionIntervals.from_angles(0.0, math.pi, 0.003, slices=30)
    with_runout = milling_forces(two, K, cut, c, OMEGA, steps=180)
    single = milling_forces(one, K, cut, 2 * c, OMEGA, steps=180)
    np.testing.assert_allclose(with_runout.fx_n, single.fx_n, atol=1e-9)
    np.testing.assert_allclose(with_runout.torque_nm, single.torque_nm, atol=1e-12)


def test_small_runout_keeps_the_mean_and_unbalances_the_teeth() -> None:
    cutter = Cutter.flat(10.0, 20.0, flutes=2, helix_rad=0.5)
    shifted = Cutter("flat", 10.0, 20.0, flutes=2, helix_rad=0.5, runout_mm=0.005)
    cut = ImmersionIntervals.from_angles(0.0, math.pi, 0.003, slices=30)
    c = 0.05e-3
    shear = CuttingCoefficients(ktc=K.ktc, krc=K.krc, kac=K.kac)
    base = milling_forces(cutter, shear, cut, c, OMEGA, steps=360)
    out = milling_forces(shifted, shear, cut, c, OMEGA, steps=360)
    # The chip one tooth misses, the next one takes: the material per revolution, hence the
    # mean shear force, is unchanged (edge forces change where a tooth leaves the cut).
    np.testing.assert_allclose(_components(out.mean()), _components(base.mean()), rtol=1e-9)
    # The larger tooth (tooth 0, lambda = 0) peaks higher than the smaller one.
    half = 180
    assert out.torque_nm[:half].max() > base.torque_nm.max() > out.torque_nm[half:].max()


def test_helical_edge_divides_the_edge_terms_by_cos_beta() -> None:
    # Royandi 2026, Eq. 10-11: dFt = Ktc h dz + Kte dz / cos(beta).
    beta = math.radians(40)
    cutter = Cutter.flat(10.0, 20.0, flutes=3, helix_rad=beta)
    edge_only = CuttingCoefficients(ktc=0.0, krc=0.0, kte=K.kte, kre=K.kre, kae=K.kae)
    cut = ImmersionIntervals.from_depths(cutter, 0.004, 0.003)
    plain = _components(mean_forces(cutter, edge_only, cut, FZ, OMEGA))
    helical = _components(mean_forces(cutter, edge_only, cut, FZ, OMEGA, helical_edge=True))
    np.testing.assert_allclose(helical, plain / math.cos(beta), rtol=1e-12)


def test_immersion_angles_and_intervals() -> None:
    # Up-milling enters at 0 and leaves at arccos(1 - 2 ae / D); down-milling mirrors it.
    assert immersion_angles(0.02, 0.005, False) == pytest.approx((0.0, math.acos(0.5)))
    assert immersion_angles(0.02, 0.005, True) == pytest.approx((math.pi - math.acos(0.5), math.pi))
    assert immersion_angles(0.02, 0.02, True) == pytest.approx((0.0, math.pi))
    cut = ImmersionIntervals.from_depths(
        Cutter.flat(20.0, 30.0, helix_rad=0.0), 0.005, 0.002, slices=4
    )
    assert cut.n_slices == 4
    assert cut.depth_m == pytest.approx(0.002)
    np.testing.assert_allclose(cut.entry_rad, 0.0)
    np.testing.assert_allclose(cut.exit_rad, math.acos(0.5))
    # An interval across 2 pi is split; a ball's lowest slices touch a narrower arc.
    wrapped = ImmersionIntervals.from_intervals([0.0, 0.001], [[(5.0, 7.0)]])
    np.testing.assert_allclose(wrapped.exit_rad, [7.0 - 2 * math.pi, 2 * math.pi])
    np.testing.assert_allclose(wrapped.entry_rad, [0.0, 5.0])
    # Overlapping intervals merge, so no angle is counted twice.
    merged = ImmersionIntervals.from_intervals([0.0, 0.001], [[(1.0, 2.0), (0.5, 1.5), (3.0, 3.1)]])
    np.testing.assert_allclose(merged.entry_rad, [0.5, 3.0])
    np.testing.assert_allclose(merged.exit_rad, [2.0, 3.1])
    # A ball's slice of radius r touches the band R - ae <= y <= R only where r > R - ae,
    # over 0 <= phi <= arccos((R - ae) / r).
    ball = Cutter.ball(20.0, 30.0, helix_rad=0.0)
    cut = ImmersionIntervals.from_depths(ball, 0.006, 0.004, slices=8)
    r = ball.slices(cut.z_bounds_m).radius_m
    touching = r > 0.004
    assert list(np.diff(cut.offsets)) == [int(t) for t in touching]
    np.testing.assert_allclose(cut.exit_rad, np.arccos(0.004 / r[touching]))


def test_frame_and_signs() -> None:
    # Forces on the tool: in a slot the workpiece pushes the tool back against the feed (-x)
    # and toward the up-milling side (+y); positive axial terms pull it down (-z).
    cutter = Cutter.flat(10.0, 20.0, flutes=2, helix_rad=0.5)
    m = mean_forces(cutter, K, ImmersionIntervals.from_angles(0.0, math.pi, 0.002), FZ, OMEGA)
    assert m.fx_n < 0 and m.fy_n > 0 and m.fz_n < 0 and m.torque_nm > 0 and m.power_w > 0
    assert m.resultant_n == pytest.approx(math.hypot(m.fx_n, m.fy_n, m.fz_n))


@pytest.mark.parametrize(
    "make",
    [
        lambda: Cutter("flat", 10.0, 20.0, runout_mm=-1e-3),
        lambda: Cutter("flat", 10.0, 20.0, runout_angle_rad=math.inf),
        lambda: ImmersionIntervals.from_depths(Cutter.flat(10.0, 20.0), 0.02, 0.001),
        lambda: ImmersionIntervals.from_angles(1.0, 0.5, 0.001),
        lambda: ImmersionIntervals.from_angles(0.0, 1.0, -0.001),
        lambda: ImmersionIntervals.from_intervals([0.0, 0.001, 0.0005], [[], []]),
        lambda: CuttingCoefficients(ktc=math.nan, krc=1.0),
        lambda: milling_forces(
            Cutter.flat(10.0, 20.0), K, ImmersionIntervals.from_angles(0, 1, 0.001), -1.0, 1.0
        ),
    ],
)
def test_bad_input_is_an_input_error(make: object) -> None:
    with pytest.raises(InputError):
        make()  # type: ignore[operator]


def test_coefficient_units() -> None:
    k = CuttingCoefficients.from_n_mm(745.1, 360.98, 0.0, 31.49, 21.85, 0.0)
    assert (k.ktc, k.krc, k.kte, k.kre) == pytest.approx((745.1e6, 360.98e6, 31490.0, 21850.0))
    assert k.to_n_mm()["krc_n_mm2"] == pytest.approx(360.98)


def test_immersion_from_a_slice_table_fills_gaps() -> None:
    # A dexel simulation reports only the slices in contact, by centre height and thickness.
    cut = ImmersionIntervals.from_slices(
        heights_m=np.array([0.0025, 0.0005, 0.0015]),
        thickness_m=np.array([0.001, 0.001, 0.001]),
        interval_slice=np.array([1, 2, 0, 0]),
        entry_rad=np.array([0.1, 0.2, 0.3, 2.0]),
        exit_rad=np.array([1.0, 1.1, 1.2, 2.5]),
    )
    np.testing.assert_allclose(cut.z_bounds_m, [0.0, 0.001, 0.002, 0.003])
    assert list(np.diff(cut.offsets)) == [1, 1, 2]
    np.testing.assert_allclose(cut.entry_rad, [0.1, 0.2, 0.3, 2.0])
    gap = ImmersionIntervals.from_slices(
        np.array([0.0005, 0.0035]),
        np.array([0.001, 0.001]),
        np.array([0, 1]),
        np.array([0.0, 0.0]),
        np.array([1.0, 1.0]),
    )
    np.testing.assert_allclose(gap.z_bounds_m, [0.0, 0.001, 0.003, 0.004])
    assert list(np.diff(gap.offsets)) == [1, 0, 1]
    with pytest.raises(InputError):
        ImmersionIntervals.from_slices(
            np.array([0.001, 0.0015]),
            np.array([0.001, 0.001]),
            np.array([0]),
            np.array([0.0]),
            np.array([1.0]),
        )


def test_cutter_from_a_configured_tool() -> None:
    from cnctwin.config.tools import ToolConfig

    tool = ToolConfig(
        number=3, kind="bull", diameter_mm=10.0, corner_radius_mm=1.0, flutes=4, helix_deg=30.0
    )
    cutter = Cutter.from_tool_config(tool, flute_length_mm=20.0)
    assert (cutter.kind, cutter.flutes) == ("bull", 4)
    # The SI views the force model reads: m, at the one unit boundary.
    assert (cutter.diameter_m, cutter.corner_radius_m) == pytest.approx((0.010, 0.001))
    assert cutter.helix_rad == pytest.approx(math.radians(30.0))
    ball = Cutter.from_tool_config(
        ToolConfig(number=1, kind="ball", diameter_mm=6.0), flute_length_mm=12.0
    )
    assert ball.corner_radius_m == pytest.approx(0.003)


@pytest.mark.parametrize(("kind", "tip_mm"), [("conical", 0.0), ("snub", 1.0)])
@pytest.mark.parametrize("angle_deg", [60.0, 90.0])
def test_cone_mean_torque_in_a_v_groove(kind: str, tip_mm: float, angle_deg: float) -> None:
    # A V-bit in a full slot 1.5 mm deep, shear coefficients only. Per element the chip is
    # h = fz sin(phi) sin(kappa) over a width dz / sin(kappa) (Lee & Altintas 1996), so the
    # tangential force Ktc fz sin(phi) dz does not depend on the lead angle: the mean torque
    # is N/(2 pi) * 2 Ktc fz * integral of r(z) dz, with r(z) = r_t + z tan(theta/2).
    theta = math.radians(angle_deg)
    depth = 1.5e-3
    k = CuttingCoefficients(ktc=800e6, krc=300e6)
    cutter = Cutter(
        kind,  # type: ignore[arg-type]
        12.0,
        30.0,
        flutes=2,
        helix_rad=0.0,
        tip_diameter_mm=tip_mm,
        tip_angle_rad=theta,
    )
    immersion = ImmersionIntervals.from_angles(0.0, math.pi, depth, slices=400)
    mean = mean_forces(cutter, k, immersion, FZ, OMEGA)
    r_t = 0.5 * tip_mm * 1e-3
    integral_r = r_t * depth + 0.5 * depth**2 * math.tan(theta / 2)
    expected = cutter.flutes / (2 * math.pi) * 2.0 * k.ktc * FZ * integral_r
    assert mean.torque_nm == pytest.approx(expected, rel=1e-4)


def test_cone_slices_follow_the_profile() -> None:
    # Widths along the edge sum to the cone's slant length plus the cylinder above it.
    theta = math.radians(60.0)
    cutter = Cutter.conical(6.0, 10.0, tip_angle_rad=theta, helix_rad=0.0)
    height = 3e-3 / math.tan(theta / 2)
    z = np.linspace(0.0, height + 2e-3, 37)
    slices = cutter.slices(z)
    assert slices.width_m.sum() == pytest.approx(height / math.cos(theta / 2) + 2e-3)
    on_cone = slices.z_m < height
    assert np.allclose(slices.kappa_rad[on_cone], math.pi / 2 - theta / 2)
    assert np.allclose(slices.radius_m[on_cone], slices.z_m[on_cone] * math.tan(theta / 2))
    assert np.allclose(slices.radius_m[~on_cone], 3e-3)
