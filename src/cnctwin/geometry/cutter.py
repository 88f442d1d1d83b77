"""Cutter geometry: flat, ball, bull-nose, conical (V-bit) and snub-nose end mills as solids of
revolution about +z.

Units: the geometry package works in mm (every length's name ends in ``_mm``) and rad; it sits
next to the NC layer, whose tool-tip positions (``SampleChunk.tcp_mm``) are in mm.

The cutting envelope is the solid swept by the cutting edges in one spindle turn. For a tool
with radius ``R``, corner radius ``rc`` (0 flat, ``R`` ball, between for a bull nose) and fluted
length ``L``, measured from the tool tip up the tool axis (+z), the envelope's local radius at a
height ``z`` above the tip is

.. math::

    r(z) = R - r_c + \\sqrt{r_c^2 - (r_c - z)^2} \\quad (0 \\le z < r_c), \\qquad
    r(z) = R \\quad (r_c \\le z \\le L),

and the envelope is empty below the tip and above ``L``. A conical tool (a V-bit) and a snub-nose
tool (a truncated cone, flat at the tip) with tip radius ``r_t`` (0 for the cone) and included
tip angle ``theta`` widen along a cone up to ``R`` at the cone height
``h_c = (R - r_t) / tan(theta / 2)``, then stay cylindrical up to ``L``:

.. math::

    r(z) = r_t + z \\tan(\\theta / 2) \\quad (0 \\le z < h_c), \\qquad
    r(z) = R \\quad (h_c \\le z \\le L).

CAMotics' ``conical`` and ``snubnose`` tools are cones over their whole ``length`` (``h_c = L``,
CAMotics' ``ConicSweep``), which :meth:`Cutter.conical` and :meth:`Cutter.snub` give when no
angle is named. The angle ``kappa`` between the tool axis and the surface normal enters the
uncut chip thickness ``h = f_z sin(phi) sin(kappa)`` (Altintas, *Manufacturing Automation*, 2nd
ed., 2012, Sec. 2.6 for ball end mills); on a cone ``sin(kappa) = cos(theta / 2)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from cnctwin.config.tools import MAX_FLUTES
from cnctwin.errors import ConfigError

if TYPE_CHECKING:
    from cnctwin.config.tools import ToolConfig

__all__ = ["Cutter", "CutterKind"]

#: ``"flat"`` end mill, ``"ball"`` nose, ``"bull"`` nose (with a corner radius), ``"conical"``
#: (a V-bit, pointed) or ``"snub"`` nose (a cone with a flat tip).
CutterKind = Literal["flat", "ball", "bull", "conical", "snub"]
_CONES = ("conical", "snub")
#: A cone height within this fraction above the fluted length is the fluted length (the angle
#: of a cone over the whole length, computed from it, rounds either way).
_CONE_REL_TOL = 1e-9


@dataclass(frozen=True, slots=True)
class Cutter:
    """A milling cutter whose axis is +z and whose tip is the lowest point of the envelope.

    Attributes
    ----------
    kind
        ``"flat"``, ``"ball"``, ``"bull"``, ``"conical"`` or ``"snub"``.
    diameter_mm
        Cutting diameter ``D = 2R`` in mm, > 0.
    flute_length_mm
        Length of the fluted (cutting) part from the tip up, mm, > 0 and, for a ball or bull
        nose, at least the corner radius; for a cone, at least the cone height. Material above
        it is not removed (see :attr:`~cnctwin.geometry.engagement.Engagement.above_flutes`).
    corner_radius_mm
        Corner radius ``rc`` in mm: 0 for ``flat``, ``conical`` and ``snub``, ``D / 2`` for
        ``ball``, strictly between for ``bull``.
    flutes
        Number of flutes (teeth), 1 to 100 (:data:`~cnctwin.config.tools.MAX_FLUTES`).
    helix_rad
        Helix angle in rad, in [0, pi/2). The envelope does not depend on it; force models do.
    tip_diameter_mm
        Diameter of the flat tip of a ``snub`` nose, mm, in (0, D); 0 for every other kind.
    tip_angle_rad
        Included angle ``theta`` of the cone of a ``conical`` or ``snub`` tool, rad, in
        (0, pi) (90 degrees for a common V-bit); 0 for every other kind.

    Raises
    ------
    ConfigError
        On a value outside those ranges.
    """

    kind: CutterKind
    diameter_mm: float
    flute_length_mm: float
    corner_radius_mm: float = 0.0
    flutes: int = 2
    helix_rad: float = math.radians(30.0)
    tip_diameter_mm: float = 0.0
    tip_angle_rad: float = 0.0

    def __post_init__(self) -> None:
        d = self.diameter_mm
        if not (isinstance(d, (int, float)) and math.isfinite(d) and d > 0.0):
            raise ConfigError(f"diameter_mm={d!r}; give a finite cutter diameter > 0 mm")
        half = 0.5 * d
        rc = self.corner_radius_mm
        if self.kind not in ("flat", "ball", "bull", *_CONES):
            raise ConfigError(
                f"kind={self.kind!r}; give 'flat', 'ball', 'bull', 'conical' or 'snub'"
            )
        if self.kind in _CONES:
            self._check_cone(d, rc)
        elif self.tip_diameter_mm != 0.0 or self.tip_angle_rad != 0.0:
            raise ConfigError(
                f"tip_diameter_mm={self.tip_diameter_mm!r}, tip_angle_rad={self.tip_angle_rad!r}"
                f" for kind {self.kind!r}; they must be 0 (use kind 'conical' or 'snub')"
            )
        elif self.kind == "flat":
            if rc != 0.0:
                raise ConfigError(
                    f"corner_radius_mm={rc!r} for a flat end mill; it must be 0 (use kind 'bull')"
                )
        elif self.kind == "ball":
            if not math.isclose(rc, half, rel_tol=1e-9, abs_tol=1e-12):
                raise ConfigError(
                    f"corner_radius_mm={rc!r} for a ball end mill; it must be diameter_mm/2 "
                    f"({half})"
                )
            object.__setattr__(self, "corner_radius_mm", half)
        elif not (math.isfinite(rc) and 0.0 < rc < half):
            raise ConfigError(
                f"corner_radius_mm={rc!r} for a bull-nose end mill; give 0 < rc < "
                f"diameter_mm/2 ({half})"
            )
        length = self.flute_length_mm
        if not (math.isfinite(length) and length > 0.0 and length >= self.corner_radius_mm):
            raise ConfigError(
                f"flute_length_mm={length!r}; give a finite length > 0 mm and at least the "
                f"corner radius ({self.corner_radius_mm} mm)"
            )
        if self.kind in _CONES:
            height = (half - 0.5 * self.tip_diameter_mm) / math.tan(0.5 * self.tip_angle_rad)
            if height > length * (1.0 + _CONE_REL_TOL):
                degrees = math.degrees(self.tip_angle_rad)
                raise ConfigError(
                    f"flute_length_mm={length!r}; the cone of this {degrees:g} degree {self.kind}"
                    f" tool is {height:g} mm high: give a flute length at least that, or a "
                    "wider tip angle"
                )
        if (
            isinstance(self.flutes, bool)
            or not isinstance(self.flutes, int)
            or not 1 <= self.flutes <= MAX_FLUTES
        ):
            raise ConfigError(f"flutes={self.flutes!r}; give an integer from 1 to {MAX_FLUTES}")
        if not (math.isfinite(self.helix_rad) and 0.0 <= self.helix_rad < 0.5 * math.pi):
            raise ConfigError(f"helix_rad={self.helix_rad!r}; give an angle in [0, pi/2) rad")

    @classmethod
    def flat(
        cls,
        diameter_mm: float,
        flute_length_mm: float,
        *,
        flutes: int = 2,
        helix_rad: float = math.radians(30.0),
    ) -> Cutter:
        """A flat end mill of diameter ``diameter_mm`` (mm) and fluted length (mm)."""
        return cls("flat", diameter_mm, flute_length_mm, 0.0, flutes, helix_rad)

    @classmethod
    def ball(
        cls,
        diameter_mm: float,
        flute_length_mm: float,
        *,
        flutes: int = 2,
        helix_rad: float = math.radians(30.0),
    ) -> Cutter:
        """A ball end mill of diameter ``diameter_mm`` (mm) and fluted length (mm)."""
        return cls("ball", diameter_mm, flute_length_mm, 0.5 * diameter_mm, flutes, helix_rad)

    @classmethod
    def bull(
        cls,
        diameter_mm: float,
        corner_radius_mm: float,
        flute_length_mm: float,
        *,
        flutes: int = 2,
        helix_rad: float = math.radians(30.0),
    ) -> Cutter:
        """A bull-nose end mill: diameter, corner radius and fluted length in mm."""
        return cls("bull", diameter_mm, flute_length_mm, corner_radius_mm, flutes, helix_rad)

    @classmethod
    def conical(
        cls,
        diameter_mm: float,
        flute_length_mm: float,
        *,
        tip_angle_rad: float | None = None,
        flutes: int = 2,
        helix_rad: float = math.radians(30.0),
    ) -> Cutter:
        """A conical tool (V-bit), pointed, of diameter ``diameter_mm`` (mm).

        Parameters
        ----------
        diameter_mm
            Largest cutting diameter, mm.
        flute_length_mm
            Fluted length, mm.
        tip_angle_rad
            Included tip angle, rad. ``None``: the cone spans the whole fluted length, as
            CAMotics models a ``conical`` tool of that ``diameter`` and ``length``:
            ``2 atan(D / (2 L))``.
        flutes, helix_rad
            Number of flutes and helix angle (rad).
        """
        angle = (
            2.0 * math.atan2(0.5 * diameter_mm, flute_length_mm)
            if tip_angle_rad is None
            else tip_angle_rad
        )
        return cls("conical", diameter_mm, flute_length_mm, 0.0, flutes, helix_rad, 0.0, angle)

    @classmethod
    def snub(
        cls,
        diameter_mm: float,
        tip_diameter_mm: float,
        flute_length_mm: float,
        *,
        tip_angle_rad: float | None = None,
        flutes: int = 2,
        helix_rad: float = math.radians(30.0),
    ) -> Cutter:
        """A snub-nose tool: a cone from a flat tip of ``tip_diameter_mm`` to ``diameter_mm`` (mm).

        ``tip_angle_rad`` (rad) as for :meth:`conical`; ``None``: the cone spans the whole fluted
        length (CAMotics' ``snubnose`` with ``snub_diameter``): ``2 atan((D - d_t) / (2 L))``.
        """
        angle = (
            2.0 * math.atan2(0.5 * (diameter_mm - tip_diameter_mm), flute_length_mm)
            if tip_angle_rad is None
            else tip_angle_rad
        )
        return cls(
            "snub", diameter_mm, flute_length_mm, 0.0, flutes, helix_rad, tip_diameter_mm, angle
        )

    @classmethod
    def from_tool_config(cls, tool: ToolConfig, flute_length_mm: float | None = None) -> Cutter:
        """The cutter of a configured tool (``[[tools]]`` entry, mm and degrees).

        Parameters
        ----------
        tool
            The tool's configuration.
        flute_length_mm
            Fluted length in mm when the configuration gives none.

        Raises
        ------
        ConfigError
            When neither the tool nor ``flute_length_mm`` gives a fluted length.
        """
        length = tool.flute_length_mm if tool.flute_length_mm is not None else flute_length_mm
        if length is None:
            raise ConfigError(
                f"tool {tool.number} has no flute_length_mm; set it in the tool's configuration"
            )
        return cls(
            tool.kind,
            tool.diameter_mm,
            length,
            float(tool.corner_radius_mm or 0.0),
            tool.flutes,
            math.radians(tool.helix_deg),
        )

    def _check_cone(self, diameter: float, corner: float) -> None:
        """Validate a conical or snub-nose tool's corner radius, tip diameter and angle."""
        if corner != 0.0:
            raise ConfigError(f"corner_radius_mm={corner!r} for a {self.kind} tool; it must be 0")
        tip = self.tip_diameter_mm
        if self.kind == "conical" and tip != 0.0:
            raise ConfigError(
                f"tip_diameter_mm={tip!r} for a conical tool; it must be 0 (use kind 'snub')"
            )
        if self.kind == "snub" and not (math.isfinite(tip) and 0.0 < tip < diameter):
            raise ConfigError(
                f"tip_diameter_mm={tip!r} for a snub-nose tool; give 0 < tip < diameter_mm "
                f"({diameter})"
            )
        angle = self.tip_angle_rad
        if not (math.isfinite(angle) and 0.0 < angle < math.pi):
            raise ConfigError(
                f"tip_angle_rad={angle!r} for a {self.kind} tool; give an included angle in "
                "(0, pi) rad"
            )

    @property
    def radius_mm(self) -> float:
        """Cutting radius ``R = D / 2`` in mm."""
        return 0.5 * self.diameter_mm

    @property
    def flat_radius_mm(self) -> float:
        """Radius of the flat bottom face in mm: ``R`` flat, ``R - rc`` bull, the tip radius
        of a snub nose, 0 for a ball or a cone."""
        if self.kind in _CONES:
            return 0.5 * self.tip_diameter_mm
        return self.radius_mm - self.corner_radius_mm

    @property
    def cone_height_mm(self) -> float:
        """Height in mm above the tip where the cone of a conical or snub tool reaches the full
        radius, ``(R - r_t) / tan(theta / 2)`` (at most the fluted length); 0 for other kinds."""
        if self.kind not in _CONES:
            return 0.0
        slope = math.tan(0.5 * self.tip_angle_rad)
        return min((self.radius_mm - self.flat_radius_mm) / slope, self.flute_length_mm)

    def radius_at(self, z_mm: np.ndarray | float) -> np.ndarray:
        """Local envelope radius ``r(z)`` in mm at heights ``z_mm`` (mm) above the tip.

        Zero below the tip and above the fluted length (outside the envelope).
        """
        z = np.asarray(z_mm, dtype=np.float64)
        big = self.radius_mm
        rc = self.corner_radius_mm
        r = np.full(z.shape, big)
        if rc > 0.0:
            low = z < rc
            zc = np.clip(z[low], 0.0, rc)
            r[low] = big - rc + np.sqrt(np.maximum(rc * rc - (rc - zc) ** 2, 0.0))
        elif self.kind in _CONES:
            low = z < self.cone_height_mm
            r[low] = self.flat_radius_mm + np.maximum(z[low], 0.0) * math.tan(
                0.5 * self.tip_angle_rad
            )
        r[(z < 0.0) | (z > self.flute_length_mm)] = 0.0
        return r

    def sin_kappa_at(self, z_mm: np.ndarray | float) -> np.ndarray:
        """``sin(kappa)`` at heights ``z_mm`` (mm) above the tip, kappa the angle in rad between
        the tool axis and the envelope's normal: 1 on the cylinder, ``sqrt(rc^2 - (rc - z)^2)/rc``
        on the corner (Altintas 2012, Sec. 2.6), ``cos(theta / 2)`` on a cone of included angle
        ``theta`` (its normal leans ``theta / 2`` from the horizontal); 0 outside the envelope."""
        z = np.asarray(z_mm, dtype=np.float64)
        rc = self.corner_radius_mm
        s = np.ones(z.shape)
        if rc > 0.0:
            low = z < rc
            zc = np.clip(z[low], 0.0, rc)
            s[low] = np.sqrt(np.maximum(rc * rc - (rc - zc) ** 2, 0.0)) / rc
        elif self.kind in _CONES:
            s[z < self.cone_height_mm] = math.cos(0.5 * self.tip_angle_rad)
        s[(z < 0.0) | (z > self.flute_length_mm)] = 0.0
        return s

    def volume_mm3(self) -> float:
        """Volume of the cutting envelope in mm^3 (closed form: Pappus for the corner, the
        frustum ``pi h (r_t^2 + r_t R + R^2) / 3`` for a cone)."""
        big, rc, length = self.radius_mm, self.corner_radius_mm, self.flute_length_mm
        if self.kind in _CONES:
            tip, height = self.flat_radius_mm, self.cone_height_mm
            cone = math.pi * height * (tip * tip + tip * big + big * big) / 3.0
            return cone + math.pi * big * big * (length - height)
        inner = big - rc
        # Corner part (0 <= z <= rc): disc of radius `inner` plus the quarter-torus ring, by
        # integrating pi r(z)^2 over z in closed form.
        corner = math.pi * (
            inner * inner * rc + 0.5 * math.pi * inner * rc * rc + (2.0 / 3.0) * rc**3
        )
        return corner + math.pi * big * big * (length - rc)
