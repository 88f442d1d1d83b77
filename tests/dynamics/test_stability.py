"""Stability lobes: zero-order approximation and semi-discretization against closed forms,
the benchmarks of ../shared/data/stability/NOTES.md, and an independent integrator.

NOTES.md sections: 1, Insperger & Stépán's semi-discretization benchmark (N = 2, Kt = 6e8,
Kn = 2e8 N/m^2, 922 Hz, zeta = 0.011, k = 1340049.648 N/m, down-milling, a/D = 1 and 0.05,
40 steps per tooth period); 4, Altintas's 2-DOF orthogonal-cutting example (absolute critical
depth 7.185 mm, 1-DOF variant 7.319 mm).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from cnctwin.dynamics.stability import (
    MillingProcess,
    OrthogonalProcess,
    ProcessDamping,
    ToolDynamics,
    ToolMode,
    floquet_multipliers,
    sdm_lobes,
    zoa_absolute_depth,
    zoa_lobes,
)
from cnctwin.errors import InputError
from cnctwin.mechanics import CuttingCoefficients

RPM = math.pi / 30.0  # rad/s per rpm

# NOTES.md section 1
FN_HZ, ZETA, K = 922.0, 0.011, 1340049.648
KT, KN, TEETH = 6e8, 2e8, 2
MODE = ToolMode.from_hz(FN_HZ, ZETA, stiffness_n_m=K)
X_ONLY = ToolDynamics.from_xy(x=[MODE])
SYMMETRIC = ToolDynamics.from_xy(x=[MODE], y=[MODE])
COEFFICIENTS = CuttingCoefficients(KT, KN)


def milling(immersion: float, teeth: int = TEETH, down: bool = True) -> MillingProcess:
    return MillingProcess.from_immersion(teeth, COEFFICIENTS, immersion, down_milling=down)


# NOTES.md section 4: modes at +30 and -45 degrees from y, the chip thickening along y.
ORTHO_MODES = (
    ToolMode.from_hz(250.0, 0.012, stiffness_n_m=2.26e8, direction_rad=math.radians(60.0)),
    ToolMode.from_hz(150.0, 0.010, stiffness_n_m=2.13e8, direction_rad=math.radians(135.0)),
)
KF = 1e9


# ----------------------------------------------------------------------------------------
# Directional matrices


def altintas_alpha(entry: float, exit_: float, kr: float) -> np.ndarray:
    """Altintas 2012, Eq. 3.53 (Altintas & Budak 1995): the integrated directional factors."""

    def at(p: float) -> np.ndarray:
        return 0.5 * np.array(
            [
                [math.cos(2 * p) - 2 * kr * p + kr * math.sin(2 * p),
                 -math.sin(2 * p) - 2 * p + kr * math.cos(2 * p)],
                [-math.sin(2 * p) + 2 * p + kr * math.cos(2 * p),
                 -math.cos(2 * p) - 2 * kr * p - kr * math.sin(2 * p)],
            ]
        )  # fmt: skip

    return at(exit_) - at(entry)


@pytest.mark.parametrize(("immersion", "down"), [(1.0, True), (0.5, True), (0.3, False)])
def test_mean_directional_matrix_is_altintas_alpha(immersion: float, down: bool) -> None:
    process = milling(immersion, down=down)
    expected = (
        TEETH * KT / (4 * math.pi) * altintas_alpha(process.entry_rad, process.exit_rad, KN / KT)
    )
    assert process.mean_matrix() == pytest.approx(expected, rel=1e-12, abs=1e-3)
    # The semi-discretization's step means average to the same matrix.
    assert process.step_matrices(40).mean(axis=0) == pytest.approx(expected, abs=1e-3)


def test_step_matrices_are_step_averages_of_the_tooth_sum() -> None:
    # Insperger & Stépán 2004, Sec. 5: H(t) = sum_j g(phi_j) M(phi_j); averaged per step by
    # fine midpoint quadrature here, exactly in the library.
    process = milling(0.05)
    steps, fine = 40, 2000
    period = 2 * math.pi / TEETH
    t = (np.arange(steps * fine) + 0.5) / (steps * fine) * period
    total = np.zeros((t.size, 2, 2))
    for j in range(TEETH):
        phi = (t + 2 * math.pi * j / TEETH) % (2 * math.pi)
        cutting = (phi > process.entry_rad) & (phi < process.exit_rad)
        total += cutting[:, None, None] * process.directional_matrix(phi)
    expected = total.reshape(steps, fine, 2, 2).mean(axis=1)
    assert process.step_matrices(steps) == pytest.approx(expected, abs=2e-4 * KT)


# ----------------------------------------------------------------------------------------
# Closed forms


def test_zoa_slot_one_dof_is_the_averaged_closed_form() -> None:
    # NOTES.md: a = 2 k zeta (1 + zeta) / (N Kn / 4) = 0.298 mm, at the frequency of the
    # minimum of Re G, fn sqrt(1 + 2 zeta).
    depth, chatter_hz = zoa_absolute_depth(X_ONLY, milling(1.0))
    assert depth == pytest.approx(2 * K * ZETA * (1 + ZETA) / (TEETH * KN / 4), rel=1e-6)
    assert depth == pytest.approx(0.298e-3, abs=0.5e-6)
    assert chatter_hz == pytest.approx(FN_HZ * math.sqrt(1 + 2 * ZETA), rel=1e-4)


def oriented_frf(w: float, modes: tuple[ToolMode, ...]) -> complex:
    """Tlusty's oriented FRF sum cos^2(theta_i) G_i(w), theta_i from the chip direction y."""
    total = 0j
    for mode in modes:
        theta = mode.direction_rad - math.pi / 2
        r = w / mode.frequency_rad_s
        total += math.cos(theta) ** 2 / (
            mode.stiffness_n_m * (1 - r * r + 2j * mode.damping_ratio * r)
        )
    return total


@pytest.mark.parametrize(("modes", "expected_mm"), [(ORTHO_MODES, 7.185), (ORTHO_MODES[:1], 7.319)])
def test_orthogonal_absolute_depth_is_the_textbook_value(
    modes: tuple[ToolMode, ...], expected_mm: float
) -> None:
    # NOTES.md section 4: a_lim = -1 / (2 Kf min Re G); min Re G = -6.959e-8 m/N at 252.98 Hz.
    found = minimize_scalar(
        lambda w: oriented_frf(w, modes).real, bounds=(2 * math.pi * 240, 2 * math.pi * 270),
        method="bounded", options={"xatol": 1e-6},
    )  # fmt: skip
    closed = -1 / (2 * KF * found.fun)
    assert closed * 1e3 == pytest.approx(expected_mm, abs=5e-4)
    depth, chatter_hz = zoa_absolute_depth(ToolDynamics(modes), OrthogonalProcess(KF))
    assert depth == pytest.approx(closed, rel=1e-6)
    assert chatter_hz == pytest.approx(found.x / (2 * math.pi), rel=1e-4)
    if len(modes) == 2:
        assert found.fun == pytest.approx(-6.959e-8, rel=2e-4)
        assert chatter_hz == pytest.approx(252.98, abs=0.01)


def sdof_turning_lobe_bottom(k: int) -> tuple[float, float]:
    """Spindle speed (rad/s) and depth (m) of the bottom of lobe k, 1-DOF turning (closed form).

    The minimum of Re G lies at w* = wn sqrt(1 + 2 zeta); there epsilon = 3 pi + 2 psi,
    psi = atan2(Im G, Re G), and w* T = epsilon + 2 pi k with T = 2 pi / Omega.
    """
    mode = ORTHO_MODES[0]
    w = mode.frequency_rad_s * math.sqrt(1 + 2 * mode.damping_ratio)
    g = oriented_frf(w, (mode,))
    epsilon = 3 * math.pi + 2 * math.atan2(g.imag, g.real)
    return 2 * math.pi * w / (epsilon + 2 * math.pi * k), -1 / (2 * KF * g.real)


def test_sdof_turning_lobe_bottoms_by_both_methods() -> None:
    # Constant coefficients: the zero-order solution is exact, so both methods must land on
    # the closed-form lobe bottoms; the semi-discretization within its O(dt^2) error (auto
    # steps: 20 per vibration cycle, about 1 %).
    tool = ToolDynamics(ORTHO_MODES[:1])
    speeds, depth = zip(*(sdof_turning_lobe_bottom(k) for k in (1, 2, 3)), strict=True)
    zoa = zoa_lobes(tool, OrthogonalProcess(KF), speeds)
    assert zoa.critical_depth_m == pytest.approx(depth, rel=1e-3)
    sdm = sdm_lobes(tool, OrthogonalProcess(KF), speeds, max_depth_m=0.02, depth_step_m=2e-3)
    assert sdm.critical_depth_m == pytest.approx(depth, rel=0.015)
    assert sdm.chatter_frequency_hz == pytest.approx(zoa.chatter_frequency_hz, rel=2e-3)
    assert set(sdm.bifurcation) == {"hopf"}


def test_orthogonal_two_dof_lobes_of_both_methods_agree() -> None:
    tool, process = ToolDynamics(ORTHO_MODES), OrthogonalProcess(KF)
    speeds = np.array([4045.0, 5500.0, 8500.0, 12000.0]) * RPM
    zoa = zoa_lobes(tool, process, speeds)
    assert zoa.min_critical_depth_m == pytest.approx(7.185e-3, rel=1e-3)
    sdm = sdm_lobes(tool, process, speeds, max_depth_m=0.02, depth_step_m=2e-3)
    assert sdm.critical_depth_m == pytest.approx(zoa.critical_depth_m, rel=0.015)


# ----------------------------------------------------------------------------------------
# Zero-order approximation and semi-discretization in milling


def test_four_tooth_slotting_is_time_invariant_so_both_methods_agree() -> None:
    # With an even number of teeth >= 4 in a slot the directional matrix is constant, so the
    # zero-order approximation is exact: the methods may differ only by the semi-
    # discretization error (auto steps, < 1 %) and the ZOA's interpolation along its
    # frequency grid; 1.5 % over 5000-25000 rpm.
    process = milling(1.0, teeth=4)
    h = process.step_matrices(40)
    assert np.abs(h - h[0]).max() < 1e-12 * KT
    speeds = np.linspace(5000.0, 25000.0, 17) * RPM
    zoa = zoa_lobes(SYMMETRIC, process, speeds)
    sdm = sdm_lobes(SYMMETRIC, process, speeds, max_depth_m=1e-3)
    assert sdm.critical_depth_m == pytest.approx(zoa.critical_depth_m, rel=0.015)
    assert sdm.chatter_frequency_hz == pytest.approx(zoa.chatter_frequency_hz, rel=2e-3)


def test_two_tooth_slotting_agrees_at_the_lobe_bottoms() -> None:
    # The benchmark's slot (N = 2, symmetric 2-DOF): H(t) varies at twice the tooth
    # frequency and the ZOA keeps only its mean. Near the lobe bottoms, where the chatter
    # frequency sits on the resonance, the methods agree (measured: 3.5 % at most where the
    # ZOA depth is below 1.5 times its absolute limit, 0.5 % on the lowest depth); the lobe
    # tops differ by up to 15 %.
    process = milling(1.0)
    speeds = np.linspace(15000.0, 25000.0, 21) * RPM
    zoa = zoa_lobes(SYMMETRIC, process, speeds)
    absolute, _ = zoa_absolute_depth(SYMMETRIC, process)
    sdm = sdm_lobes(SYMMETRIC, process, speeds, max_depth_m=5e-4)
    bottoms = zoa.critical_depth_m < 1.5 * absolute
    assert bottoms.sum() >= 8
    assert sdm.critical_depth_m[bottoms] == pytest.approx(zoa.critical_depth_m[bottoms], rel=0.05)
    assert sdm.min_critical_depth_m == pytest.approx(absolute, rel=0.01)
    assert sdm.chatter_frequency_hz[bottoms] == pytest.approx(
        zoa.chatter_frequency_hz[bottoms], rel=5e-3
    )


def test_up_and_down_milling_share_zoa_lobes_for_a_symmetric_tool() -> None:
    # The eigenvalues of alpha depend on the swept angle only (Altintas 2012, ch. 3).
    speeds = np.linspace(8000.0, 12000.0, 9) * RPM
    down = zoa_lobes(SYMMETRIC, milling(0.3, down=True), speeds)
    up = zoa_lobes(SYMMETRIC, milling(0.3, down=False), speeds)
    assert up.critical_depth_m == pytest.approx(down.critical_depth_m, rel=1e-9)


def test_low_immersion_flip_lobes_that_zoa_misses() -> None:
    # NOTES.md section 1, a/D = 0.05 down-milling, 1-DOF in x, 40 steps per tooth period.
    # Intermittent cutting adds period-doubling lobes: a multiplier leaves the unit circle
    # at -1, the chatter frequency is then an odd multiple of half the tooth frequency, and
    # the principal flip lobe sits where 3/2 f_tooth = fn (Insperger & Stépán 2004;
    # Davies et al. 2002): 2 fn / 3 * 60 / N = 18440 rpm. The averaged ZOA cannot see it.
    process = milling(0.05)
    rpm = np.linspace(14500.0, 21000.0, 27)
    sdm = sdm_lobes(X_ONLY, process, rpm * RPM, max_depth_m=0.01, steps=40)
    zoa = zoa_lobes(X_ONLY, process, rpm * RPM)
    flip = np.array([kind == "flip" for kind in sdm.bifurcation])
    assert flip.sum() >= 8
    tooth_hz = rpm * TEETH / 60.0
    ratio = sdm.chatter_frequency_hz[flip] / tooth_hz[flip]
    assert ratio == pytest.approx(np.round(ratio - 0.5) + 0.5, abs=1e-6)
    bottom = int(np.argmin(np.where(flip, sdm.critical_depth_m, np.inf)))
    assert rpm[bottom] == pytest.approx(2 * FN_HZ / 3 * 60 / TEETH, rel=0.05)
    assert zoa.critical_depth_m[bottom] > 2.5 * sdm.critical_depth_m[bottom]
    assert set(zoa.bifurcation) == {"hopf"}
    # The flip lobe's bottom lies far below the ZOA's absolute limit.
    assert sdm.critical_depth_m[bottom] < 0.8 * zoa_absolute_depth(X_ONLY, process)[0]


# ----------------------------------------------------------------------------------------
# An independent reference: the monodromy matrix of the 1-DOF milling DDE by RK4


def rk4_spectral_radius(process: MillingProcess, rpm: float, depth: float, per: int = 100) -> float:
    """Spectral radius of the 1-DOF (x) delay equation's period map, by the method of steps.

    m x'' + c x' + k x = -a w(t) (x(t) - x(t - T)), w = -H_xx (Insperger & Stépán 2004):
    classical RK4 on a grid repeating every tooth period with the entry and exit times as
    nodes; the delayed state at RK4 midpoints by cubic Hermite interpolation of the stored
    (x, x') of the previous period. Each basis vector of the history (x, x' at the M + 1
    nodes of the previous period) is propagated over one period.
    """
    wn = MODE.frequency_rad_s
    omega = rpm * RPM
    period = 2 * math.pi / (TEETH * omega)
    nodes = {0.0, period}
    for j in range(TEETH):
        for angle in (process.entry_rad, process.exit_rad):
            nodes.add(((angle - 2 * math.pi * j / TEETH) % (2 * math.pi) / omega) % period)
    nodes = sorted(nodes)
    grid = [0.0]
    for low, high in zip(nodes[:-1], nodes[1:], strict=True):
        if high - low > 1e-12 * period:
            count = max(2, math.ceil(per * (high - low) / period))
            grid += list(np.linspace(low, high, count + 1)[1:])
    times = np.array(grid)
    m = times.size - 1

    def w(t: float) -> float:
        total = 0.0
        for j in range(TEETH):
            phi = (omega * t + 2 * math.pi * j / TEETH) % (2 * math.pi)
            if process.entry_rad < phi < process.exit_rad:
                total -= float(process.directional_matrix(phi)[0, 0])
        return total

    def rate(t: float, x: np.ndarray, v: np.ndarray, delayed: np.ndarray) -> tuple:
        force = -depth * w(t) * (x - delayed) * wn * wn / K
        return v, -2 * ZETA * wn * v - wn * wn * x + force

    size = 2 * (m + 1)
    identity = np.eye(size)
    xs = [identity[i] for i in range(m + 1)]
    vs = [identity[m + 1 + i] for i in range(m + 1)]
    for i in range(m):
        t, h = times[i], times[i + 1] - times[i]
        inside = 1e-9 * h  # w on the step's own side of a node
        x, v = xs[-1], vs[-1]
        xa, va, xb, vb = xs[i], vs[i], xs[i + 1], vs[i + 1]
        xm = 0.5 * (xa + xb) + h * (va - vb) / 8
        k1 = rate(t + inside, x, v, xa)
        k2 = rate(t + h / 2, x + h / 2 * k1[0], v + h / 2 * k1[1], xm)
        k3 = rate(t + h / 2, x + h / 2 * k2[0], v + h / 2 * k2[1], xm)
        k4 = rate(t + h - inside, x + h * k3[0], v + h * k3[1], xb)
        xs.append(x + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]))
        vs.append(v + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]))
    period_map = np.vstack(xs[m:] + vs[m:])
    return float(np.abs(np.linalg.eigvals(period_map)).max())


@pytest.mark.parametrize(
    ("immersion", "rpm", "kind"),
    [
        (1.0, 16000.0, "hopf"),
        (1.0, 12000.0, "flip"),
        (0.05, 18000.0, "flip"),
        (0.05, 12250.0, "hopf"),
    ],
)
def test_sdm_boundary_matches_an_independent_integrator(
    immersion: float, rpm: float, kind: str
) -> None:
    # The semi-discretization (80 steps) must put the boundary where the RK4 period map's
    # spectral radius crosses 1: stable 2 % below, unstable 2 % above (the two differ by
    # <= 1 % here, measured).
    process = milling(immersion)
    lobes = sdm_lobes(X_ONLY, process, [rpm * RPM], max_depth_m=0.01, steps=80)
    depth = float(lobes.critical_depth_m[0])
    assert lobes.bifurcation == (kind,)
    assert rk4_spectral_radius(process, rpm, 0.98 * depth) < 1.0
    assert rk4_spectral_radius(process, rpm, 1.02 * depth) > 1.0


# ----------------------------------------------------------------------------------------
# Process damping


def test_effective_process_damping_has_the_papers_magnitude() -> None:
    # Royandi 2026, Eq. 3 and Sec. 4.2/6.4: C_pd = 3e9 N/m^2; a 12 mm cutter at 7500 rpm,
    # ap = 2.5 mm, fz = 0.075 mm: C_eff = C_pd a fz / Vc = 119 N s/m, inside the paper's
    # "10^2 - 10^3 N s/m".
    damping = ProcessDamping(3e9, 0.075e-3, 0.012)
    speed = 7500 * RPM
    value = damping.effective_damping(2.5e-3, speed)
    assert value == pytest.approx(3e9 * 2.5e-3 * 0.075e-3 / (speed * 0.006))
    assert 100.0 < value < 1000.0


def test_process_damping_in_turning_is_the_damped_structures_exact_limit() -> None:
    # With process damping the critical depth a* at a speed must be the exact (ZOA) limit of
    # the structure whose damping includes C_eff(a*): a fixed point, checked at two speeds.
    # The damping acts along the chip direction, here the mode's own direction.
    mode = ToolMode.from_hz(250.0, 0.012, stiffness_n_m=2.26e8, direction_rad=math.pi / 2)
    process = OrthogonalProcess(KF)
    damping = ProcessDamping(1e10, 0.1e-3, 0.05)
    speeds = np.array([1200.0, 6000.0]) * RPM
    plain = sdm_lobes(ToolDynamics((mode,)), process, speeds, max_depth_m=0.1, depth_step_m=2e-3)
    damped = sdm_lobes(
        ToolDynamics((mode,)), process, speeds, max_depth_m=0.1, depth_step_m=2e-3,
        damping=damping,
    )  # fmt: skip
    for speed, depth in zip(speeds, damped.critical_depth_m, strict=True):
        extra = damping.effective_damping(depth, speed)
        zeta = mode.damping_ratio + extra / (2 * mode.mass_kg * mode.frequency_rad_s)
        stiffer = ToolMode(mode.frequency_rad_s, zeta, mode.stiffness_n_m, mode.direction_rad)
        exact = zoa_lobes(ToolDynamics((stiffer,)), process, [speed]).critical_depth_m[0]
        assert depth == pytest.approx(exact, rel=0.015)
    gain = damped.critical_depth_m / plain.critical_depth_m
    assert gain[0] > gain[1] > 1.0  # C_eff grows as the cutting speed falls


# ----------------------------------------------------------------------------------------
# Multipliers, modes and errors


def test_floquet_multipliers_without_cutting_are_the_free_decay() -> None:
    # a = 0: the structural multipliers exp((-zeta wn +- i wd) T) over a tooth period.
    speed = 10000 * RPM
    values = floquet_multipliers(X_ONLY, milling(1.0), speed, 0.0, steps=40)
    period = 2 * math.pi / (TEETH * speed)
    wn = MODE.frequency_rad_s
    wd = wn * math.sqrt(1 - ZETA**2)
    expected = np.exp(complex(-ZETA * wn, wd) * period)
    assert values[0] == pytest.approx(expected, rel=1e-10) or values[0] == pytest.approx(
        expected.conjugate(), rel=1e-10
    )
    assert np.abs(values[2:]).max() < 1e-12


def test_tool_mode_from_mass_and_from_a_modal_fit() -> None:
    mode = ToolMode.from_hz(922.0, 0.011, mass_kg=0.03993)
    assert mode.stiffness_n_m == pytest.approx(0.03993 * (2 * math.pi * 922.0) ** 2)
    assert mode.mass_kg == pytest.approx(0.03993)

    class Fitted:  # the attributes of cnctwin.dynamics.Mode
        omega_n, zeta, stiffness = 5793.0, 0.02, 1.5e6

    fitted = ToolMode.from_modal(Fitted(), direction_rad=math.pi / 2)
    assert (fitted.frequency_rad_s, fitted.damping_ratio, fitted.stiffness_n_m) == (
        5793.0, 0.02, 1.5e6,
    )  # fmt: skip
    g = ToolDynamics((fitted,)).frf(np.array([5793.0]))[0]
    assert g[1, 1] == pytest.approx(1 / (1.5e6 * 2j * 0.02))
    assert g[0, 0] == pytest.approx(0, abs=1e-20)


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda: ToolMode.from_hz(-1.0, 0.01, stiffness_n_m=1e6), "frequency_hz"),
        (lambda: ToolMode.from_hz(900.0, 1.2, stiffness_n_m=1e6), "damping_ratio"),
        (lambda: ToolMode.from_hz(900.0, 0.01), "stiffness"),
        (lambda: ToolMode.from_hz(900.0, 0.01, stiffness_n_m=1e6, mass_kg=1.0), "stiffness"),
        (lambda: ToolDynamics(()), "ToolMode"),
        (lambda: MillingProcess.from_immersion(2, COEFFICIENTS, 1.5), "ae/D"),
        (lambda: MillingProcess(0, KT, KN, 0.0, math.pi), "teeth"),
        (lambda: sdm_lobes(X_ONLY, milling(1.0), [1000.0], max_depth_m=1e-3, steps=1), "steps"),
        (lambda: zoa_lobes(X_ONLY, milling(1.0), [0.0]), "spindle speeds"),
        (lambda: ProcessDamping(-1.0, 1e-4, 0.01), "C_pd"),
    ],
)
def test_bad_input_raises_input_error(build, message: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(InputError, match=message):
        build()


# ----------------------------------------------------------------------------------------
# The automatic step count at any radial immersion (issue 16, item 7)


@pytest.mark.parametrize("tool", ["x", "xy"])
@pytest.mark.parametrize("immersion", [0.01, 0.05, 0.1, 0.5, 1.0])
def test_auto_steps_are_within_one_percent_of_a_converged_run(
    immersion: float, tool: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The benchmark's cutter (NOTES.md section 1) from a/D 0.01 to slotting, 1-DOF and
    # symmetric 2-DOF. Converged: the same grid with 100 instead of 30 steps per cycle in the
    # cut and 80 instead of 20 in the shortest cut (the error falls as 1/m^2, so this one is
    # about ten times smaller). Measured: 0.65 % at most over 6000-24000 rpm.
    from cnctwin.dynamics import stability

    dynamics = X_ONLY if tool == "x" else SYMMETRIC
    process = milling(immersion)
    speeds = np.array([9000.0, 15000.0, 21000.0]) * RPM
    auto = sdm_lobes(dynamics, process, speeds, max_depth_m=0.2)
    monkeypatch.setattr(stability, "_CUT_STEPS_PER_CYCLE", 100)
    monkeypatch.setattr(stability, "_MIN_CUT_STEPS", 80)
    converged = sdm_lobes(dynamics, process, speeds, max_depth_m=0.2)
    assert np.all(np.isfinite(converged.critical_depth_m))
    assert auto.critical_depth_m == pytest.approx(converged.critical_depth_m, rel=0.01)
    assert auto.bifurcation == converged.bifurcation


@pytest.mark.parametrize("rpm", [9000.0, 15000.0, 21000.0])
def test_auto_steps_at_one_percent_immersion_match_the_independent_integrator(
    rpm: float,
) -> None:
    # a/D = 0.01: a tooth cuts for 6 % of the period. The old default (40 equal steps, a
    # cut of 2.6 steps whose edges fall inside steps) was off by up to 6 % here; the grid
    # with nodes at the entry and exit puts the boundary where the RK4 period map's spectral
    # radius crosses 1, within 1 %.
    process = milling(0.01)
    lobes = sdm_lobes(X_ONLY, process, [rpm * RPM], max_depth_m=0.2)
    depth = float(lobes.critical_depth_m[0])
    assert rk4_spectral_radius(process, rpm, 0.99 * depth, per=200) < 1.0
    assert rk4_spectral_radius(process, rpm, 1.01 * depth, per=200) > 1.0


def test_equal_steps_miss_the_short_cut_that_the_auto_grid_resolves() -> None:
    # The reason for the grid: 40 equal steps per period (the old default at these speeds)
    # put the a/D = 0.01 boundary at 15000 rpm more than 4 % off the converged one.
    process = milling(0.01)
    speeds = [15000.0 * RPM]
    auto = sdm_lobes(X_ONLY, process, speeds, max_depth_m=0.2).critical_depth_m[0]
    equal = sdm_lobes(X_ONLY, process, speeds, max_depth_m=0.2, steps=40).critical_depth_m[0]
    assert abs(equal / auto - 1.0) > 0.04


def test_four_tooth_slot_sdm_matches_the_closed_form_within_one_percent() -> None:
    # Time-invariant H (N = 4, slot): the Altintas-Budak closed form is exact; at its lobe
    # bottom a_lim = 1 / (2 max Re mu) (zoa_absolute_depth, a bounded search, no grid) the
    # semi-discretization's lowest critical depth must agree within 1 %.
    process = milling(1.0, teeth=4)
    absolute, hz = zoa_absolute_depth(SYMMETRIC, process)
    # Lobe k = 1 .. 4 bottoms sit where the tooth period holds k + epsilon / 2 pi cycles.
    speeds = np.linspace(5000.0, 25000.0, 801) * RPM
    zoa = zoa_lobes(SYMMETRIC, process, speeds)
    bottom = speeds[int(np.argmin(zoa.critical_depth_m))]
    near = np.linspace(0.995, 1.005, 11) * bottom
    sdm = sdm_lobes(SYMMETRIC, process, near, max_depth_m=2 * absolute)
    assert sdm.min_critical_depth_m == pytest.approx(absolute, rel=0.01)
    assert hz == pytest.approx(sdm.chatter_frequency_hz[int(np.argmin(sdm.critical_depth_m))],
                               rel=0.01)  # fmt: skip
