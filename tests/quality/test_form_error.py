"""Form error from static tool deflection: the cantilever closed form, the stepped tool against
numerical integration of the unit-load integral, and a hand example."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from cnctwin.errors import InputError
from cnctwin.quality.form_error import (
    CARBIDE_YOUNGS_MODULUS_PA,
    cantilever_deflection,
    end_mill_stiffness,
    form_error,
    second_moment_of_area,
    wall_normal_force,
)


def test_hand_example_10mm_carbide_end_mill() -> None:
    """D = 10 mm, 30 mm overhang, all fluted (D_e = 8 mm), E = 600 GPa, by hand:
    I = pi 0.008^4 / 64 = 2.0106e-10 m^4; k = 3 E I / L^3 = 3 * 600e9 * 2.0106e-10 / 2.7e-5
    = 1.3404e7 N/m (13.4 N/um); 200 N normal to the wall -> 14.9 um."""
    assert second_moment_of_area(0.008) == pytest.approx(2.0106e-10, rel=1e-4)
    k = end_mill_stiffness(0.010, 0.030)
    assert k == pytest.approx(1.3404e7, rel=1e-4)
    assert form_error(200.0, k) == pytest.approx(14.92e-6, rel=1e-3)


def test_uniform_tool_is_the_cantilever_closed_form() -> None:
    """k = 1 / (L^3 / (3 E I)) with I of 0.8 D when the whole overhang is fluted."""
    d, length = 0.006, 0.024
    i = math.pi * (0.8 * d) ** 4 / 64
    delta = cantilever_deflection(150.0, length, CARBIDE_YOUNGS_MODULUS_PA, i)
    assert delta == pytest.approx(150.0 * length**3 / (3 * CARBIDE_YOUNGS_MODULUS_PA * i))
    k = end_mill_stiffness(d, length, flute_length_m=length)
    assert 150.0 / k == pytest.approx(delta, rel=1e-12)
    assert end_mill_stiffness(d, length) == k
    forces = np.array([0.0, 50.0, 100.0])
    np.testing.assert_allclose(
        cantilever_deflection(forces, length, 2e11, i), forces * length**3 / (3 * 2e11 * i)
    )


@pytest.mark.parametrize("flute_fraction", [0.2, 0.5, 0.9])
def test_stepped_tool_matches_the_unit_load_integral(flute_fraction: float) -> None:
    """Tip deflection = integral of M m / (E I(x)) over the length (M = F (L - x), m = L - x),
    integrated numerically with the section changing at the flute's end."""
    d, length, modulus = 0.012, 0.050, 580e9
    fluted = flute_fraction * length
    i_shank = math.pi * d**4 / 64
    i_flute = math.pi * (0.8 * d) ** 4 / 64

    def integrand(x: float) -> float:
        i = i_shank if x < length - fluted else i_flute
        return (length - x) ** 2 / (modulus * i)

    compliance, _ = integrate.quad(integrand, 0.0, length, points=[length - fluted])
    k = end_mill_stiffness(d, length, fluted, youngs_modulus_pa=modulus)
    assert 1.0 / k == pytest.approx(compliance, rel=1e-9)
    # the shank stiffens the tool: between the all-shank and all-fluted bounds
    assert end_mill_stiffness(d, length, youngs_modulus_pa=modulus) < k
    assert k < end_mill_stiffness(
        d, length, youngs_modulus_pa=modulus, equivalent_diameter_ratio=1.0
    )


def test_wall_normal_force_and_sign() -> None:
    # a wall along X with its material at y < 0: normal +y; Fy = 120 N pushes the tool off it
    assert wall_normal_force(80.0, 120.0, (0.0, 1.0)) == 120.0
    # a wall at 30 degrees, unnormalised normal
    n = (-math.sin(math.radians(30)) * 2, math.cos(math.radians(30)) * 2)
    fx, fy = np.array([10.0, -40.0]), np.array([50.0, 0.0])
    expected = (fx * n[0] + fy * n[1]) / 2
    np.testing.assert_allclose(wall_normal_force(fx, fy, n), expected)
    assert form_error(-100.0, 1e7) == pytest.approx(-10e-6)  # pulled in: overcut


@pytest.mark.parametrize(
    "call",
    [
        lambda: end_mill_stiffness(0.0, 0.03),
        lambda: end_mill_stiffness(0.01, 0.03, flute_length_m=0.04),
        lambda: end_mill_stiffness(0.01, 0.03, equivalent_diameter_ratio=1.2),
        lambda: form_error(10.0, -1.0),
        lambda: wall_normal_force(1.0, 1.0, (0.0, 0.0)),
    ],
)
def test_bad_geometry_is_an_input_error(call) -> None:
    with pytest.raises(InputError):
        call()
