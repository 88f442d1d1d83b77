"""End-mill geometry for the force model: local radius, lead angle and helix lag along the axis.

A flat, ball or bull-nose end mill is a profile of revolution: a corner arc of radius ``rc``
(0 for a flat end mill, ``D/2`` for a ball end mill) below a cylinder of radius ``R = D/2``.
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

from cnctwin.errors import ConfigError

if TYPE_CHECKING:
    from cnctwin.config.tools import ToolConfig

__all__ = ["CutterKind", "CutterSlices", "EndMill"]

CutterKind = Literal["flat", "ball", "bull"]


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
        Number of teeth (flutes) N, >= 1.
    helix_rad
        Helix angle beta in rad, 0 <= beta < pi/2 (right-hand helix for a clockwise spindle).
    kind
        ``"flat"``, ``"ball"`` or ``"bull"`` (nose with a corner radius).
    corner_radius_m
        Corner radius rc in m: 0 for ``flat``, ``D/2`` for ``ball`` (0 is taken as ``D/2``),
        strictly between 0 and ``D/2`` for ``bull``.
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

    def __post_init__(self) -> None:
        d = self.diameter_m
        if not (isinstance(d, (int, float)) and math.isfinite(d) and d > 0):
            raise ConfigError(f"diameter_m={d!r}; give a finite diameter > 0 m")
        if isinstance(self.teeth, bool) or not isinstance(self.teeth, (int, np.integer)):
            raise ConfigError(f"teeth={self.teeth!r}; give an integer >= 1")
        if self.teeth < 1:
            raise ConfigError(f"teeth={self.teeth!r}; give an integer >= 1")
        if not (math.isfinite(self.helix_rad) and 0.0 <= self.helix_rad < math.pi / 2):
            raise ConfigError(f"helix_rad={self.helix_rad!r}; give 0 <= helix < pi/2 rad")
        if not (math.isfinite(self.runout_m) and self.runout_m >= 0.0):
            raise ConfigError(f"runout_m={self.runout_m!r}; give a finite runout >= 0 m")
        if not math.isfinite(self.runout_angle_rad):
            raise ConfigError(f"runout_angle_rad={self.runout_angle_rad!r}; give a finite angle")
        half = d / 2.0
        rc = self.corner_radius_m
        if self.kind == "flat":
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
            raise ConfigError(f"kind={self.kind!r}; give 'flat', 'ball' or 'bull'")

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
    lag = z_mid * math.tan(cutter.helix_rad) / cutter.radius_m
    arrays = (z_mid, radius, kappa, np.diff(s), lag)
    for array in arrays:
        array.setflags(write=False)
    return CutterSlices(*arrays)
