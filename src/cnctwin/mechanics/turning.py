"""Turning forces: Kienzle's specific cutting force and the oblique edge-force model.

Two descriptions of the same single-point cut of chip thickness ``h`` and width ``b``:

* Kienzle (Kienzle 1952, "Die Bestimmung von Kräften und Leistungen an spanenden Werkzeugen
  und Werkzeugmaschinen", VDI-Z 94(11/12); Kienzle & Victor 1957): the specific cutting force
  falls with the chip thickness as a power law, ``kc = kc1.1 (h / 1 mm)^-mc``, and the cutting
  force is ``Fc = kc b h = kc1.1 b h^(1 - mc)`` (kc1.1 in N/mm^2 at h = b = 1 mm).
* The linear edge-force model in cutting, feed and radial directions (Altintas 2012, ch. 2;
  Armarego & Whitfield 1985): ``F = Kc b h + Ke b``, with the shear coefficients either
  measured or predicted from orthogonal cutting data by the oblique transformation
  (:func:`oblique_coefficients`).

Chip geometry of a straight-edged insert at depth of cut ap, feed f per revolution and
tool cutting-edge (approach) angle kr (ISO 3002: angle between the edge and the feed
direction): ``h = f sin(kr)``, ``b = ap / sin(kr)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cnctwin.errors import InputError

__all__ = [
    "TurningCoefficients",
    "TurningForces",
    "edge_force_turning",
    "kienzle_cutting_force",
    "kienzle_specific_force",
    "oblique_coefficients",
    "turning_chip",
]

_MM = 1e-3  # m per mm: Kienzle's reference chip thickness h0 = 1 mm


@dataclass(frozen=True)
class TurningForces:
    """Force components of a turning cut on the tool, in N.

    Attributes
    ----------
    cutting_n
        Cutting (tangential) force Fc, along the cutting speed.
    feed_n
        Feed force Ff, along the feed direction.
    radial_n
        Passive (radial, thrust) force Fp, normal to the other two.
    """

    cutting_n: float
    feed_n: float
    radial_n: float


@dataclass(frozen=True)
class TurningCoefficients:
    """Coefficients of the edge-force model in turning.

    Attributes
    ----------
    ktc, kfc, krc
        Shear coefficients in the cutting, feed and radial directions, in Pa.
    kte, kfe, kre
        Edge coefficients in the same directions, in N/m.
    """

    ktc: float
    kfc: float
    krc: float = 0.0
    kte: float = 0.0
    kfe: float = 0.0
    kre: float = 0.0


def turning_chip(
    feed_per_rev_m: float, depth_m: float, approach_rad: float = math.pi / 2
) -> tuple[float, float]:
    """Undeformed chip thickness and width (m) of a straight edge: ``f sin(kr)``, ``ap / sin(kr)``.

    Parameters
    ----------
    feed_per_rev_m
        Feed per revolution f in m, > 0.
    depth_m
        Depth of cut ap in m, > 0.
    approach_rad
        Tool cutting-edge angle kr in rad, 0 < kr <= pi/2 (pi/2: orthogonal edge).
    """
    if not (math.isfinite(feed_per_rev_m) and feed_per_rev_m > 0.0):
        raise InputError(f"feed_per_rev_m={feed_per_rev_m!r}; give a finite feed > 0 m")
    if not (math.isfinite(depth_m) and depth_m > 0.0):
        raise InputError(f"depth_m={depth_m!r}; give a finite depth of cut > 0 m")
    if not (math.isfinite(approach_rad) and 0.0 < approach_rad <= math.pi / 2):
        raise InputError(f"approach_rad={approach_rad!r}; give 0 < kr <= pi/2 rad")
    sin_kr = math.sin(approach_rad)
    return feed_per_rev_m * sin_kr, depth_m / sin_kr


def kienzle_specific_force(
    kc11_pa: float, mc: float, chip_thickness_m: float | np.ndarray
) -> float | np.ndarray:
    """Kienzle's specific cutting force ``kc = kc1.1 (h / 1 mm)^-mc``, in Pa.

    Parameters
    ----------
    kc11_pa
        Specific cutting force at h = b = 1 mm, in Pa (N/mm^2 times 1e6), > 0.
    mc
        Kienzle exponent (rise), 0 <= mc < 1.
    chip_thickness_m
        Undeformed chip thickness h in m, > 0.
    """
    _check_kienzle(kc11_pa, mc)
    h = np.asarray(chip_thickness_m, dtype=np.float64)
    if not np.all(np.isfinite(h) & (h > 0.0)):
        raise InputError(f"chip_thickness_m={chip_thickness_m!r}; give finite values > 0 m")
    kc = kc11_pa * (h / _MM) ** (-mc)
    return float(kc) if kc.ndim == 0 else kc


def kienzle_cutting_force(
    kc11_pa: float, mc: float, chip_thickness_m: float, chip_width_m: float
) -> float:
    """Kienzle's cutting force ``Fc = kc1.1 b h^(1 - mc)`` (h in units of 1 mm), in N.

    Parameters
    ----------
    kc11_pa, mc
        As for :func:`kienzle_specific_force`.
    chip_thickness_m
        Undeformed chip thickness h in m, > 0.
    chip_width_m
        Chip width b in m, > 0.
    """
    if not (math.isfinite(chip_width_m) and chip_width_m > 0.0):
        raise InputError(f"chip_width_m={chip_width_m!r}; give a finite width > 0 m")
    kc = kienzle_specific_force(kc11_pa, mc, chip_thickness_m)
    return float(kc) * chip_width_m * chip_thickness_m


def edge_force_turning(
    coefficients: TurningCoefficients, chip_thickness_m: float, chip_width_m: float
) -> TurningForces:
    """Turning forces of the linear edge-force model ``F = Kc b h + Ke b`` (Altintas 2012, ch. 2).

    Parameters
    ----------
    coefficients
        Shear (Pa) and edge (N/m) coefficients in the cutting, feed and radial directions.
    chip_thickness_m, chip_width_m
        Undeformed chip thickness h and width b in m (see :func:`turning_chip`).
    """
    h, b = chip_thickness_m, chip_width_m
    if not (math.isfinite(h) and h >= 0.0 and math.isfinite(b) and b >= 0.0):
        raise InputError(f"chip h={h!r} m, b={b!r} m; give finite values >= 0")
    k = coefficients
    return TurningForces(
        cutting_n=(k.ktc * h + k.kte) * b,
        feed_n=(k.kfc * h + k.kfe) * b,
        radial_n=(k.krc * h + k.kre) * b,
    )


def oblique_coefficients(
    shear_stress_pa: float,
    shear_angle_rad: float,
    friction_angle_rad: float,
    rake_angle_rad: float,
    inclination_rad: float = 0.0,
) -> tuple[float, float, float]:
    """Shear coefficients (Ktc, Kfc, Krc) in Pa predicted from orthogonal cutting data.

    The oblique transformation of Armarego & Whitfield (1985, Annals of the CIRP 34(1)) as
    given by Budak, Altintas & Armarego (1996, J. Manuf. Sci. Eng. 118(2), Eq. 5) and Altintas
    (2012, ch. 2), with Stabler's rule (chip flow angle = inclination angle i) and the
    orthogonal shear angle, friction angle and rake angle taken as the normal ones::

        tan(beta_n) = tan(beta_a) cos(eta),  Q = sqrt(cos^2(phi_n + beta_n - alpha_n)
                                                     + tan^2(eta) sin^2(beta_n))
        Ktc = tau_s / sin(phi_n) (cos(beta_n - alpha_n) + tan(i) tan(eta) sin(beta_n)) / Q
        Kfc = tau_s / (sin(phi_n) cos(i)) sin(beta_n - alpha_n) / Q
        Krc = tau_s / sin(phi_n) (cos(beta_n - alpha_n) tan(i) - tan(eta) sin(beta_n)) / Q

    With i = 0 this is Merchant's orthogonal model, ``Ktc = tau_s cos(beta - alpha) /
    (sin(phi) cos(phi + beta - alpha))``, ``Kfc = tau_s sin(beta - alpha) / (sin(phi)
    cos(phi + beta - alpha))``, ``Krc = 0``.

    Parameters
    ----------
    shear_stress_pa
        Shear stress in the primary shear zone tau_s in Pa, > 0.
    shear_angle_rad
        Shear angle phi_n in rad, 0 < phi_n < pi/2.
    friction_angle_rad
        Average friction angle beta_a on the rake face in rad.
    rake_angle_rad
        Normal rake angle alpha_n in rad.
    inclination_rad
        Inclination (oblique) angle i of the edge in rad, |i| < pi/2; 0 for orthogonal cutting.
    """
    if not (math.isfinite(shear_stress_pa) and shear_stress_pa > 0.0):
        raise InputError(f"shear_stress_pa={shear_stress_pa!r}; give a finite stress > 0 Pa")
    if not (math.isfinite(shear_angle_rad) and 0.0 < shear_angle_rad < math.pi / 2):
        raise InputError(f"shear_angle_rad={shear_angle_rad!r}; give 0 < phi < pi/2 rad")
    if not (math.isfinite(inclination_rad) and abs(inclination_rad) < math.pi / 2):
        raise InputError(f"inclination_rad={inclination_rad!r}; give |i| < pi/2 rad")
    if not (math.isfinite(friction_angle_rad) and math.isfinite(rake_angle_rad)):
        raise InputError(
            f"friction_angle_rad={friction_angle_rad!r}, rake_angle_rad={rake_angle_rad!r}; "
            "give finite angles"
        )
    eta = inclination_rad
    beta_n = math.atan(math.tan(friction_angle_rad) * math.cos(eta))
    lead = beta_n - rake_angle_rad
    q = math.sqrt(
        math.cos(shear_angle_rad + lead) ** 2 + math.tan(eta) ** 2 * math.sin(beta_n) ** 2
    )
    scale = shear_stress_pa / (math.sin(shear_angle_rad) * q)
    ktc = scale * (math.cos(lead) + math.tan(inclination_rad) * math.tan(eta) * math.sin(beta_n))
    kfc = scale * math.sin(lead) / math.cos(inclination_rad)
    krc = scale * (math.cos(lead) * math.tan(inclination_rad) - math.tan(eta) * math.sin(beta_n))
    return ktc, kfc, krc


def _check_kienzle(kc11_pa: float, mc: float) -> None:
    if not (math.isfinite(kc11_pa) and kc11_pa > 0.0):
        raise InputError(f"kc11_pa={kc11_pa!r}; give a finite kc1.1 > 0 Pa")
    if not (math.isfinite(mc) and 0.0 <= mc < 1.0):
        raise InputError(f"mc={mc!r}; give a Kienzle exponent 0 <= mc < 1")
