"""Turning forces: Kienzle's power law and the orthogonal/oblique edge-force model."""

from __future__ import annotations

import math

import pytest

from cnctwin.errors import InputError
from cnctwin.mechanics.materials import kienzle_material
from cnctwin.mechanics.turning import (
    TurningCoefficients,
    edge_force_turning,
    kienzle_cutting_force,
    kienzle_specific_force,
    oblique_coefficients,
    turning_chip,
)


def test_kienzle_is_kc11_at_one_millimetre_and_falls_with_slope_mc() -> None:
    kc11, mc = 2220e6, 0.14
    assert kienzle_specific_force(kc11, mc, 1e-3) == pytest.approx(kc11)
    # kc = kc1.1 h^-mc: a straight line of slope -mc in log-log.
    k1, k2 = kienzle_specific_force(kc11, mc, 0.1e-3), kienzle_specific_force(kc11, mc, 0.4e-3)
    assert math.log(k2 / k1) / math.log(4.0) == pytest.approx(-mc)


def test_kienzle_force_worked_by_hand() -> None:
    # C45 (kc1.1 = 2220 N/mm^2, mc = 0.14), h = 0.2 mm, b = 2 mm:
    # kc = 2220 * 0.2^-0.14 = 2220 * exp(0.14 ln 5) = 2220 * 1.25272 = 2781.0 N/mm^2,
    # Fc = kc * b * h = 2781.0 * 0.4 = 1112.4 N.
    c45 = kienzle_material("C45")
    assert kienzle_cutting_force(c45.kc11_pa, c45.mc, 0.2e-3, 2e-3) == pytest.approx(
        1112.4, abs=0.1
    )


def test_chip_section_of_a_straight_edge() -> None:
    # h = f sin(kr), b = ap / sin(kr); the section f ap does not depend on kr.
    h, b = turning_chip(0.3e-3, 2e-3, math.radians(45))
    assert h == pytest.approx(0.3e-3 * math.sqrt(0.5))
    assert b == pytest.approx(2e-3 / math.sqrt(0.5))
    assert h * b == pytest.approx(0.3e-3 * 2e-3)
    assert turning_chip(0.3e-3, 2e-3) == pytest.approx((0.3e-3, 2e-3))


def test_orthogonal_limit_is_merchants_model() -> None:
    # Merchant: Fc = tau b h cos(beta - alpha) / (sin(phi) cos(phi + beta - alpha)),
    # Ff = tau b h sin(beta - alpha) / (sin(phi) cos(phi + beta - alpha)).
    tau, phi, beta, alpha = 500e6, math.radians(25), math.radians(35), math.radians(8)
    ktc, kfc, krc = oblique_coefficients(tau, phi, beta, alpha)
    denominator = math.sin(phi) * math.cos(phi + beta - alpha)
    assert ktc == pytest.approx(tau * math.cos(beta - alpha) / denominator)
    assert kfc == pytest.approx(tau * math.sin(beta - alpha) / denominator)
    assert krc == pytest.approx(0.0, abs=1e-6)


def test_oblique_edge_pushes_radially_and_keeps_the_frictionless_limit() -> None:
    tau, phi, alpha = 500e6, math.radians(25), math.radians(5)
    # A friction angle equal to the rake angle puts the resultant along the cutting speed:
    # with i = 0 the feed force vanishes and Ktc = tau / (sin(phi) cos(phi)).
    ktc, kfc, _ = oblique_coefficients(tau, phi, alpha, alpha)
    assert kfc == pytest.approx(0.0, abs=1e-6)
    assert ktc == pytest.approx(tau / (math.sin(phi) * math.cos(phi)))
    # An inclined edge (i > 0) adds a radial component and leaves Ktc close to orthogonal.
    ortho = oblique_coefficients(tau, phi, math.radians(30), alpha)
    oblique = oblique_coefficients(tau, phi, math.radians(30), alpha, math.radians(10))
    assert oblique[2] > 0.0
    assert oblique[0] == pytest.approx(ortho[0], rel=0.05)


def test_edge_force_form_is_linear_in_the_chip_thickness() -> None:
    k = TurningCoefficients(ktc=2000e6, kfc=800e6, krc=300e6, kte=40e3, kfe=50e3, kre=10e3)
    f1 = edge_force_turning(k, 0.1e-3, 3e-3)
    f2 = edge_force_turning(k, 0.2e-3, 3e-3)
    assert f2.cutting_n - f1.cutting_n == pytest.approx(2000e6 * 0.1e-3 * 3e-3)
    assert f1.feed_n == pytest.approx((800e6 * 0.1e-3 + 50e3) * 3e-3)
    assert f1.radial_n == pytest.approx((300e6 * 0.1e-3 + 10e3) * 3e-3)


@pytest.mark.parametrize(
    "call",
    [
        lambda: kienzle_specific_force(-1.0, 0.2, 1e-3),
        lambda: kienzle_specific_force(2e9, 1.2, 1e-3),
        lambda: kienzle_specific_force(2e9, 0.2, 0.0),
        lambda: kienzle_cutting_force(2e9, 0.2, 1e-4, -1e-3),
        lambda: turning_chip(0.1e-3, 1e-3, 0.0),
        lambda: oblique_coefficients(500e6, 0.0, 0.5, 0.1),
    ],
)
def test_bad_input_is_an_input_error(call: object) -> None:
    with pytest.raises(InputError):
        call()  # type: ignore[operator]
