"""Form error of a milled wall from the static deflection of the end mill (Heide 2025, use case 2).

The cutting force bends the end mill like a cantilever clamped in the holder; the part of the
deflection normal to the machined wall moves the cutting edge away from (or into) the wall and
is left on the part as form error (Kops & Vo 1990; Altintas 2012, "Manufacturing Automation",
2nd ed., ch. 2 on static deformations in end milling; Budak & Altintas 1994, Int. J. Mach.
Tools Manuf. 34(7), for the model with the load distributed over the depth of cut).

The end mill is an Euler-Bernoulli cantilever of overhang ``L`` (holder face to tip): a shank
of diameter ``D`` and, over the fluted length ``L_f`` at the tip, a solid cylinder of the
*equivalent diameter* ``D_e`` that has the same bending compliance as the fluted cross-section.
Kops & Vo (1990, CIRP Annals 39(1) 93-96, "Determination of the equivalent diameter of an end
mill based on its compliance") measured ``D_e`` of about 0.8 ``D``; that is the default ratio.
With the load ``F`` at the tip, the unit-load (Castigliano) integral over the two sections gives

    delta = F / (3 E) * (L_f^3 / I_f + (L^3 - L_f^3) / I_s),    I = pi d^4 / 64,

which is ``F L^3 / (3 E I)`` for a uniform tool. The tip is the point of largest deflection and
the load at the tip the conservative (largest) case of a force spread over the depth of cut.
The Young's modulus of cemented tungsten carbide falls from about 650 to 530 GPa as the cobalt
binder rises from 6 to 12 %; 600 GPa, typical of the grades of solid end mills, is the
default. Everything is in SI units: N, m, Pa, N/m.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cnctwin.errors import InputError

__all__ = [
    "CARBIDE_YOUNGS_MODULUS_PA",
    "EQUIVALENT_DIAMETER_RATIO",
    "cantilever_deflection",
    "end_mill_stiffness",
    "form_error",
    "second_moment_of_area",
    "wall_normal_force",
]

#: Young's modulus of cemented tungsten carbide, Pa (530-650 GPa by cobalt content).
CARBIDE_YOUNGS_MODULUS_PA = 600e9
#: Equivalent diameter of the fluted part over the nominal diameter (Kops & Vo 1990).
EQUIVALENT_DIAMETER_RATIO = 0.8

FloatOrArray = float | NDArray[np.float64]


def _positive(name: str, value: float) -> float:
    if not (math.isfinite(value) and value > 0.0):
        raise InputError(f"{name}={value!r}; give a finite value > 0")
    return float(value)


def second_moment_of_area(diameter_m: float) -> float:
    """Second moment of area of a solid circular section, ``pi d^4 / 64``, m^4 (d in m)."""
    return math.pi * _positive("diameter_m", diameter_m) ** 4 / 64.0


def cantilever_deflection(
    force_n: ArrayLike, length_m: float, youngs_modulus_pa: float, second_moment_m4: float
) -> FloatOrArray:
    """Tip deflection of a uniform cantilever under a tip load, ``F L^3 / (3 E I)``, m.

    Parameters
    ----------
    force_n
        Tip load, N (scalar or array).
    length_m
        Free length, m.
    youngs_modulus_pa
        Young's modulus, Pa.
    second_moment_m4
        Second moment of area of the section, m^4.
    """
    compliance = _positive("length_m", length_m) ** 3 / (
        3.0
        * _positive("youngs_modulus_pa", youngs_modulus_pa)
        * _positive("second_moment_m4", second_moment_m4)
    )
    result = np.asarray(force_n, dtype=float) * compliance
    return float(result) if result.ndim == 0 else result


def end_mill_stiffness(
    diameter_m: float,
    overhang_m: float,
    flute_length_m: float | None = None,
    youngs_modulus_pa: float = CARBIDE_YOUNGS_MODULUS_PA,
    equivalent_diameter_ratio: float = EQUIVALENT_DIAMETER_RATIO,
) -> float:
    """Static bending stiffness of an end mill at its tip, N/m.

    Parameters
    ----------
    diameter_m
        Nominal (cutting and shank) diameter ``D``, m.
    overhang_m
        Overhang ``L`` from the holder face to the tip, m.
    flute_length_m
        Fluted length ``L_f`` at the tip, m (<= ``overhang_m``); ``None`` takes the whole
        overhang as fluted (the stiffness is then ``3 E I_e / L^3``, the lower bound).
    youngs_modulus_pa
        Young's modulus ``E`` of the tool material, Pa (carbide by default).
    equivalent_diameter_ratio
        ``D_e / D`` of the fluted part (Kops & Vo 1990: about 0.8), in (0, 1].

    Returns
    -------
    float
        ``k = F / delta_tip`` with ``delta_tip`` from the stepped-cantilever formula of the
        module docstring, N/m.
    """
    diameter = _positive("diameter_m", diameter_m)
    length = _positive("overhang_m", overhang_m)
    modulus = _positive("youngs_modulus_pa", youngs_modulus_pa)
    ratio = _positive("equivalent_diameter_ratio", equivalent_diameter_ratio)
    if ratio > 1.0:
        raise InputError(f"equivalent_diameter_ratio={ratio!r}; give a ratio in (0, 1]")
    fluted = length if flute_length_m is None else _positive("flute_length_m", flute_length_m)
    if fluted > length:
        raise InputError(
            f"flute_length_m={fluted!r} exceeds overhang_m={length!r}; the fluted part lies "
            f"inside the overhang"
        )
    i_fluted = second_moment_of_area(ratio * diameter)
    i_shank = second_moment_of_area(diameter)
    compliance = (fluted**3 / i_fluted + (length**3 - fluted**3) / i_shank) / (3.0 * modulus)
    return 1.0 / compliance


def wall_normal_force(
    force_x_n: ArrayLike, force_y_n: ArrayLike, wall_normal_xy: tuple[float, float]
) -> FloatOrArray:
    """Component of the cutting force on the tool along the wall's normal, N.

    Parameters
    ----------
    force_x_n, force_y_n
        Force on the tool in the machine's X and Y, N (scalars or arrays).
    wall_normal_xy
        Normal of the machined wall in the XY plane, pointing out of the material toward the
        tool (normalised here).

    Returns
    -------
    float or ndarray
        ``F . n``, N: positive pushes the tool away from the wall (material is left: the wall
        stands proud of its nominal position), negative pulls it into the wall (overcut).
    """
    nx, ny = (float(c) for c in wall_normal_xy)
    norm = math.hypot(nx, ny)
    if not (math.isfinite(norm) and norm > 0.0):
        raise InputError(f"wall_normal_xy={wall_normal_xy!r}; give a non-zero finite vector")
    result = (
        np.asarray(force_x_n, dtype=float) * nx + np.asarray(force_y_n, dtype=float) * ny
    ) / norm
    return float(result) if result.ndim == 0 else result


def form_error(normal_force_n: ArrayLike, stiffness_n_per_m: float) -> FloatOrArray:
    """Form error of the wall from the static tool deflection, ``F_n / k``, m.

    Parameters
    ----------
    normal_force_n
        Force on the tool normal to the wall (:func:`wall_normal_force`), N.
    stiffness_n_per_m
        Tool stiffness at the tip (:func:`end_mill_stiffness` or measured), N/m.

    Returns
    -------
    float or ndarray
        Signed deviation of the wall from its nominal position, m: positive leaves material
        (undercut), negative removes too much (overcut).
    """
    k = _positive("stiffness_n_per_m", stiffness_n_per_m)
    result = np.asarray(normal_force_n, dtype=float) / k
    return float(result) if result.ndim == 0 else result
