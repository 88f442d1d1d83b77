"""Cutter geometry: flat, ball and bull-nose end mills as solids of revolution about +z.

Units: the geometry package works in mm (every length's name ends in ``_mm``) and rad; it sits
next to the NC layer, whose tool-tip positions (``SampleChunk.tcp_mm``) are in mm.

The cutting envelope is the solid swept by the cutting edges in one spindle turn. For a tool
with radius ``R``, corner radius ``rc`` (0 flat, ``R`` ball, between for a bull nose) and fluted
length ``L``, measured from the tool tip up the tool axis (+z), the envelope's local radius at a
height ``z`` above the tip is

.. math::

    r(z) = R - r_c + \\sqrt{r_c^2 - (r_c - z)^2} \\quad (0 \\le z < r_c), \\qquad
    r(z) = R \\quad (r_c \\le z \\le L),

and the envelope is empty below the tip and above ``L``. The angle ``kappa`` between the tool
axis and the surface normal enters the uncut chip thickness ``h = f_z sin(phi) sin(kappa)``
(Altintas, *Manufacturing Automation*, 2nd ed., 2012, Sec. 2.6 for ball end mills).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from cnctwin.errors import ConfigError

if TYPE_CHECKING:
    from cnctwin.config.tools import ToolConfig

__all__ = ["Cutter", "CutterKind"]

#: ``"flat"`` end mill, ``"ball"`` nose or ``"bull"`` nose (with a corner radius).
CutterKind = Literal["flat", "ball", "bull"]


@dataclass(frozen=True, slots=True)
class Cutter:
    """A milling cutter whose axis is +z and whose tip is the lowest point of the envelope.

    Attributes
    ----------
    kind
        ``"flat"``, ``"ball"`` or ``"bull"``.
    diameter_mm
        Cutting diameter ``D = 2R`` in mm, > 0.
    flute_length_mm
        Length of the fluted (cutting) part from the tip up, mm, > 0 and, for a ball or bull
        nose, at least the corner radius. Material above it is not removed (see
        :attr:`~cnctwin.geometry.engagement.Engagement.above_flutes`).
    corner_radius_mm
        Corner radius ``rc`` in mm: 0 for ``flat``, ``D / 2`` for ``ball``, strictly between for
        ``bull``.
    flutes
        Number of flutes (teeth), >= 1.
    helix_rad
        Helix angle in rad, in [0, pi/2). The envelope does not depend on it; force models do.

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

    def __post_init__(self) -> None:
        d = self.diameter_mm
        if not (isinstance(d, (int, float)) and math.isfinite(d) and d > 0.0):
            raise ConfigError(f"diameter_mm={d!r}; give a finite cutter diameter > 0 mm")
        half = 0.5 * d
        rc = self.corner_radius_mm
        if self.kind == "flat":
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
        elif self.kind == "bull":
            if not (math.isfinite(rc) and 0.0 < rc < half):
                raise ConfigError(
                    f"corner_radius_mm={rc!r} for a bull-nose end mill; give 0 < rc < "
                    f"diameter_mm/2 ({half})"
                )
        else:
            raise ConfigError(f"kind={self.kind!r}; give 'flat', 'ball' or 'bull'")
        length = self.flute_length_mm
        if not (math.isfinite(length) and length > 0.0 and length >= self.corner_radius_mm):
            raise ConfigError(
                f"flute_length_mm={length!r}; give a finite length > 0 mm and at least the "
                f"corner radius ({self.corner_radius_mm} mm)"
            )
        if isinstance(self.flutes, bool) or not isinstance(self.flutes, int) or self.flutes < 1:
            raise ConfigError(f"flutes={self.flutes!r}; give an integer >= 1")
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

    @property
    def radius_mm(self) -> float:
        """Cutting radius ``R = D / 2`` in mm."""
        return 0.5 * self.diameter_mm

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
        r[(z < 0.0) | (z > self.flute_length_mm)] = 0.0
        return r

    def sin_kappa_at(self, z_mm: np.ndarray | float) -> np.ndarray:
        """``sin(kappa)`` at heights ``z_mm`` (mm) above the tip, kappa the angle in rad between
        the tool axis and the envelope's normal: 1 on the cylinder, ``sqrt(rc^2 - (rc - z)^2)/rc``
        on the corner (Altintas 2012, Sec. 2.6); 0 outside the envelope."""
        z = np.asarray(z_mm, dtype=np.float64)
        rc = self.corner_radius_mm
        s = np.ones(z.shape)
        if rc > 0.0:
            low = z < rc
            zc = np.clip(z[low], 0.0, rc)
            s[low] = np.sqrt(np.maximum(rc * rc - (rc - zc) ** 2, 0.0)) / rc
        s[(z < 0.0) | (z > self.flute_length_mm)] = 0.0
        return s

    def volume_mm3(self) -> float:
        """Volume of the cutting envelope in mm^3 (closed form, Pappus for the corner)."""
        big, rc, length = self.radius_mm, self.corner_radius_mm, self.flute_length_mm
        inner = big - rc
        # Corner part (0 <= z <= rc): disc of radius `inner` plus the quarter-torus ring, by
        # integrating pi r(z)^2 over z in closed form.
        corner = math.pi * (
            inner * inner * rc + 0.5 * math.pi * inner * rc * rc + (2.0 / 3.0) * rc**3
        )
        return corner + math.pi * big * big * (length - rc)
