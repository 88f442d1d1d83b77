"""The "christiand2024" preset: Table 5 of Christiand 2024 with the lost exponent signs restored.

The text of the paper lost every minus sign (units too read ``N m A 1`` for N m A^-1), so each
power of ten in Table 5 may be positive or negative. These tests enumerate all 2^8 sign choices
for the drive's eight exponents and check, with closed forms only, that exactly one gives a
physically plausible drive whose speed loop is stable and settles: the preset's choice.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from cnctwin.drives import SPINDLE_PRESETS, spindle_preset
from cnctwin.errors import ConfigError

# Table 5 as extracted: (mantissa, |exponent|); R = 1.40 ohm has no exponent.
TABLE5 = {
    "J": (6.06, 6),  # kg m^2
    "B": (6.00, 7),  # N m s/rad
    "L": (7.20, 2),  # H
    "KT": (1.80, 2),  # N m/A
    "Ke": (6.00, 3),  # V s/rad
    "Kp": (5.00, 6),  # V s/rad
    "Ki": (1.7, 2),  # V/rad
    "Kd": (1.00, 11),  # V s^2/rad
}
R = 1.40
W_REF = 20000.0 * 2.0 * math.pi / 60.0  # the paper's spindle speed, rad/s


def plausible(p: dict[str, float]) -> bool:
    """Physical and control criteria of docs/drives.md, all closed form."""
    j, b, la, kt, ke, kp, ki, kd = (p[k] for k in TABLE5)  # la: armature inductance L
    # Closed-loop characteristic polynomial of Eq. 10-14 (derivative on the speed).
    poly = [la * j, la * b + R * j + kt * kd, R * b + kt * ke + kt * kp, kt * ki]
    poles = np.roots(poly)
    idle_current = b * W_REF / kt
    checks = [
        j <= 1e-3,  # a micro-milling rotor: < 2 kg at < 30 mm radius
        1e-6 <= la / R <= 1.0,  # armature time constant
        1e-2 <= j / b <= 1e3,  # coast-down time constant
        0.1 <= kt / ke <= 10.0,  # K_T = K_e for an ideal machine in SI units
        1e-3 <= idle_current <= 10.0,  # no-load current at 20,000 rpm
        abs(kp * W_REF) <= 1e3,  # voltage commanded on the start from rest
        bool(np.all(poles.real < -0.1)),  # stable, and settles within about a minute
    ]
    return all(checks)


def test_exactly_one_sign_choice_is_plausible_and_it_is_the_preset() -> None:
    survivors = []
    for signs in itertools.product((-1, 1), repeat=len(TABLE5)):
        p = {k: m * 10.0 ** (s * e) for (k, (m, e)), s in zip(TABLE5.items(), signs, strict=True)}
        if plausible(p):
            survivors.append(p)
    assert len(survivors) == 1
    only = survivors[0]
    preset = spindle_preset("christiand2024")
    m, c = preset.motor, preset.controller
    actual = [m.inertia, m.viscous_friction, m.inductance, m.torque_constant,
              m.back_emf_constant, c.kp, c.ki, c.kd]  # fmt: skip
    assert actual == pytest.approx([only[k] for k in TABLE5], rel=1e-12)
    assert m.resistance == R
    assert (m.coulomb_friction, c.voltage_limit) == (0.0, None)  # not in the paper


def test_preset_time_constants() -> None:
    m = spindle_preset("christiand2024").motor
    assert m.electrical_time_constant == pytest.approx(7.2e-2 / 1.4)  # 51 ms
    assert m.mechanical_time_constant == pytest.approx(6.06e-6 / 6.0e-7)  # 10.1 s


def test_unknown_preset_names_the_valid_ones() -> None:
    with pytest.raises(ConfigError, match="christiand2024"):
        spindle_preset("nakanishi")
    assert "christiand2024" in SPINDLE_PRESETS
