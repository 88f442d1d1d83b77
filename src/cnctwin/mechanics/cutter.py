"""End-mill geometry for the force model: local radius, lead angle and helix lag along the axis.

A flat, ball or bull-nose end mill is a profile of revolution: a corner arc of radius ``rc``
(0 for a flat end mill, ``D/2`` for a ball end mill) below a cylinder of radius ``R = D/2``.
A conical tool (V-bit) or a snub nose (a cone with a flat tip of radius ``r_t``) is a cone of
included angle ``theta``, ``r(z) = r_t + z tan(theta/2)``, below the cylinder.
At a point of the cutting edge the model needs the local radius ``r``, the axial immersion
(lead) angle ``kappa`` between the tool axis and the surface normal (90 deg on the cylinder,
0 at a ball's tip), the chip width of the element (its length along the profile) and the lag
angle of the helical flute. The formulation is that of Lee & Altintas (1996), "Prediction of
ball-end milling forces from orthogonal cutting data", IJMTM 36(9), with a constant helix lead:
the lag at height ``z`` above the tip is ``psi = z tan(beta) / R`` (Altintas 2012, ch. 2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING, Literal

import numpy as np

from cnctwin.config.tools import MAX_FLUTES
from cnctwin.errors import ConfigError

if TYPE_CHECKING:
    from cnctwin.config.tools import ToolConfig

__all__ = ["CutterKind", "CutterSlices", "EndMill"]

CutterKind = Literal["flat", "ball", "bull", "conical", "snub"]

_CONES = ("conical", "snub")


@dataclass(frozen=True)
class CutterSlices:
    """Local geometry of axial slices of an end mill (arrays of one value per slice).

    Attributes
    ----------
    z_m
        Height of the slice's representative point above the tool tip, in m.
    radius_m
        Local radius of the cutting edge, in m.
    kappa_rad
        Axial immersion (lead) angle in rad: pi/2 on the cylinder, 0 at a ball's tip.
    width_m
        Chip width of the slice: its length along the tool profile, in m (``dz`` on the
        cylinder, ``rc * d(kappa)`` on the corner arc).
    lag_rad
        Helix lag angle of the edge at ``z_m``, in rad.
    """

    z_m: np.ndarray
    radius_m: np.ndarray
    kappa_rad: np.ndarray
    width_m: np.ndarray
    lag_rad: np.ndarray


@dataclass(frozen=True)
class EndMill:
    """A milling cutter with equally spaced teeth.

    Attributes
    ----------
    diameter_m
        Cutter diameter D in m, > 0.
    teeth
        Number of teeth (flutes) N, 1 to 100 (:data:`~cnctwin.config.tools.MAX_FLUTES`).
    helix_rad
        Helix angle beta in rad, 0 <= beta < pi/2 (right-hand helix for a clockwise spindle).
    kind
        ``"flat"``, ``"ball"``, ``"bull"`` (nose with a corner radius), ``"conical"`` (V-bit)
        or ``"snub"`` (cone with a flat tip).
    corner_radius_m
        Corner radius rc in m: 0 for ``flat``, ``conical`` and ``snub``, ``D/2`` for ``ball``
        (0 is taken as ``D/2``), strictly between 0 and ``D/2`` for ``bull``.
    runout_m
        Radial runout (parallel offset of the tool axis from the spindle axis) rho in m, >= 0.
    runout_angle_rad
        Direction of that offset, lambda in rad, measured from tooth 0 in the direction of
        rotation: tooth j's radius becomes ``R + rho cos(j 2 pi / N - lambda)``.
    """

    diameter_m: float
    teeth: int
    helix_rad: float = 0.0
    kind: CutterKind = "flat"
    corner_radius_m: float = 0.0
    runout_m: float = 0.0
    runout_angle_rad: float = 0.0
    tip_angle_rad: float = 0.0
    tip_diameter_m: float = 0.0

    def __post_init__(self) -> None:
        d = self.diameter_m
        if not (isinstance(d, (int, float)) and math.isfinite(d) and d > 0):
            raise ConfigError(f"diameter_m={d!r}; give a finite diameter > 0 m")
        if isinstance(self.teeth, bool) or not isinstance(self.teeth, (int, np.integer)):
            raise ConfigError(f"teeth={self.teeth!r}; give an integer from 1 to {MAX_FLUTES}")
        if not 1 <= self.teeth <= MAX_FLUTES:
            raise ConfigError(f"teeth={self.teeth!r}; give an integer from 1 to {MAX_FLUTES}")
        if not (math.isfinite(self.helix_rad) and 0.0 <= self.helix_rad < math.pi / 2):
            raise ConfigError(f"helix_rad={self.helix_rad!r}; give 0 <= helix < pi/2 rad")
        if not (math.isfinite(self.runout_m) and self.runout_m >= 0.0):
            raise ConfigError(f"runout_m={self.runout_m!r}; give a finite runout >= 0 m")
        if not math.isfinite(self.runout_angle_rad):
            raise ConfigError(f"runout_angle_rad={self.runout_angle_rad!r}; give a finite angle")
        half = d / 2.0
        rc = self.corner_radius_m
        if self.kind in _CONES:
            self._check_cone(half)
        elif self.tip_angle_rad != 0.0 or self.tip_diameter_m != 0.0:
            raise ConfigError(
                f"tip_angle_rad={self.tip_angle_rad!r}, tip_diameter_m={self.tip_diameter_m!r} "
                f"for kind {self.kind!r}; they must be 0 (use kind 'conical' or 'snub')"
            )
        elif self.kind == "flat":
            if rc != 0.0:
                raise ConfigError(f"corner_radius_m={rc!r} for a flat end mill; it must be 0")
        elif self.kind == "ball":
            if rc == 0.0:
                object.__setattr__(self, "corner_radius_m", half)
            elif not math.isclose(rc, half, rel_tol=1e-9):
                raise ConfigError(f"corner_radius_m={rc!r} for a ball end mill; it must be D/2")
        elif self.kind == "bull":
            if not (math.isfinite(rc) and 0.0 < rc < half):
                raise ConfigError(
                    f"corner_radius_m={rc!r} for a bull-nose end mill; give 0 < rc < D/2 ({half})"
                )
        else:
            raise ConfigError(
                f"kind={self.kind!r}; give 'flat', 'ball', 'bull', 'conical' or 'snub'"
            )

    def _check_cone(self, half: float) -> None:
        if self.corner_radius_m != 0.0:
            raise ConfigError(
                f"corner_radius_m={self.corner_radius_m!r} for a {self.kind} tool; it must be 0"
            )
        angle = self.tip_angle_rad
        if not (math.isfinite(angle) and 0.0 < angle < math.pi):
            raise ConfigError(
                f"tip_angle_rad={angle!r} for a {self.kind} tool; give an included angle in "
                "(0, pi) rad"
            )
        tip = self.tip_diameter_m
        if self.kind == "conical" and tip != 0.0:
            raise ConfigError(
                f"tip_diameter_m={tip!r} for a conical tool; it must be 0 (use kind 'snub')"
            )
        if self.kind == "snub" and not (math.isfinite(tip) and 0.0 < tip < 2.0 * half):
            raise ConfigError(
                f"tip_diameter_m={tip!r} for a snub nose; give 0 < tip < diameter ({2 * half} m)"
            )

    @classmethod
    def from_tool(
        cls, tool: ToolConfig, runout_m: float = 0.0, runout_angle_rad: float = 0.0
    ) -> EndMill:
        """The end mill of a configured tool (``[[tools]]`` entry, lengths in mm)."""
        return cls(
            diameter_m=tool.diameter_mm * 1e-3,
            teeth=tool.flutes,
            helix_rad=math.radians(tool.helix_deg),
            kind=tool.kind,
            corner_radius_m=(tool.corner_radius_mm or 0.0) * 1e-3,
            runout_m=runout_m,
            runout_angle_rad=runout_angle_rad,
        )

    @property
    def radius_m(self) -> float:
        """Nominal radius R = D/2 in m."""
        return self.diameter_m / 2.0

    @property
    def pitch_rad(self) -> float:
        """Tooth spacing 2 pi / N in rad."""
        return 2.0 * math.pi / self.teeth

    def tooth_radius_offsets_m(self) -> np.ndarray:
        """Radius of each tooth minus the nominal radius, in m: ``rho cos(j 2 pi/N - lambda)``.

        Kline & DeVor (1983), "The effect of runout on cutting geometry and forces in end
        milling", IJMTDR 23(2): a parallel axis offset rho changes each tooth's radius.
        """
        j = np.arange(self.teeth, dtype=np.float64)
        return self.runout_m * np.cos(j * self.pitch_rad - self.runout_angle_rad)

    def slices(self, z_bounds_m: np.ndarray) -> CutterSlices:
        """Local geometry of the axial slices between consecutive heights ``z_bounds_m``.

        Parameters
        ----------
        z_bounds_m
            Increasing heights above the tool tip in m, >= 0 (n + 1 values for n slices).

        Returns
        -------
        CutterSlices
            One value per slice, taken at the slice's midpoint along the tool profile.
        """
        z = np.asarray(z_bounds_m, dtype=np.float64)
        if z.ndim != 1:
            raise ConfigError(f"z_bounds_m has shape {z.shape}; give a 1-D array of heights in m")
        return _slices(self, z.tobytes())


@lru_cache(maxsize=256)
def _slices(cutter: EndMill, z_bytes: bytes) -> CutterSlices:
    """:meth:`EndMill.slices`, cached (a twin asks for the same slices at every cycle)."""
    z = np.frombuffer(z_bytes, dtype=np.float64)
    if z.size < 2 or not np.all(np.isfinite(z)):
        raise ConfigError("z_bounds_m must be at least two finite heights in m")
    if z[0] < 0.0 or np.any(np.diff(z) <= 0.0):
        raise ConfigError(f"z_bounds_m from {z[0]!r}; give increasing heights >= 0 m")
    rc = cutter.corner_radius_m
    if cutter.kind in _CONES:
        return _cone_slices(cutter, z)
    if rc > 0.0:
        # Arc length along the profile: rc * kappa on the corner, then the cylinder.
        kappa_z = np.arccos(np.clip((rc - np.minimum(z, rc)) / rc, -1.0, 1.0))
        s = np.where(z < rc, rc * kappa_z, rc * math.pi / 2 + (z - rc))
        s_mid = 0.5 * (s[:-1] + s[1:])
        kappa = np.minimum(s_mid / rc, math.pi / 2)
        z_mid = np.where(
            s_mid < rc * math.pi / 2,
            rc * (1.0 - np.cos(kappa)),
            s_mid - rc * (math.pi / 2 - 1),
        )
    else:
        s = z
        z_mid = 0.5 * (z[:-1] + z[1:])
        kappa = np.full(z_mid.shape, math.pi / 2)
    radius = cutter.radius_m - rc + rc * np.sin(kappa)
    return _frozen_slices(cutter, z_mid, radius, kappa, np.diff(s))


def _cone_slices(cutter: EndMill, z: np.ndarray) -> CutterSlices:
    """Slices of a conical or snub-nose tool (heights ``z`` above the tip, m).

    On the cone ``r(z) = r_t + z tan(theta/2)`` and the lead angle is constant,
    ``kappa = pi/2 - theta/2`` (the angle between the axis and the cone's normal); an element of
    height ``dz`` has the chip width ``dz / cos(theta/2)`` along the edge. Above the cone's
    height ``(R - r_t) / tan(theta/2)`` the tool is a cylinder. The flat tip of a snub nose, like
    the bottom of a flat end mill, does not cut sideways and has no slice.
    """
    half_angle = 0.5 * cutter.tip_angle_rad
    tip_radius = 0.5 * cutter.tip_diameter_m
    height = (cutter.radius_m - tip_radius) / math.tan(half_angle)
    z_mid = 0.5 * (z[:-1] + z[1:])
    on_cone = z_mid < height
    radius = np.where(on_cone, tip_radius + z_mid * math.tan(half_angle), cutter.radius_m)
    kappa = np.where(on_cone, 0.5 * math.pi - half_angle, 0.5 * math.pi)
    # Length along the profile of each slice, split at the cone's height.
    dz = np.diff(z)
    dz_cone = np.clip(np.minimum(z[1:], height) - z[:-1], 0.0, None)
    width = dz_cone / math.cos(half_angle) + (dz - dz_cone)
    return _frozen_slices(cutter, z_mid, radius, kappa, width)


def _frozen_slices(
    cutter: EndMill, z_mid: np.ndarray, radius: np.ndarray, kappa: np.ndarray, width: np.ndarray
) -> CutterSlices:
    """Slices with the helix lag ``psi = z tan(beta) / R`` (Altintas 2012, ch. 2), read-only."""
    lag = z_mid * math.tan(cutter.helix_rad) / cutter.radius_m
    arrays = (z_mid, radius, kappa, width, lag)
    for array in arrays:
        array.setflags(write=False)
    return CutterSlices(*arrays)
