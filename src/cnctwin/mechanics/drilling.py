"""Drilling and tapping: thrust, torque and power of a twist drill, torque of a cutting tap.

Drilling (a drill of diameter ``D = 2R``, point angle ``sigma``, ``z`` lips and a chisel edge of
width ``w`` fed ``f`` per revolution). Each lip is a straight edge at the lead (setting) angle
``kappa = sigma / 2`` to the axis; it cuts a chip of thickness and width (Kienzle's model applied
to drilling: König W., Klocke F., *Fertigungsverfahren 1: Drehen, Fräsen, Bohren*, Springer, ch.
"Bohren"; Sandvik Coromant's and ISCAR's published drilling formulas use the same chip):

.. math::

    h = \\frac{f}{z} \\sin\\kappa, \\qquad b = \\frac{r_2 - r_1}{\\sin\\kappa}, \\qquad
    k_c = k_{c1.1} \\left(\\frac{h}{1\\,\\mathrm{mm}}\\right)^{-m_c},

where ``[r_1, r_2]`` is the lip's engaged radial band (``[w/2, R]`` in a solid drill at full
depth). The cutting force per lip ``F_c = k_c b h = k_c (r_2 - r_1) f / z`` acts at the mean
radius ``(r_1 + r_2) / 2`` of a uniform load along the lip, and the lip's normal (passive) force
``F_n = c_f F_c`` has the axial component ``F_n sin(kappa)`` (its radial components cancel
between symmetric lips):

.. math::

    M_{lips} = z F_c \\frac{r_1 + r_2}{2}, \\qquad T_{lips} = z\\, c_f\\, F_c \\sin\\kappa .

For ``w = 0``, ``z = 2`` and the whole radius these are ISCAR's catalogue formulas (ISCAR,
*Rotating tools catalogue* 2017, "User guide - General calculations": ``Mc = f kc D^2 / 8000``
N m and ``Ff = 0.63 (D / 2) f kc sin(kappa)`` N, ``c_f = 0.63``) and Sandvik Coromant's (the
same torque, ``Ff ~ 0.5 kc (D / 2) f sin(kappa)``, ``c_f = 0.5``).

The chisel edge (``0 <= r <= w / 2``) cuts with a large negative rake: it is taken as ``z``
half-edges perpendicular to the axis (``kappa = 90 deg``) each cutting ``h_ch = f / z``, with
the cutting force ``F_ch = k_c(h_ch) (r_2 - r_1) f / z`` and a thrust ``c_ch F_ch`` whose ratio
``c_ch`` is large: the chisel edge extrudes rather than cuts, and is often quoted to give about
half of a conventional twist drill's thrust and little of its torque (the project has not
checked a printed source for that share; ``c_ch`` of the packaged data is fitted, see
docs/drilling.md):

.. math::

    M_{ch} = z F_{ch} \\frac{r_1 + r_2}{2}, \\qquad T_{ch} = z\\, c_{ch} F_{ch} .

The spindle power is ``P = M omega``.

Tapping (a cutting tap of nominal diameter ``D`` into a bored hole ``D_0``, thread half angle
``theta``): per revolution the tap cuts the thread groove over one pitch; the groove's cross
section is the triangle of depth ``H_1 = (D - D_0) / 2`` and area ``H_1^2 tan(theta)`` whose
centroid lies at the radius ``(D + 2 D_0) / 6``. The torque is that area times ``k_c`` times the
centroid radius times a tap correction ``K`` (Yamawa, *General catalogue* 2016-2017, "Tapping
torque of cutting taps", Tables 1-2):

.. math::

    M_{tap} = \\frac{\\tan\\theta\\, k_c K (D - D_0)^2 (D + 2 D_0)}{24} .

The bored hole defaults to the tap-drill rule ``D_0 = D - P`` (pitch ``P``).

Coefficients per workpiece material are in ``cnctwin/mechanics/data/drilling.toml`` (with their
sources), read by :func:`drilling_material`; the Kienzle values ``kc1.1`` and ``mc`` come from
the Kienzle entries of the materials library (:func:`cnctwin.mechanics.kienzle_material`).

SI units throughout: m, N, Pa, rad, rad/s, N m, W.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from functools import lru_cache
from importlib.resources import files
from typing import Any

from cnctwin.errors import ConfigError, DataError, InputError
from cnctwin.mechanics.materials import kienzle_material
from cnctwin.mechanics.turning import kienzle_specific_force

__all__ = [
    "DrillingLoad",
    "DrillingMaterial",
    "drilling_load",
    "drilling_material",
    "drilling_materials",
    "tapping_torque",
]

#: Thread half angle of ISO metric and unified threads (60 degree flanks), rad.
ISO_THREAD_HALF_ANGLE_RAD = math.radians(30.0)

_KEYS = (
    "kienzle",
    "thrust_ratio",
    "chisel_thrust_ratio",
    "tap_kc_n_mm2",
    "tap_k",
    "source",
    "note",
    "checked",
)
_REQUIRED = ("kienzle", "thrust_ratio", "chisel_thrust_ratio", "tap_kc_n_mm2", "tap_k", "source")


@dataclass(frozen=True)
class DrillingMaterial:
    """Drilling and tapping coefficients of one workpiece material, with their source.

    Attributes
    ----------
    name
        The entry's name (a ``[material].name``).
    kc11_pa
        Kienzle's specific cutting force at ``h = b = 1 mm``, Pa.
    mc
        Kienzle's exponent, dimensionless, in [0, 1).
    thrust_ratio
        ``c_f``: a lip's normal (passive) force over its cutting force, dimensionless, >= 0.
    chisel_thrust_ratio
        ``c_ch``: the chisel edge's thrust over its cutting force, dimensionless, >= 0.
    tap_kc_pa
        Specific cutting resistance for tapping (Yamawa's ``kc``), Pa.
    tap_k
        Tap correction ``K`` (tap type and chips), dimensionless, > 0.
    kienzle
        Name of the Kienzle entry ``kc11_pa`` and ``mc`` come from.
    source
        Where the values come from.
    checked
        Whether the project compared the values with the printed sources.
    note
        Caveats.
    """

    name: str
    kc11_pa: float
    mc: float
    thrust_ratio: float
    chisel_thrust_ratio: float
    tap_kc_pa: float
    tap_k: float
    kienzle: str
    source: str
    checked: bool
    note: str


@dataclass(frozen=True)
class DrillingLoad:
    """Mean load of a drill or tap over a revolution (the lips' lateral forces cancel).

    Attributes
    ----------
    thrust_n
        Axial force on the tool, N, >= 0 (pushing the tool back along its axis).
    torque_nm
        Cutting torque, N m, >= 0.
    power_w
        Cutting power ``torque * omega``, W.
    lip_thrust_n, chisel_thrust_n
        The lips' and the chisel edge's shares of the thrust, N.
    """

    thrust_n: float
    torque_nm: float
    power_w: float
    lip_thrust_n: float
    chisel_thrust_n: float


def drilling_load(
    material: DrillingMaterial,
    diameter_m: float,
    feed_per_rev_m: float,
    *,
    point_angle_rad: float = math.radians(118.0),
    web_m: float = 0.0,
    lips: int = 2,
    spindle_rad_s: float = 0.0,
    inner_radius_m: float = 0.0,
    outer_radius_m: float | None = None,
) -> DrillingLoad:
    """Thrust (N), torque (N m) and power (W) of a twist drill (module notes, Kienzle lip model).

    Parameters
    ----------
    material
        The workpiece's drilling coefficients (:func:`drilling_material`).
    diameter_m
        Drill diameter ``D``, m, > 0.
    feed_per_rev_m
        Feed per revolution ``f``, m, >= 0 (0: no load).
    point_angle_rad
        Point angle ``sigma``, rad, in (0, pi]; the lip's lead angle is ``sigma / 2`` (pi: a
        flat-bottomed indexable drill).
    web_m
        Chisel-edge width ``w``, m, in [0, D).
    lips
        Number of cutting lips ``z``, >= 1.
    spindle_rad_s
        Spindle speed ``omega``, rad/s (its magnitude gives the power).
    inner_radius_m, outer_radius_m
        Engaged radial band of the edges, m: 0 and ``D / 2`` (the default) in solid material
        at full depth; a pre-drilled hole raises the inner radius, the point entering the
        material lowers the outer one.

    Returns
    -------
    DrillingLoad
        Zero without feed or without an engaged band.

    Raises
    ------
    InputError
        On a value outside those ranges, naming it.
    """
    radius = 0.5 * diameter_m
    _positive("diameter_m", diameter_m)
    if not (math.isfinite(feed_per_rev_m) and feed_per_rev_m >= 0.0):
        raise InputError(f"feed_per_rev_m={feed_per_rev_m!r}; give a finite feed >= 0 m")
    if not (math.isfinite(point_angle_rad) and 0.0 < point_angle_rad <= math.pi):
        raise InputError(f"point_angle_rad={point_angle_rad!r}; give an angle in (0, pi] rad")
    if not (math.isfinite(web_m) and 0.0 <= web_m < diameter_m):
        raise InputError(f"web_m={web_m!r}; give a chisel-edge width 0 <= w < D = {diameter_m} m")
    if lips < 1:
        raise InputError(f"lips={lips!r}; give at least 1 cutting lip")
    outer = radius if outer_radius_m is None else min(outer_radius_m, radius)
    inner = max(inner_radius_m, 0.0)
    if not (math.isfinite(inner) and math.isfinite(outer)):
        raise InputError(
            f"engaged band [{inner_radius_m!r}, {outer_radius_m!r}] m; give finite radii"
        )
    omega = abs(spindle_rad_s)
    if feed_per_rev_m == 0.0 or outer <= inner:
        return DrillingLoad(0.0, 0.0, 0.0, 0.0, 0.0)
    chip_per_lip = feed_per_rev_m / lips
    kappa = 0.5 * point_angle_rad
    half_web = 0.5 * web_m
    torque = lip_thrust = chisel_thrust = 0.0
    r1, r2 = max(inner, half_web), outer
    if r2 > r1:
        kc = float(
            kienzle_specific_force(material.kc11_pa, material.mc, chip_per_lip * math.sin(kappa))
        )
        force = kc * (r2 - r1) * chip_per_lip  # F_c per lip, N
        torque += lips * force * 0.5 * (r1 + r2)
        lip_thrust = lips * material.thrust_ratio * force * math.sin(kappa)
    r1, r2 = inner, min(outer, half_web)
    if r2 > r1:
        kc = float(kienzle_specific_force(material.kc11_pa, material.mc, chip_per_lip))
        force = kc * (r2 - r1) * chip_per_lip  # F_ch per half-edge, N
        torque += lips * force * 0.5 * (r1 + r2)
        chisel_thrust = lips * material.chisel_thrust_ratio * force
    return DrillingLoad(
        lip_thrust + chisel_thrust, torque, torque * omega, lip_thrust, chisel_thrust
    )


def tapping_torque(
    material: DrillingMaterial,
    diameter_m: float,
    pitch_m: float,
    *,
    hole_diameter_m: float | None = None,
    thread_half_angle_rad: float = ISO_THREAD_HALF_ANGLE_RAD,
) -> float:
    """Torque of a cutting tap, N m: ``tan(theta) kc K (D - D0)^2 (D + 2 D0) / 24`` (Yamawa's
    tapping-torque equation; the module notes derive it from the thread groove's area and
    centroid).

    Parameters
    ----------
    material
        The workpiece's coefficients (``tap_kc_pa``, ``tap_k``).
    diameter_m
        Nominal (major) diameter ``D`` of the tap, m, > 0.
    pitch_m
        Thread pitch ``P``, m, in (0, D / 2).
    hole_diameter_m
        Bored (tap-drill) hole diameter ``D0``, m, in (0, D]; none: ``D - P``.
    thread_half_angle_rad
        Thread half angle ``theta``, rad, in (0, pi/2): 30 degrees for ISO metric threads.

    Raises
    ------
    InputError
        On a value outside those ranges, naming it.
    """
    _positive("diameter_m", diameter_m)
    if not (math.isfinite(pitch_m) and 0.0 < pitch_m < 0.5 * diameter_m):
        raise InputError(f"pitch_m={pitch_m!r}; give a pitch in (0, D/2 = {0.5 * diameter_m}) m")
    hole = diameter_m - pitch_m if hole_diameter_m is None else hole_diameter_m
    if not (math.isfinite(hole) and 0.0 < hole <= diameter_m):
        raise InputError(f"hole_diameter_m={hole_diameter_m!r}; give 0 < D0 <= D = {diameter_m} m")
    if not (math.isfinite(thread_half_angle_rad) and 0.0 < thread_half_angle_rad < 0.5 * math.pi):
        raise InputError(
            f"thread_half_angle_rad={thread_half_angle_rad!r}; give an angle in (0, pi/2) rad"
        )
    depth = diameter_m - hole
    return (
        math.tan(thread_half_angle_rad)
        * material.tap_kc_pa
        * material.tap_k
        * depth
        * depth
        * (diameter_m + 2.0 * hole)
        / 24.0
    )


def drilling_materials() -> dict[str, DrillingMaterial]:
    """All entries of the packaged drilling coefficients, by name."""
    return dict(_library())


def drilling_material(name: str) -> DrillingMaterial:
    """The drilling coefficients of the workpiece material ``name`` (case-insensitive).

    Raises
    ------
    ConfigError
        If there is no such entry; the message lists the valid names.
    """
    table = _library()
    for key, entry in table.items():
        if key.casefold() == name.casefold():
            return entry
    raise ConfigError(f"no drilling coefficients for material {name!r}; valid: {', '.join(table)}")


def _positive(name: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0.0):
        raise InputError(f"{name}={value!r}; give a finite value > 0 m")


@lru_cache(maxsize=1)
def _library() -> dict[str, DrillingMaterial]:
    resource = files("cnctwin.mechanics").joinpath("data", "drilling.toml")
    try:
        data = tomllib.loads(resource.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise DataError(f"drilling coefficients {resource}: {err}") from None
    unknown = set(data) - {"drilling"}
    if unknown:
        raise DataError(f"drilling coefficients: unknown tables {sorted(unknown)}; valid: drilling")
    return {name: _entry(name, entry) for name, entry in data.get("drilling", {}).items()}


def _entry(name: str, entry: Any) -> DrillingMaterial:
    where = f"drilling coefficients, entry {name!r}"
    if not isinstance(entry, dict):
        raise DataError(f"{where} is not a table")
    unknown = set(entry) - set(_KEYS)
    missing = set(_REQUIRED) - set(entry)
    if unknown or missing:
        raise DataError(
            f"{where}: unknown keys {sorted(unknown)}, missing {sorted(missing)}; valid keys: "
            f"{', '.join(_KEYS)}"
        )
    numbers = {}
    for key in ("thrust_ratio", "chisel_thrust_ratio", "tap_kc_n_mm2", "tap_k"):
        value = entry[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or value < 0.0:
            raise DataError(f"{where}: {key}={value!r}; give a number >= 0")
        numbers[key] = float(value)
    try:
        kienzle = kienzle_material(str(entry["kienzle"]))
    except ConfigError as err:
        raise DataError(f"{where}: kienzle: {err}") from None
    return DrillingMaterial(
        name=name,
        kc11_pa=kienzle.kc11_pa,
        mc=kienzle.mc,
        thrust_ratio=numbers["thrust_ratio"],
        chisel_thrust_ratio=numbers["chisel_thrust_ratio"],
        tap_kc_pa=numbers["tap_kc_n_mm2"] * 1e6,
        tap_k=numbers["tap_k"],
        kienzle=kienzle.name,
        source=str(entry["source"]),
        checked=bool(entry.get("checked", False)),
        note=str(entry.get("note", "")),
    )
