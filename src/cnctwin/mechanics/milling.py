"""Mechanistic milling forces, torque and power: waveforms over a revolution and their means.

The model (Altintas, *Manufacturing Automation*, 2nd ed., 2012, ch. 2; Royandi 2026,
Eq. 8-12; Ward 2021, Eq. 1-2) cuts the engaged part of the cutter into axial slices. A tooth
of a slice at immersion angle phi removes a chip of thickness ``h = f_z sin(phi) sin(kappa)``
(plus the runout term, see :meth:`~cnctwin.geometry.Cutter.tooth_radius_offsets_m`) and
feels, per unit chip width ``db``,

    dFt = (Ktc h + Kte) db,   dFr = (Krc h + Kre) db,   dFa = (Kac h + Kae) db,

projected on the tool frame (Lee & Altintas 1996) as

    dFx = -dFt cos(phi) - (dFr sin(kappa) + dFa cos(kappa)) sin(phi)
    dFy = +dFt sin(phi) - (dFr sin(kappa) + dFa cos(kappa)) cos(phi)
    dFz = +dFr cos(kappa) - dFa sin(kappa).

Sign convention: the forces are those the workpiece exerts **on the tool**, in the tool frame
of :mod:`cnctwin.mechanics.engagement` (x along the feed, z from the tip toward the spindle,
y = z x x). On a flat end mill (kappa = pi/2) the axial force is ``Fz = -Fa``: positive
``Kac``, ``Kae`` pull the tool toward the workpiece, as a right-hand helix cutting clockwise
does. The tangential force opposes the cutting speed, so the cutting torque ``sum(r dFt)``
and the power ``torque * omega`` are positive. The dynamometer under a workpiece measures the
opposite of these forces.

Royandi 2026 (Eq. 10-11) charges the edge terms per unit length of the helical edge,
``Kte dz / cos(beta)``; ``helical_edge=True`` does the same. The default charges them per unit
chip width, as Altintas' coefficient identification (:mod:`cnctwin.mechanics.identification`)
assumes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cnctwin.errors import InputError
from cnctwin.geometry import Cutter
from cnctwin.mechanics import _milling_kernels as _k
from cnctwin.mechanics.coefficients import CuttingCoefficients
from cnctwin.mechanics.engagement import ImmersionIntervals

__all__ = [
    "ForceWaveform",
    "MeanForces",
    "flat_end_mill_mean_forces",
    "mean_forces",
    "milling_forces",
]


@dataclass(frozen=True)
class MeanForces:
    """Per-revolution mean forces on the tool, torque and power.

    Attributes
    ----------
    fx_n, fy_n, fz_n
        Mean force components in N, tool frame (x feed, y normal in the plane, z tool axis).
    torque_nm
        Mean cutting torque about the tool axis in N m (positive: resists the spindle).
    power_w
        Mean cutting power in W (torque times spindle speed).
    """

    fx_n: float
    fy_n: float
    fz_n: float
    torque_nm: float
    power_w: float

    @property
    def resultant_n(self) -> float:
        """Magnitude of the mean force vector in N."""
        return math.sqrt(self.fx_n**2 + self.fy_n**2 + self.fz_n**2)


@dataclass(frozen=True)
class ForceWaveform:
    """Forces, torque and power over one spindle revolution.

    Attributes
    ----------
    angle_rad
        Spindle angle in rad: the immersion angle of tooth 0 at the tool tip; uniform steps
        from 0 over one revolution (the last sample is one step before 2 pi).
    fx_n, fy_n, fz_n
        Force on the tool in N, tool frame.
    torque_nm
        Cutting torque in N m.
    power_w
        Cutting power in W.
    """

    angle_rad: np.ndarray
    fx_n: np.ndarray
    fy_n: np.ndarray
    fz_n: np.ndarray
    torque_nm: np.ndarray
    power_w: np.ndarray

    @property
    def resultant_n(self) -> np.ndarray:
        """Magnitude of the force vector in N at each angle."""
        resultant: np.ndarray = np.sqrt(self.fx_n**2 + self.fy_n**2 + self.fz_n**2)
        return resultant

    def mean(self) -> MeanForces:
        """Per-revolution means (the average of the uniformly spaced samples)."""
        return MeanForces(
            fx_n=float(self.fx_n.mean()),
            fy_n=float(self.fy_n.mean()),
            fz_n=float(self.fz_n.mean()),
            torque_nm=float(self.torque_nm.mean()),
            power_w=float(self.power_w.mean()),
        )


def milling_forces(
    cutter: Cutter,
    coefficients: CuttingCoefficients,
    immersion: ImmersionIntervals,
    feed_per_tooth_m: float,
    spindle_rad_s: float,
    *,
    steps: int = 360,
    helical_edge: bool = False,
) -> ForceWaveform:
    """Forces, torque and power over one revolution, by summing teeth and axial slices.

    Parameters
    ----------
    cutter
        The cutter (shape, flutes, helix, runout; its SI views are read).
    coefficients
        Shear (Pa) and edge (N/m) coefficients.
    immersion
        Contact intervals per axial slice; the slices are those of the intervals.
    feed_per_tooth_m
        Feed per tooth f_z in m, >= 0.
    spindle_rad_s
        Spindle speed in rad/s, >= 0 (only the power depends on it).
    steps
        Number of spindle angles over the revolution, >= 1 (360: 1 degree).
    helical_edge
        Charge the edge terms per unit helical edge length (Royandi 2026, Eq. 10-11).

    Returns
    -------
    ForceWaveform
        Fx, Fy, Fz (N), torque (N m) and power (W) at each spindle angle.
    """
    _check_cut(feed_per_tooth_m, spindle_rad_s)
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise InputError(f"steps={steps!r}; give an integer >= 1")
    geometry = cutter.slices(immersion.z_bounds_m)
    theta = np.arange(steps, dtype=np.float64) * (2.0 * math.pi / steps)
    out = np.zeros((4, steps))
    _k.waveform(
        int(steps),
        geometry.radius_m,
        geometry.kappa_rad,
        geometry.width_m,
        geometry.lag_rad,
        immersion.offsets,
        immersion.entry_rad,
        immersion.exit_rad,
        cutter.pitch_rad,
        cutter.tooth_radius_offsets_m(),
        float(feed_per_tooth_m),
        coefficients.as_array(),
        _edge_scale(cutter, helical_edge),
        out,
    )
    return ForceWaveform(
        angle_rad=theta,
        fx_n=out[0],
        fy_n=out[1],
        fz_n=out[2],
        torque_nm=out[3],
        power_w=out[3] * spindle_rad_s,
    )


def mean_forces(
    cutter: Cutter,
    coefficients: CuttingCoefficients,
    immersion: ImmersionIntervals,
    feed_per_tooth_m: float,
    spindle_rad_s: float,
    *,
    helical_edge: bool = False,
) -> MeanForces:
    """Per-revolution mean forces, torque and power of any immersion, in closed form.

    Integrates the elemental forces of :func:`milling_forces` exactly over each slice's
    contact intervals (Altintas 2012, ch. 2, generalised to a lead angle per slice). The
    helix lag does not change a mean, nor does runout change its shear part (the chip one
    tooth misses, the next one takes); runout only removes the edge force of a tooth while
    it is out of the cut, which this function ignores (as it ignores the cutter's runout).

    Parameters
    ----------
    cutter, coefficients, immersion, feed_per_tooth_m, spindle_rad_s, helical_edge
        As for :func:`milling_forces`.

    Returns
    -------
    MeanForces
        Mean Fx, Fy, Fz (N), torque (N m) and power (W).
    """
    _check_cut(feed_per_tooth_m, spindle_rad_s)
    geometry = cutter.slices(immersion.z_bounds_m)
    fx, fy, fz, torque = _k.mean(
        geometry.radius_m,
        geometry.kappa_rad,
        geometry.width_m,
        immersion.offsets,
        immersion.entry_rad,
        immersion.exit_rad,
        cutter.flutes,
        float(feed_per_tooth_m),
        coefficients.as_array(),
        _edge_scale(cutter, helical_edge),
    )
    return MeanForces(fx, fy, fz, torque, torque * spindle_rad_s)


def flat_end_mill_mean_forces(
    coefficients: CuttingCoefficients,
    teeth: int,
    radius_m: float,
    entry_rad: float,
    exit_rad: float,
    depth_m: float,
    feed_per_tooth_m: float,
    spindle_rad_s: float,
) -> MeanForces:
    """Mean forces of a flat end mill, Altintas' closed form (Manufacturing Automation, ch. 2).

    With N teeth, axial depth a, feed per tooth c, evaluated between entry and exit angles
    (clipped to 0..pi)::

        Fx = N a c / (8 pi) [Ktc cos 2phi - Krc (2phi - sin 2phi)]
             + N a / (2 pi) [-Kte sin phi + Kre cos phi]
        Fy = N a c / (8 pi) [Ktc (2phi - sin 2phi) + Krc cos 2phi]
             - N a / (2 pi) [Kte cos phi + Kre sin phi]
        Fz = -N a / (2 pi) [-Kac c cos phi + Kae phi]
        T  = N a R / (2 pi) [-Ktc c cos phi + Kte phi]

    ``Fz`` carries the sign convention of :mod:`cnctwin.mechanics.milling` (``Fz = -Fa``).

    Parameters
    ----------
    coefficients
        Shear (Pa) and edge (N/m) coefficients.
    teeth
        Number of teeth N, >= 1.
    radius_m
        Cutter radius R in m (only the torque and power depend on it).
    entry_rad, exit_rad
        Entry and exit immersion angles in rad (see
        :func:`~cnctwin.mechanics.engagement.immersion_angles`).
    depth_m
        Axial depth of cut a in m.
    feed_per_tooth_m
        Feed per tooth c in m.
    spindle_rad_s
        Spindle speed in rad/s.

    Returns
    -------
    MeanForces
        Mean Fx, Fy, Fz (N), torque (N m) and power (W).
    """
    a = max(entry_rad, 0.0)
    b = min(exit_rad, math.pi)
    if b <= a:
        return MeanForces(0.0, 0.0, 0.0, 0.0, 0.0)
    c = feed_per_tooth_m
    k = coefficients
    shear = teeth * depth_m * c / (8.0 * math.pi)
    edge = teeth * depth_m / (2.0 * math.pi)
    cos2 = math.cos(2.0 * b) - math.cos(2.0 * a)
    wrap = (2.0 * b - math.sin(2.0 * b)) - (2.0 * a - math.sin(2.0 * a))
    sin1 = math.sin(b) - math.sin(a)
    cos1 = math.cos(b) - math.cos(a)
    fx = shear * (k.ktc * cos2 - k.krc * wrap) + edge * (-k.kte * sin1 + k.kre * cos1)
    fy = shear * (k.ktc * wrap + k.krc * cos2) - edge * (k.kte * cos1 + k.kre * sin1)
    fz = -edge * (-k.kac * c * cos1 + k.kae * (b - a))
    torque = edge * radius_m * (-k.ktc * c * cos1 + k.kte * (b - a))
    return MeanForces(fx, fy, fz, torque, torque * spindle_rad_s)


def _edge_scale(cutter: Cutter, helical_edge: bool) -> float:
    return 1.0 / math.cos(cutter.helix_rad) if helical_edge else 1.0


def _check_cut(feed_per_tooth_m: float, spindle_rad_s: float) -> None:
    if not (math.isfinite(feed_per_tooth_m) and feed_per_tooth_m >= 0.0):
        raise InputError(f"feed_per_tooth_m={feed_per_tooth_m!r}; give a finite feed >= 0 m")
    if not (math.isfinite(spindle_rad_s) and spindle_rad_s >= 0.0):
        raise InputError(f"spindle_rad_s={spindle_rad_s!r}; give a finite speed >= 0 rad/s")
