"""The cutter: flat, ball, bull-nose, conical (V-bit) and snub-nose end mills, twist drills and
taps as solids of revolution about +z, for the material removal, the engagement and the force
model alike.

Units: a :class:`Cutter` stores its lengths in mm (every length's name ends in ``_mm``), as the
``[[tools]]`` configuration and the geometry and NC layers do, and its angles in rad (the
configuration's degrees are converted once, in :meth:`Cutter.from_tool_config`). The force model
(:mod:`cnctwin.mechanics`, SI) reads the SI views: :attr:`Cutter.diameter_m`,
:attr:`Cutter.radius_m`, :attr:`Cutter.corner_radius_m`, :attr:`Cutter.tip_diameter_m`,
:attr:`Cutter.runout_m` and :meth:`Cutter.slices` (heights in m). This class is the one unit
boundary between the mm of the geometry and the m of the mechanics.

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
angle is named. A twist drill (:meth:`Cutter.drill`) sweeps the same envelope as a conical tool
whose included angle is the drill's point angle (``h_c = R / tan(theta / 2)``, 0.30 D at
118 degrees); its chisel-edge width (``web_mm``) only enters the force model. A tap
(:meth:`Cutter.tap`) sweeps the cylinder of its nominal (major) diameter, flat at the tip (its
chamfer is not modelled); its thread pitch (``pitch_mm``) enters the torque model. The forces of
both are those of :mod:`cnctwin.mechanics.drilling`, not the milling model.

The angle ``kappa`` between the tool axis and the surface normal enters the
uncut chip thickness ``h = f_z sin(phi) sin(kappa)`` (Altintas, *Manufacturing Automation*, 2nd
ed., 2012, Sec. 2.6 for ball end mills); on a cone ``sin(kappa) = cos(theta / 2)``.

For the force model the edge is cut into axial slices (:meth:`Cutter.slices`): each has a local
radius, a lead angle ``kappa``, a chip width (its length along the profile) and the lag angle
of the helical flute, ``psi = z tan(beta) / R`` at height ``z`` (Lee & Altintas (1996),
"Prediction of ball-end milling forces from orthogonal cutting data", IJMTM 36(9); Altintas
2012, ch. 2). A radial runout ``rho`` (a parallel offset of the tool axis) changes each
tooth's radius (Kline & DeVor (1983), IJMTDR 23(2)); the envelope uses the nominal radius.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np

from cnctwin.config import MAX_FLUTES, CutterKind
from cnctwin.errors import ConfigError

if TYPE_CHECKING:
    from cnctwin.config import ToolConfig

__all__ = ["AXIAL_KINDS", "Cutter", "CutterSlices"]

#: Kinds whose tip is a cone (a drill's point is a cone of its point angle).
_CONES = ("conical", "snub", "drill")
#: Kinds that cut along their axis (the drilling model, :mod:`cnctwin.mechanics.drilling`).
AXIAL_KINDS = ("drill", "tap")
#: A cone height within this fraction above the fluted length is the fluted length (the angle
#: of a cone over the whole length, computed from it, rounds either way).
_CONE_REL_TOL = 1e-9


@dataclass(frozen=True)
class CutterSlices:
    """Local geometry of axial slices of a cutter (arrays of one value per slice).

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


@dataclass(frozen=True, slots=True)
class Cutter:
    """A milling cutter whose axis is +z and whose tip is the lowest point of the envelope.

    The one tool geometry of the project: the dexel removal and engagement
    (:mod:`cnctwin.geometry`), the force model (:mod:`cnctwin.mechanics`), the time-domain
    vibration model, the twin and the virtual machine all take it. Lengths are stored in mm and
    angles in rad; the force model reads the SI views (``*_m`` properties and :meth:`slices`),
    the unit boundary of the module notes. :meth:`from_tool_config` is the one factory from a
    ``[[tools]]`` entry (mm and degrees).

    Attributes
    ----------
    kind
        ``"flat"``, ``"ball"``, ``"bull"``, ``"conical"``, ``"snub"``, ``"drill"`` or ``"tap"``
        (:data:`~cnctwin.config.tools.CutterKind`).
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
    runout_mm
        Radial runout (parallel offset of the tool axis from the spindle axis) ``rho`` in mm,
        >= 0. Only the force model uses it (:meth:`tooth_radius_offsets_m`); the envelope keeps
        the nominal radius.
    runout_angle_rad
        Direction of that offset, ``lambda`` in rad, measured from tooth 0 in the direction of
        rotation: tooth j's radius becomes ``R + rho cos(j 2 pi / N - lambda)``.
    web_mm
        Chisel-edge (web) width of a ``drill`` in mm, in [0, D); 0 for every other kind.
    pitch_mm
        Thread pitch of a ``tap`` in mm, in (0, D/2); 0 for every other kind.

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
    runout_mm: float = 0.0
    runout_angle_rad: float = 0.0
    web_mm: float = 0.0
    pitch_mm: float = 0.0

    def __post_init__(self) -> None:
        d = self.diameter_mm
        if not (isinstance(d, (int, float)) and math.isfinite(d) and d > 0.0):
            raise ConfigError(f"diameter_mm={d!r}; give a finite cutter diameter > 0 mm")
        half = 0.5 * d
        rc = self.corner_radius_mm
        if self.kind not in ("flat", "ball", "bull", "tap", *_CONES):
            raise ConfigError(
                f"kind={self.kind!r}; give 'flat', 'ball', 'bull', 'conical', 'snub', 'drill' "
                "or 'tap'"
            )
        self._check_axial(d)
        if self.kind in _CONES:
            self._check_cone(d, rc)
        elif self.tip_diameter_mm != 0.0 or self.tip_angle_rad != 0.0:
            raise ConfigError(
                f"tip_diameter_mm={self.tip_diameter_mm!r}, tip_angle_rad={self.tip_angle_rad!r}"
                f" for kind {self.kind!r}; they must be 0 (use kind 'conical' or 'snub')"
            )
        elif self.kind in ("flat", "tap"):
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
        if not (math.isfinite(self.runout_mm) and self.runout_mm >= 0.0):
            raise ConfigError(f"runout_mm={self.runout_mm!r}; give a finite runout >= 0 mm")
        if not math.isfinite(self.runout_angle_rad):
            raise ConfigError(f"runout_angle_rad={self.runout_angle_rad!r}; give a finite angle")

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
    def drill(
        cls,
        diameter_mm: float,
        flute_length_mm: float,
        *,
        point_angle_rad: float = math.radians(118.0),
        web_mm: float = 0.0,
        lips: int = 2,
        helix_rad: float = math.radians(30.0),
    ) -> Cutter:
        """A twist drill: diameter and fluted length in mm, point angle in rad (118 degrees by
        default), chisel-edge width ``web_mm`` in mm (0: no chisel edge) and ``lips`` cutting
        lips. Its envelope is the cone of its point angle (see the module notes)."""
        return cls(
            "drill", diameter_mm, flute_length_mm, 0.0, lips, helix_rad, 0.0, point_angle_rad,
            web_mm=web_mm,
        )  # fmt: skip

    @classmethod
    def tap(
        cls,
        diameter_mm: float,
        pitch_mm: float,
        flute_length_mm: float,
        *,
        flutes: int = 3,
    ) -> Cutter:
        """A cutting tap: nominal (major) diameter, thread pitch and fluted length in mm.
        Its envelope is the cylinder of the nominal diameter (see the module notes)."""
        return cls("tap", diameter_mm, flute_length_mm, 0.0, flutes, 0.0, pitch_mm=pitch_mm)

    @classmethod
    def from_tool_config(cls, tool: ToolConfig, flute_length_mm: float | None = None) -> Cutter:
        """The cutter of a configured tool (``[[tools]]`` entry, mm and degrees): every kind,
        with its corner radius, tip diameter and tip angle (degrees to rad).

        Parameters
        ----------
        tool
            The tool's configuration.
        flute_length_mm
            Fluted length in mm when the configuration gives none.

        Raises
        ------
        ConfigError
            When neither the tool nor ``flute_length_mm`` gives a fluted length, or the cone of
            a conical or snub tool is higher than its fluted length (the message names the tool).
        """
        length = tool.flute_length_mm if tool.flute_length_mm is not None else flute_length_mm
        if length is None:
            raise ConfigError(
                f"tool {tool.number} has no flute_length_mm; set it in the tool's configuration"
            )
        helix = math.radians(tool.helix_deg)
        angle = None if tool.tip_angle_deg is None else math.radians(tool.tip_angle_deg)
        try:
            if tool.kind == "conical":
                return cls.conical(
                    tool.diameter_mm, length, tip_angle_rad=angle, flutes=tool.flutes,
                    helix_rad=helix,
                )  # fmt: skip
            if tool.kind == "snub":
                return cls.snub(
                    tool.diameter_mm, float(tool.tip_diameter_mm or 0.0), length,
                    tip_angle_rad=angle, flutes=tool.flutes, helix_rad=helix,
                )  # fmt: skip
            if tool.kind == "drill":
                point = {} if angle is None else {"point_angle_rad": angle}
                return cls.drill(
                    tool.diameter_mm, length, web_mm=tool.web_mm, lips=tool.flutes,
                    helix_rad=helix, **point,
                )  # fmt: skip
            if tool.kind == "tap":
                return cls.tap(
                    tool.diameter_mm, float(tool.pitch_mm or 0.0), length, flutes=tool.flutes
                )
            return cls(
                tool.kind,
                tool.diameter_mm,
                length,
                float(tool.corner_radius_mm or 0.0),
                tool.flutes,
                helix,
            )
        except ConfigError as err:
            raise ConfigError(f"tool {tool.number}: {err}") from None

    def _check_axial(self, diameter: float) -> None:
        """Validate a drill's web and a tap's pitch (mm); both 0 for the other kinds."""
        web, pitch = self.web_mm, self.pitch_mm
        if self.kind == "drill":
            if not (math.isfinite(web) and 0.0 <= web < diameter):
                raise ConfigError(
                    f"web_mm={web!r} for a drill; give a chisel-edge width 0 <= web < "
                    f"diameter_mm ({diameter})"
                )
        elif web != 0.0:
            raise ConfigError(f"web_mm={web!r} for kind {self.kind!r}; it is only for a drill")
        if self.kind == "tap":
            if not (math.isfinite(pitch) and 0.0 < pitch < 0.5 * diameter):
                raise ConfigError(
                    f"pitch_mm={pitch!r} for a tap; give a thread pitch 0 < pitch < "
                    f"diameter_mm/2 ({0.5 * diameter})"
                )
        elif pitch != 0.0:
            raise ConfigError(f"pitch_mm={pitch!r} for kind {self.kind!r}; it is only for a tap")

    def _check_cone(self, diameter: float, corner: float) -> None:
        """Validate a conical or snub-nose tool's corner radius, tip diameter and angle."""
        if corner != 0.0:
            raise ConfigError(f"corner_radius_mm={corner!r} for a {self.kind} tool; it must be 0")
        tip = self.tip_diameter_mm
        if self.kind in ("conical", "drill") and tip != 0.0:
            raise ConfigError(
                f"tip_diameter_mm={tip!r} for a {self.kind} tool; it must be 0 (use kind 'snub')"
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
    def diameter_m(self) -> float:
        """Cutting diameter ``D`` in m (SI view for the force model)."""
        return self.diameter_mm * 1e-3

    @property
    def radius_m(self) -> float:
        """Cutting radius ``R = D / 2`` in m (SI view for the force model)."""
        return self.diameter_m / 2.0

    @property
    def corner_radius_m(self) -> float:
        """Corner radius ``rc`` in m (SI view for the force model)."""
        return self.corner_radius_mm * 1e-3

    @property
    def tip_diameter_m(self) -> float:
        """Diameter of a snub nose's flat tip in m (SI view for the force model)."""
        return self.tip_diameter_mm * 1e-3

    @property
    def runout_m(self) -> float:
        """Radial runout ``rho`` in m (SI view for the force model)."""
        return self.runout_mm * 1e-3

    @property
    def pitch_rad(self) -> float:
        """Tooth spacing ``2 pi / N`` in rad."""
        return 2.0 * math.pi / self.flutes

    def tooth_radius_offsets_m(self) -> np.ndarray:
        """Radius of each tooth minus the nominal radius, in m: ``rho cos(j 2 pi/N - lambda)``.

        Kline & DeVor (1983), "The effect of runout on cutting geometry and forces in end
        milling", IJMTDR 23(2): a parallel axis offset rho changes each tooth's radius.
        """
        j = np.arange(self.flutes, dtype=np.float64)
        return self.runout_m * np.cos(j * self.pitch_rad - self.runout_angle_rad)

    def slices(self, z_bounds_m: np.ndarray) -> CutterSlices:
        """Local geometry of the axial slices between consecutive heights ``z_bounds_m``, for
        the force model (SI).

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


@lru_cache(maxsize=256)
def _slices(cutter: Cutter, z_bytes: bytes) -> CutterSlices:
    """:meth:`Cutter.slices`, cached (a twin asks for the same slices at every cycle)."""
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


def _cone_slices(cutter: Cutter, z: np.ndarray) -> CutterSlices:
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
    cutter: Cutter, z_mid: np.ndarray, radius: np.ndarray, kappa: np.ndarray, width: np.ndarray
) -> CutterSlices:
    """Slices with the helix lag ``psi = z tan(beta) / R`` (Altintas 2012, ch. 2), read-only."""
    lag = z_mid * math.tan(cutter.helix_rad) / cutter.radius_m
    arrays = (z_mid, radius, kappa, width, lag)
    for array in arrays:
        array.setflags(write=False)
    return CutterSlices(*arrays)
