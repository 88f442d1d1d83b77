"""Cutter geometry against closed forms and numerical integration."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from cnctwin.config import ToolConfig
from cnctwin.errors import ConfigError
from cnctwin.geometry import Cutter


def test_flat_envelope_is_a_cylinder() -> None:
    cutter = Cutter.flat(6.0, 12.0)
    z = np.array([-0.1, 0.0, 1.0, 12.0, 12.1])
    assert cutter.radius_at(z).tolist() == [0.0, 3.0, 3.0, 3.0, 0.0]
    assert cutter.sin_kappa_at(z).tolist() == [0.0, 1.0, 1.0, 1.0, 0.0]


def test_ball_radius_is_the_sphere() -> None:
    cutter = Cutter.ball(10.0, 20.0)
    z = np.linspace(0.0, 5.0, 11)
    # A sphere of radius 5 centred 5 above the tip: r^2 + (5 - z)^2 = 25.
    np.testing.assert_allclose(cutter.radius_at(z) ** 2 + (5.0 - z) ** 2, 25.0, atol=1e-12)
    # kappa is the angle between the axis and the normal: sin = r / R on a sphere.
    np.testing.assert_allclose(cutter.sin_kappa_at(z), cutter.radius_at(z) / 5.0, atol=1e-12)
    assert cutter.radius_at(7.0) == 5.0


def test_bull_nose_corner_is_a_torus() -> None:
    cutter = Cutter.bull(10.0, 2.0, 15.0)
    z = np.linspace(0.0, 2.0, 9)
    # Corner circle of radius 2 centred at (r = 3, z = 2).
    np.testing.assert_allclose((cutter.radius_at(z) - 3.0) ** 2 + (2.0 - z) ** 2, 4.0)
    assert cutter.radius_at(0.0) == 3.0 and cutter.radius_at(5.0) == 5.0


def test_cones_widen_linearly_to_the_diameter() -> None:
    # A 90 degree V-bit of 6 mm: r = z tan(45 deg) up to 3 mm, then the cylinder.
    vbit = Cutter.conical(6.0, 10.0, tip_angle_rad=math.pi / 2)
    z = np.array([-0.1, 0.0, 1.0, 2.5, 3.5, 7.0, 10.0, 10.1])
    np.testing.assert_allclose(vbit.radius_at(z), [0, 0, 1, 2.5, 3, 3, 3, 0], atol=1e-12)
    # The cone's normal leans 45 degrees from the horizontal: sin(kappa) = cos(45 deg).
    np.testing.assert_allclose(
        vbit.sin_kappa_at(z), [0, *[math.sqrt(0.5)] * 3, 1, 1, 1, 0], atol=1e-12
    )
    assert vbit.cone_height_mm == pytest.approx(3.0) and vbit.flat_radius_mm == 0.0
    # Without an angle the cone spans the fluted length (CAMotics' conical): 2 x 2 mm is
    # 2 atan(1/2) = 53.13 degrees, and reaches the diameter at the top.
    camotics = Cutter.conical(2.0, 2.0)
    assert math.degrees(camotics.tip_angle_rad) == pytest.approx(53.130102354)
    assert camotics.radius_at([1.0, 2.0]) == pytest.approx([0.5, 1.0])
    # A snub nose: flat tip of 2 mm, 4 mm at 5.5 mm (CAMotics' snubnose).
    snub = Cutter.snub(4.0, 2.0, 5.5)
    np.testing.assert_allclose(snub.radius_at([0.0, 2.75, 5.5]), [1.0, 1.5, 2.0])
    assert snub.flat_radius_mm == 1.0 and snub.cone_height_mm == pytest.approx(5.5)


@pytest.mark.parametrize(
    "cutter",
    [
        Cutter.flat(6.0, 10.0),
        Cutter.ball(6.0, 10.0),
        Cutter.bull(8.0, 1.5, 10.0),
        Cutter.conical(6.0, 10.0, tip_angle_rad=math.radians(60.0)),
        Cutter.conical(2.0, 2.0),
        Cutter.snub(8.0, 1.0, 10.0, tip_angle_rad=math.radians(90.0)),
    ],
    ids=["flat", "ball", "bull", "vbit", "camotics-cone", "snub"],
)
def test_envelope_volume_matches_integral(cutter: Cutter) -> None:
    integral, _ = quad(
        lambda z: math.pi * float(cutter.radius_at(z)) ** 2,
        0.0,
        cutter.flute_length_mm,
        points=[cutter.corner_radius_mm or cutter.cone_height_mm],
    )
    assert cutter.volume_mm3() == pytest.approx(integral, rel=1e-9)


@pytest.mark.parametrize(
    ("kwargs", "fragment"),
    [
        ({"kind": "flat", "diameter_mm": 0.0, "flute_length_mm": 5.0}, "diameter_mm=0.0"),
        (
            {"kind": "flat", "diameter_mm": 6.0, "flute_length_mm": 5.0, "corner_radius_mm": 1.0},
            "must be 0",
        ),
        (
            {"kind": "ball", "diameter_mm": 6.0, "flute_length_mm": 5.0, "corner_radius_mm": 1.0},
            "diameter_mm/2",
        ),
        (
            {"kind": "bull", "diameter_mm": 6.0, "flute_length_mm": 5.0, "corner_radius_mm": 3.0},
            "0 < rc <",
        ),
        (
            {"kind": "ball", "diameter_mm": 6.0, "flute_length_mm": 2.0, "corner_radius_mm": 3.0},
            "at least",
        ),
        ({"kind": "reamer", "diameter_mm": 6.0, "flute_length_mm": 5.0}, "kind='reamer'"),
        (
            {"kind": "flat", "diameter_mm": 6.0, "flute_length_mm": 5.0, "tip_angle_rad": 1.0},
            "use kind 'conical'",
        ),
        (
            {"kind": "conical", "diameter_mm": 6.0, "flute_length_mm": 5.0, "tip_angle_rad": 3.2},
            r"\(0, pi\)",
        ),
        (
            {"kind": "conical", "diameter_mm": 6.0, "flute_length_mm": 2.0, "tip_angle_rad": 1.0},
            "cone of this 57.2958 degree conical tool is 5.49146 mm high",
        ),
        (
            {
                "kind": "conical",
                "diameter_mm": 6.0,
                "flute_length_mm": 9.0,
                "tip_angle_rad": 1.0,
                "tip_diameter_mm": 1.0,
            },
            "use kind 'snub'",
        ),
        (
            {
                "kind": "snub",
                "diameter_mm": 6.0,
                "flute_length_mm": 9.0,
                "tip_angle_rad": 1.0,
                "tip_diameter_mm": 6.0,
            },
            "0 < tip < diameter_mm",
        ),
        (
            {
                "kind": "snub",
                "diameter_mm": 6.0,
                "flute_length_mm": 9.0,
                "tip_angle_rad": 1.0,
                "tip_diameter_mm": 2.0,
                "corner_radius_mm": 0.5,
            },
            "for a snub tool; it must be 0",
        ),
        ({"kind": "flat", "diameter_mm": 6.0, "flute_length_mm": 5.0, "flutes": 0}, "flutes=0"),
        ({"kind": "flat", "diameter_mm": 6.0, "flute_length_mm": 5.0, "helix_rad": 2.0}, "helix"),
    ],
)
def test_invalid_cutters_are_rejected(kwargs: dict, fragment: str) -> None:
    with pytest.raises(ConfigError, match=fragment):
        Cutter(**kwargs)


def test_from_tool_config_converts_degrees_and_needs_a_flute_length() -> None:
    tool = ToolConfig(number=3, kind="bull", diameter_mm=8.0, corner_radius_mm=1.0, helix_deg=45)
    with pytest.raises(ConfigError, match="tool 3 has no flute_length_mm"):
        Cutter.from_tool_config(tool)
    cutter = Cutter.from_tool_config(tool, flute_length_mm=16.0)
    assert cutter == Cutter.bull(8.0, 1.0, 16.0, flutes=2, helix_rad=math.pi / 4)


@pytest.mark.parametrize(
    ("fields", "expected"),
    [
        ({"kind": "flat"}, Cutter.flat(8.0, 16.0, helix_rad=math.pi / 4)),
        ({"kind": "ball"}, Cutter.ball(8.0, 16.0, helix_rad=math.pi / 4)),
        (
            {"kind": "conical", "tip_angle_deg": 90.0},
            Cutter.conical(8.0, 16.0, tip_angle_rad=math.pi / 2, helix_rad=math.pi / 4),
        ),
        # No angle: the cone spans the fluted length, as CAMotics' conical tool.
        ({"kind": "conical"}, Cutter.conical(8.0, 16.0, helix_rad=math.pi / 4)),
        (
            {"kind": "snub", "tip_diameter_mm": 2.0, "tip_angle_deg": 60.0},
            Cutter.snub(8.0, 2.0, 16.0, tip_angle_rad=math.pi / 3, helix_rad=math.pi / 4),
        ),
    ],
)
def test_from_tool_config_builds_every_kind(fields: dict, expected: Cutter) -> None:
    tool = ToolConfig(number=4, diameter_mm=8.0, flute_length_mm=16.0, helix_deg=45, **fields)
    cutter = Cutter.from_tool_config(tool)
    assert cutter.kind == expected.kind
    for name in ("diameter_mm", "flute_length_mm", "corner_radius_mm", "tip_diameter_mm"):
        assert getattr(cutter, name) == getattr(expected, name), name
    assert cutter.tip_angle_rad == pytest.approx(expected.tip_angle_rad, rel=1e-15)
    assert cutter.helix_rad == pytest.approx(expected.helix_rad, rel=1e-15)


def test_from_tool_config_names_the_tool_of_a_cone_too_high_for_its_flutes() -> None:
    # A 20-degree V-bit of 8 mm reaches its diameter 22.7 mm above the tip: 16 mm of flutes
    # cannot hold it.
    tool = ToolConfig(
        number=7, kind="conical", diameter_mm=8.0, tip_angle_deg=20.0, flute_length_mm=16.0
    )
    with pytest.raises(ConfigError, match=r"^tool 7: flute_length_mm=16.0; the cone"):
        Cutter.from_tool_config(tool)


@pytest.mark.parametrize(
    "cutter",
    [
        Cutter.flat(6.0, 12.0),
        Cutter.ball(6.0, 12.0),
        Cutter.bull(6.0, 1.5, 12.0),
        Cutter.conical(6.0, 12.0, tip_angle_rad=math.radians(60.0)),
        Cutter.snub(6.0, 2.0, 12.0, tip_angle_rad=math.radians(90.0)),
    ],
    ids=["flat", "ball", "bull", "conical", "snub"],
)
def test_force_model_slices_lie_on_the_envelope(cutter: Cutter) -> None:
    # Two views of one profile: the SI slices of the force model (radius and lead angle at each
    # slice's midpoint along the profile, m) and the envelope of the dexel removal (mm).
    slices = cutter.slices(np.linspace(0.0, 10e-3, 41))
    z_mm = slices.z_m * 1e3
    np.testing.assert_allclose(slices.radius_m, cutter.radius_at(z_mm) * 1e-3, rtol=1e-9)
    np.testing.assert_allclose(np.sin(slices.kappa_rad), cutter.sin_kappa_at(z_mm), rtol=1e-9)
    # The profile lengths sum to the envelope's outline from the tip to 10 mm, minus the flat
    # bottom (which has no side edge).
    r = cutter.radius_at(np.linspace(0.0, 10.0, 200_001))
    outline = np.sum(np.hypot(np.diff(r), 10.0 / 200_000))
    assert slices.width_m.sum() * 1e3 == pytest.approx(outline, rel=1e-6)
    assert np.all(np.diff(slices.lag_rad) > 0.0)
