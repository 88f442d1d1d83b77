"""Chatter stability lobes of milling and orthogonal cutting (turning, shaping).

Regenerative chatter: the tool-tip displacement ``r(t)`` in the x-y plane changes the chip by
``r(t) - r(t - tau)``, the difference between this pass and the one a delay ``tau`` earlier
(one tooth period ``2 pi / (N Omega)`` in milling, one revolution ``2 pi / Omega`` in turning).
The linear model is the delay-differential equation

    M q'' + C q' + K q = a Phi^T H(t) Phi (q(t) - q(t - tau)),

with ``q`` the modal displacements of the tool-tip modes (:class:`ToolMode`), ``Phi`` their
directions in the plane, ``a`` the depth of cut (chip width) in m and ``H(t)`` the directional
matrix per unit depth in N/m^2 (force on the tool per unit chip width and unit chip-thickness
change). Two methods give the critical depth per spindle speed:

- the zero-order approximation (:func:`zoa_lobes`; Altintas & Budak 1995, CIRP Annals 44,
  357-362): ``H`` replaced by its mean ``H0``; the eigenvalues ``mu`` of ``H0 G(i w)`` give the
  limiting depth ``a = 1 / (2 Re mu)`` and the phase ``epsilon = pi + 2 atan(Im mu / Re mu)``;
  the spindle speed of lobe k follows from ``w tau = epsilon + 2 pi k``. This is the textbook
  ``a_lim = -2 pi Lambda_R (1 + kappa^2) / (N Kt)`` with ``Lambda = -1 / lambda`` and
  ``mu = N Kt lambda / (4 pi)`` written without the milling-only factors, so that the same
  code does orthogonal cutting, where it reduces to ``a_lim = -1 / (2 Kf Re G_o)`` (Altintas,
  *Manufacturing Automation*, 2000, ch. 3). It is exact when ``H`` is constant (turning,
  slotting with an even number of teeth >= 4) and misses the period-doubling (flip) lobes of
  intermittent cutting;
- the first-order semi-discretization (:func:`sdm_lobes`, :func:`floquet_multipliers`;
  Insperger & Stépán 2002, Int. J. Numer. Meth. Eng. 55, 503-518, and 2004, 61, 117-141):
  the Floquet transition matrix over one period with ``m`` steps (see
  :mod:`cnctwin.dynamics._sdm`); the cut is stable while its spectral radius is below 1.

Frame and angles are those of :mod:`cnctwin.mechanics.engagement` (Altintas 2012): x along the
feed, y normal to it, the immersion angle phi clockwise from +y, a tooth cutting for
``entry < phi < exit``. Helix and edge forces are left out: neither changes the linear
stability of a flat end mill in the zero-order or the semi-discretization model. Mode
directions are angles from +x toward +y.

Process damping (:class:`ProcessDamping`) is Royandi 2026, Eq. 3-6: a viscous force
``F_pd = (C_pd a h / V_c) v`` against the tool-tip velocity ``v``.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from cnctwin.dynamics import _sdm, _zoa
from cnctwin.errors import ConfigError, InputError
from cnctwin.mechanics import CuttingCoefficients, immersion_angles

__all__ = [
    "MillingProcess",
    "OrthogonalProcess",
    "ProcessDamping",
    "SdmCost",
    "StabilityLobes",
    "ToolDynamics",
    "ToolMode",
    "floquet_multipliers",
    "sdm_cost",
    "sdm_lobes",
    "zoa_absolute_depth",
    "zoa_lobes",
]

logger = logging.getLogger(__name__)

_TWO_PI = 2.0 * math.pi
# The automatic semi-discretization grid (steps=None, _auto_grid): steps per cycle of the
# highest mode where a tooth cuts and in free flight (solved exactly: only the chatter
# frequency's harmonics need its samples), least steps per period where teeth cut, and least
# steps in each stretch of cutting.
_CUT_STEPS_PER_CYCLE = 30
_FREE_STEPS_PER_CYCLE = 10
_MIN_STEPS = 40
_MIN_CUT_STEPS = 20


def _finite(name: str, value: float, low: float = 0.0, strict: bool = True) -> float:
    """``value`` as a float, checked finite and above ``low`` (or at least, if not strict)."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = math.nan
    ok = math.isfinite(number) and (number > low if strict else number >= low)
    if not ok:
        relation = ">" if strict else ">="
        raise ConfigError(f"{name}={value!r}; give a finite number {relation} {low:g}")
    return number


@dataclass(frozen=True)
class ToolMode:
    """One vibration mode of the tool tip, along one direction of the x-y plane.

    The mode is normalised to the tool tip: a modal displacement ``q`` moves the tip by
    ``q (cos theta, sin theta)`` and a force ``F`` at the tip excites it with
    ``(cos theta, sin theta) . F``, so its direct FRF is ``1 / (k (1 - r^2 + 2 i zeta r))``,
    ``r = w / wn`` (Royandi 2026, Eq. 13).

    Attributes
    ----------
    frequency_rad_s
        Undamped natural frequency ``wn`` in rad/s, > 0.
    damping_ratio
        Viscous damping ratio ``zeta``, 0 <= zeta < 1.
    stiffness_n_m
        Modal stiffness ``k`` in N/m, > 0; the modal mass is ``k / wn^2``.
    direction_rad
        Direction ``theta`` of the mode in rad, from +x toward +y (0: x, pi/2: y).
    """

    frequency_rad_s: float
    damping_ratio: float
    stiffness_n_m: float
    direction_rad: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "frequency_rad_s", _finite("frequency", self.frequency_rad_s))
        zeta = _finite("damping_ratio", self.damping_ratio, strict=False)
        if zeta >= 1.0:
            raise ConfigError(f"damping_ratio={zeta!r}; give 0 <= damping_ratio < 1")
        object.__setattr__(self, "damping_ratio", zeta)
        object.__setattr__(self, "stiffness_n_m", _finite("stiffness", self.stiffness_n_m))
        angle = self.direction_rad
        object.__setattr__(self, "direction_rad", _finite("direction", angle, -math.inf))

    @classmethod
    def from_hz(
        cls,
        frequency_hz: float,
        damping_ratio: float,
        *,
        stiffness_n_m: float | None = None,
        mass_kg: float | None = None,
        direction_rad: float = 0.0,
    ) -> ToolMode:
        """A mode from its natural frequency in Hz and either its modal stiffness or mass.

        Parameters
        ----------
        frequency_hz
            Undamped natural frequency in Hz.
        damping_ratio
            Viscous damping ratio.
        stiffness_n_m, mass_kg
            Modal stiffness in N/m or modal mass in kg (``k = m wn^2``); give exactly one.
        direction_rad
            Direction in rad from +x toward +y.
        """
        wn = _TWO_PI * _finite("frequency_hz", frequency_hz)
        if (stiffness_n_m is None) == (mass_kg is None):
            raise ConfigError("give either the modal stiffness (N/m) or the modal mass (kg)")
        if stiffness_n_m is not None:
            k = float(stiffness_n_m)
        else:
            k = _finite("mass", mass_kg) * wn * wn  # type: ignore[arg-type]
        return cls(wn, damping_ratio, float(k), direction_rad)

    @classmethod
    def from_modal(cls, mode: object, direction_rad: float = 0.0) -> ToolMode:
        """The tool mode of a fitted :class:`cnctwin.dynamics.Mode` (``omega_n``, ``zeta``,
        ``stiffness``) along ``direction_rad``; the fit must be of a driving-point FRF."""
        try:
            w, zeta, k = mode.omega_n, mode.zeta, mode.stiffness  # type: ignore[attr-defined]
        except AttributeError:
            raise InputError(f"{mode!r} is not a mode of a modal fit") from None
        return cls(w, zeta, k, direction_rad)

    @property
    def frequency_hz(self) -> float:
        """Undamped natural frequency in Hz."""
        return self.frequency_rad_s / _TWO_PI

    @property
    def mass_kg(self) -> float:
        """Modal mass ``k / wn^2`` in kg."""
        return self.stiffness_n_m / self.frequency_rad_s**2

    def receptance(self, frequency_rad_s: np.ndarray | float) -> np.ndarray:
        """Direct FRF (receptance) along the mode's direction in m/N at ``w`` in rad/s."""
        r = np.asarray(frequency_rad_s, dtype=np.float64) / self.frequency_rad_s
        return 1.0 / (self.stiffness_n_m * (1.0 - r * r + 2j * self.damping_ratio * r))


@dataclass(frozen=True)
class ToolDynamics:
    """The tool-tip dynamics in the x-y plane: a set of directed modes.

    Attributes
    ----------
    modes
        At least one :class:`ToolMode`.
    """

    modes: tuple[ToolMode, ...]

    def __post_init__(self) -> None:
        modes = tuple(self.modes)
        if not modes or not all(isinstance(mode, ToolMode) for mode in modes):
            raise ConfigError("tool dynamics need at least one ToolMode")
        object.__setattr__(self, "modes", modes)

    @classmethod
    def from_xy(cls, x: Sequence[ToolMode] = (), y: Sequence[ToolMode] = ()) -> ToolDynamics:
        """Modes flexible along x (feed) and along y (normal); their own directions are reset.

        Parameters
        ----------
        x, y
            Modes of each direction (either may be empty, not both).
        """
        modes = [
            ToolMode(m.frequency_rad_s, m.damping_ratio, m.stiffness_n_m, angle)
            for group, angle in ((x, 0.0), (y, 0.5 * math.pi))
            for m in group
        ]
        return cls(tuple(modes))

    @property
    def directions(self) -> np.ndarray:
        """``(2, n)`` unit vectors of the modes' directions."""
        angles = np.array([m.direction_rad for m in self.modes])
        return np.vstack((np.cos(angles), np.sin(angles)))

    def frf(self, frequency_rad_s: np.ndarray | float) -> np.ndarray:
        """Tool-tip FRF matrix ``G(i w)`` in m/N.

        Parameters
        ----------
        frequency_rad_s
            Frequencies in rad/s, any shape S.

        Returns
        -------
        numpy.ndarray
            Complex, shape ``S + (2, 2)``: ``sum_i d_i d_i^T / (k_i (1 - r_i^2 + 2 i zeta_i r_i))``.
        """
        w = np.asarray(frequency_rad_s, dtype=np.float64)
        d = self.directions
        out = np.zeros(w.shape + (2, 2), dtype=np.complex128)
        for i, mode in enumerate(self.modes):
            out += mode.receptance(w)[..., None, None] * np.outer(d[:, i], d[:, i])
        return out


@dataclass(frozen=True)
class MillingProcess:
    """Milling with a flat end mill of evenly spaced teeth: the regenerative force model.

    A tooth at immersion ``phi`` inside ``(entry, exit)`` adds the force (on the tool, per unit
    depth, per unit change of chip thickness ``h = (dx sin phi + dy cos phi)``)
    ``[-Kt cos phi - Kr sin phi, Kt sin phi - Kr cos phi]`` (Altintas 2012, ch. 2 and 3;
    Insperger & Stépán 2004, Sec. 5; Royandi 2026, Eq. 8-12 in another angle convention).

    Attributes
    ----------
    teeth
        Number of teeth N, >= 1.
    tangential_pa
        Tangential cutting coefficient Kt (``Ktc``) in Pa (N/m^2), > 0.
    radial_pa
        Radial (normal) cutting coefficient Kr (``Krc``, Insperger's ``Kn``) in Pa.
    entry_rad, exit_rad
        Immersion interval in rad, ``0 <= entry < exit <= 2 pi``
        (:func:`cnctwin.mechanics.immersion_angles`).
    """

    teeth: int
    tangential_pa: float
    radial_pa: float
    entry_rad: float
    exit_rad: float

    def __post_init__(self) -> None:
        if isinstance(self.teeth, bool) or not isinstance(self.teeth, int) or self.teeth < 1:
            raise ConfigError(f"teeth={self.teeth!r}; give an integer >= 1")
        object.__setattr__(self, "tangential_pa", _finite("Kt", self.tangential_pa))
        object.__setattr__(self, "radial_pa", _finite("Kr", self.radial_pa, -math.inf))
        entry = _finite("entry", self.entry_rad, 0.0, strict=False)
        exit_ = _finite("exit", self.exit_rad, entry)
        if exit_ > _TWO_PI + 1e-12:
            raise ConfigError(f"exit={exit_!r} rad; give entry < exit <= 2 pi")
        object.__setattr__(self, "entry_rad", entry)
        object.__setattr__(self, "exit_rad", exit_)

    @classmethod
    def from_immersion(
        cls,
        teeth: int,
        coefficients: CuttingCoefficients,
        radial_immersion: float,
        *,
        down_milling: bool = True,
    ) -> MillingProcess:
        """Milling at a radial immersion ``ae / D`` (1 is a slot), up- or down-milling.

        Parameters
        ----------
        teeth
            Number of teeth.
        coefficients
            Cutting coefficients; the shear terms ``ktc`` and ``krc`` (Pa) are used.
        radial_immersion
            Radial depth over diameter, ``0 < ae / D <= 1``.
        down_milling
            Down- (climb) milling, exiting at phi = pi; False for up-milling, entering at 0.
        """
        ratio = _finite("radial immersion ae/D", radial_immersion)
        if ratio > 1.0:
            raise InputError(f"radial immersion ae/D={ratio!r}; give 0 < ae/D <= 1")
        entry, exit_ = immersion_angles(1.0, ratio, down_milling)
        return cls(teeth, coefficients.ktc, coefficients.krc, entry, exit_)

    def delay_s(self, spindle_rad_s: np.ndarray | float) -> np.ndarray:
        """Tooth period ``2 pi / (N Omega)`` in s at spindle speeds ``Omega`` in rad/s."""
        return _TWO_PI / (self.teeth * np.asarray(spindle_rad_s, dtype=np.float64))

    def directional_matrix(self, phi_rad: np.ndarray | float) -> np.ndarray:
        """Directional matrix of one tooth at immersion ``phi`` (whether cutting or not).

        Returns
        -------
        numpy.ndarray
            Shape ``phi.shape + (2, 2)`` in N/m^2: the force on the tool per unit depth and
            unit displacement difference ``r(t) - r(t - tau)``.
        """
        p = np.asarray(phi_rad, dtype=np.float64)
        s, c = np.sin(p), np.cos(p)
        kt, kr = self.tangential_pa, self.radial_pa
        out = np.empty(p.shape + (2, 2))
        out[..., 0, 0] = -(kt * c + kr * s) * s
        out[..., 0, 1] = -(kt * c + kr * s) * c
        out[..., 1, 0] = (kt * s - kr * c) * s
        out[..., 1, 1] = (kt * s - kr * c) * c
        return out

    def step_matrices(self, steps: int) -> np.ndarray:
        """Means of ``H(t) = sum_j g_j M(phi_j)`` over ``steps`` equal steps of a tooth period.

        The tooth j sits at ``phi = Omega t + 2 pi j / N``; the integrals over each step's part
        inside ``(entry, exit)`` are exact.

        Returns
        -------
        numpy.ndarray
            ``(steps, 2, 2)`` in N/m^2.
        """
        return self.interval_matrices(np.linspace(0.0, 1.0, steps + 1))

    def interval_matrices(self, nodes: np.ndarray) -> np.ndarray:
        """Means of ``H(t)`` (as :meth:`step_matrices`) between consecutive ``nodes``.

        Parameters
        ----------
        nodes
            Increasing fractions of the tooth period, from 0 to 1 (``m + 1`` of them).

        Returns
        -------
        numpy.ndarray
            ``(m, 2, 2)`` in N/m^2.
        """
        pitch = _TWO_PI / self.teeth
        fractions = np.asarray(nodes, dtype=np.float64)
        tooth = np.arange(self.teeth)[:, None] * pitch  # a revolution, tooth 0's view
        starts = tooth + fractions[None, :-1] * pitch
        ends = tooth + fractions[None, 1:] * pitch
        low = np.clip(starts, self.entry_rad, self.exit_rad)
        high = np.clip(ends, self.entry_rad, self.exit_rad)
        total = self._integral(low, high) / (ends - starts)[..., None, None]
        matrices: np.ndarray = total.sum(axis=0)
        return matrices

    def breakpoints(self) -> np.ndarray:
        """Fractions of the tooth period in ``[0, 1)`` where a tooth enters or leaves the cut
        (where ``H(t)`` jumps)."""
        pitch = _TWO_PI / self.teeth
        angles = np.array([self.entry_rad, self.exit_rad]) / pitch
        return np.unique(np.round(angles - np.floor(angles), 12) % 1.0)

    def mean_matrix(self) -> np.ndarray:
        """Mean directional matrix ``H0 = N / (2 pi) int_entry^exit M(phi) dphi`` in N/m^2.

        Equal to Altintas & Budak's ``N Kt / (4 pi) [alpha]`` (Altintas 2012, Eq. 3.53).
        """
        integral = self._integral(np.array([self.entry_rad]), np.array([self.exit_rad]))[0]
        mean: np.ndarray = self.teeth / _TWO_PI * integral
        return mean

    def spindle_rad_s(self, delay_s: np.ndarray | float) -> np.ndarray:
        """Spindle speed in rad/s whose tooth period is ``delay_s``."""
        return _TWO_PI / (self.teeth * np.asarray(delay_s, dtype=np.float64))

    def damping_projector(self) -> np.ndarray:
        """Directions of process damping: the whole x-y plane (Royandi 2026, Eq. 6-7)."""
        return np.eye(2)

    def _integral(self, low: np.ndarray, high: np.ndarray) -> np.ndarray:
        """``int_low^high M(phi) dphi`` elementwise, shape ``low.shape + (2, 2)``."""
        kt, kr = self.tangential_pa, self.radial_pa
        sc = 0.5 * (np.sin(high) ** 2 - np.sin(low) ** 2)
        wave = 0.25 * (np.sin(2.0 * high) - np.sin(2.0 * low))
        ss = 0.5 * (high - low) - wave
        cc = 0.5 * (high - low) + wave
        out = np.empty(low.shape + (2, 2))
        out[..., 0, 0] = -kt * sc - kr * ss
        out[..., 0, 1] = -kt * cc - kr * sc
        out[..., 1, 0] = kt * ss - kr * sc
        out[..., 1, 1] = kt * sc - kr * cc
        return out


@dataclass(frozen=True)
class OrthogonalProcess:
    """Orthogonal cutting (turning, boring, shaping): one chip regenerated once per revolution.

    The chip thickness grows with the tool's displacement along the unit vector ``n`` (angle
    ``chip_direction_rad``); the cutting force ``Kf a h`` pushes the tool back along ``-f``,
    ``f`` being ``n`` turned by ``force_angle_rad`` (beta). So ``H = -Kf f n^T`` and the
    oriented FRF is ``G_o = n^T G f = sum_i cos(theta_i) cos(theta_i - beta) G_i`` with the
    angles theta_i between the modes and ``n`` (Altintas, *Manufacturing Automation*, 2000,
    ch. 3; Tlusty).

    Attributes
    ----------
    cutting_coefficient_pa
        Cutting force coefficient Kf in Pa (N/m^2), > 0.
    chip_direction_rad
        Direction of ``n`` in rad from +x toward +y; default +y.
    force_angle_rad
        Angle beta between the cutting force and ``n``, rad.
    """

    cutting_coefficient_pa: float
    chip_direction_rad: float = 0.5 * math.pi
    force_angle_rad: float = 0.0

    def __post_init__(self) -> None:
        kf = _finite("Kf", self.cutting_coefficient_pa)
        object.__setattr__(self, "cutting_coefficient_pa", kf)
        for name in ("chip_direction_rad", "force_angle_rad"):
            object.__setattr__(self, name, _finite(name, getattr(self, name), -math.inf))

    def delay_s(self, spindle_rad_s: np.ndarray | float) -> np.ndarray:
        """One revolution ``2 pi / Omega`` in s at spindle speeds ``Omega`` in rad/s."""
        return _TWO_PI / np.asarray(spindle_rad_s, dtype=np.float64)

    def spindle_rad_s(self, delay_s: np.ndarray | float) -> np.ndarray:
        """Spindle speed in rad/s whose revolution lasts ``delay_s``."""
        return _TWO_PI / np.asarray(delay_s, dtype=np.float64)

    def mean_matrix(self) -> np.ndarray:
        """The constant directional matrix ``H = -Kf f n^T`` in N/m^2."""
        chi, beta = self.chip_direction_rad, self.force_angle_rad
        n = np.array([math.cos(chi), math.sin(chi)])
        f = np.array([math.cos(chi + beta), math.sin(chi + beta)])
        return -self.cutting_coefficient_pa * np.outer(f, n)

    def step_matrices(self, steps: int) -> np.ndarray:
        """``H`` on each of ``steps`` steps of a revolution, ``(steps, 2, 2)`` in N/m^2."""
        return np.broadcast_to(self.mean_matrix(), (steps, 2, 2)).copy()

    def interval_matrices(self, nodes: np.ndarray) -> np.ndarray:
        """``H`` between consecutive ``nodes`` (fractions of a revolution), ``(m, 2, 2)``
        in N/m^2."""
        return self.step_matrices(np.asarray(nodes).size - 1)

    def breakpoints(self) -> np.ndarray:
        """Where ``H`` jumps: nowhere (an empty array)."""
        return np.empty(0)

    def damping_projector(self) -> np.ndarray:
        """Direction of process damping: along ``n`` only (Royandi 2026, Eq. 4, 1-DOF form)."""
        chi = self.chip_direction_rad
        n = np.array([math.cos(chi), math.sin(chi)])
        return np.outer(n, n)


Process = MillingProcess | OrthogonalProcess


@dataclass(frozen=True)
class ProcessDamping:
    """Velocity-proportional process damping, Royandi 2026, Eq. 3-6 (after Chen et al.).

    ``F_pd = -C_eff v`` on the tool, ``v`` the tool-tip velocity, with the effective damping
    ``C_eff = C_pd a h / V_c`` in N s/m: ``C_pd`` in N/m^2, depth ``a`` in m, chip thickness
    ``h`` in m (the feed per tooth; the paper's Sec. 6.4 uses ``C_pd a_p f_z / V_c``), cutting
    speed ``V_c = Omega D / 2`` in m/s. Royandi 2026 calibrates C_pd = 4.7e9 ... 2.9e11 N/m^2
    (AL6061 slotting), hence C_eff of 1e2 ... 1e3 N s/m. The damping acts at all times (as the
    paper's Eq. 4-6 write it), in both x and y for milling and along the chip direction in
    orthogonal cutting. It makes the stability problem depth-dependent, so only the
    semi-discretization (:func:`sdm_lobes`) takes it.

    Attributes
    ----------
    coefficient_pa
        Process damping coefficient ``C_pd`` in N/m^2, >= 0.
    chip_thickness_m
        Chip thickness ``h`` in m (feed per tooth in milling, feed per revolution in turning).
    diameter_m
        Cutting diameter in m (the tool's in milling, the workpiece's in turning).
    """

    coefficient_pa: float
    chip_thickness_m: float
    diameter_m: float

    def __post_init__(self) -> None:
        c = _finite("process damping C_pd", self.coefficient_pa, strict=False)
        object.__setattr__(self, "coefficient_pa", c)
        h = _finite("process damping chip thickness", self.chip_thickness_m)
        object.__setattr__(self, "chip_thickness_m", h)
        object.__setattr__(self, "diameter_m", _finite("cutting diameter", self.diameter_m))

    def effective_damping(self, depth_m: float, spindle_rad_s: float) -> float:
        """``C_eff = C_pd a h / V_c`` in N s/m at depth ``a`` (m) and speed ``Omega`` (rad/s)."""
        speed = spindle_rad_s * 0.5 * self.diameter_m
        return self.coefficient_pa * depth_m * self.chip_thickness_m / speed


@dataclass(frozen=True, eq=False)
class StabilityLobes:
    """Critical depth of cut and chatter frequency per spindle speed.

    Attributes
    ----------
    spindle_rad_s
        Spindle speeds in rad/s.
    critical_depth_m
        Lowest unstable depth in m per speed; ``inf`` where none was found (below the
        search's upper limit for the semi-discretization).
    chatter_frequency_hz
        Chatter frequency in Hz at the critical depth, NaN where there is none.
    bifurcation
        Per speed ``"hopf"`` (a complex pair of multipliers leaves the unit circle: quasi-
        periodic chatter), ``"flip"`` (a multiplier at -1: period doubling), ``"fold"`` (at +1)
        or ``"none"``; the zero-order approximation only finds ``"hopf"``.
    method
        ``"zoa"`` or ``"sdm"``.
    """

    spindle_rad_s: np.ndarray
    critical_depth_m: np.ndarray
    chatter_frequency_hz: np.ndarray
    bifurcation: tuple[str, ...]
    method: str

    @property
    def min_critical_depth_m(self) -> float:
        """Lowest critical depth over the speeds in m (``inf`` if none)."""
        return float(np.min(self.critical_depth_m))


# ----------------------------------------------------------------------------------------
# Zero-order approximation


def _frequency_grid(tool: ToolDynamics, count: int = 3000) -> np.ndarray:
    """Chatter frequencies to sweep, rad/s: 0.5 wmin .. 2.5 wmax plus a dense band per mode."""
    wn = np.array([m.frequency_rad_s for m in tool.modes])
    zeta = np.array([max(m.damping_ratio, 1e-4) for m in tool.modes])
    parts = [np.linspace(0.5 * wn.min(), 2.5 * wn.max(), count)]
    for w, z in zip(wn, zeta, strict=True):
        parts.append(w * (1.0 + z * np.linspace(-6.0, 30.0, 600)))
    grid = np.unique(np.concatenate(parts))
    return grid[grid > 0.0]


def _zoa_eigenvalues(
    tool: ToolDynamics, process: Process, frequency_rad_s: np.ndarray
) -> np.ndarray:
    """Eigenvalues ``mu`` (1/m) of ``H0 G(i w)``, ``(F, 2)``, each branch tracked along F."""
    product = process.mean_matrix() @ tool.frf(frequency_rad_s)
    return _zoa.tracked_eigenvalues(np.ascontiguousarray(product))


def zoa_lobes(
    tool: ToolDynamics,
    process: Process,
    spindle_rad_s: Sequence[float] | np.ndarray,
    *,
    frequency_rad_s: np.ndarray | None = None,
) -> StabilityLobes:
    """Stability lobes by the zero-order approximation, on a spindle-speed grid.

    Altintas & Budak 1995 (Altintas 2012, Eq. 3.60-3.66), in the form of the module notes:
    for each chatter frequency ``w`` and eigenvalue ``mu`` of ``H0 G(i w)`` with
    ``Re mu > 0``, the limiting depth ``a = 1 / (2 Re mu)`` lies on lobe k at the delay
    ``tau = (epsilon + 2 pi k) / w``, ``epsilon = pi + 2 atan(Im mu / Re mu)``; the critical
    depth at a speed is the lowest lobe there.

    Parameters
    ----------
    tool
        Tool-tip dynamics.
    process
        :class:`MillingProcess` or :class:`OrthogonalProcess`.
    spindle_rad_s
        Spindle speeds in rad/s, > 0.
    frequency_rad_s
        Chatter frequencies to sweep in rad/s; default 0.5 ... 2.5 times the modes' natural
        frequencies with a dense band above each mode.

    Returns
    -------
    StabilityLobes
        Method ``"zoa"``; the chatter frequency is the lobe's ``w / (2 pi)``.
    """
    speeds = _speeds(spindle_rad_s)
    omega = _frequency_grid(tool) if frequency_rad_s is None else _frequencies(frequency_rad_s)
    mu = _zoa_eigenvalues(tool, process, omega)
    positive = mu.real > 1e-300
    safe = np.where(positive, mu, 1.0)
    depth = np.where(positive, 0.5 / safe.real, np.nan)
    phase = np.pi + 2.0 * np.arctan(safe.imag / safe.real)
    per_rate = float(process.spindle_rad_s(1.0))  # Omega * tau
    longest = float(process.delay_s(speeds.min()))
    lobes = int(math.ceil(omega.max() * longest / _TWO_PI)) + 1
    order = np.argsort(speeds)
    best, chatter = _zoa.envelope(speeds[order], omega, depth, phase, lobes, per_rate)
    critical = np.empty_like(best)
    frequency = np.empty_like(chatter)
    critical[order] = best
    frequency[order] = chatter / _TWO_PI
    kinds = tuple("hopf" if math.isfinite(a) else "none" for a in critical)
    return StabilityLobes(speeds, critical, frequency, kinds, "zoa")


def zoa_absolute_depth(
    tool: ToolDynamics, process: Process, *, frequency_rad_s: np.ndarray | None = None
) -> tuple[float, float]:
    """The zero-order approximation's lowest limiting depth over all spindle speeds.

    ``a_abs = 1 / (2 max_w Re mu(w))``; for orthogonal cutting this is the textbook
    ``a_lim = -1 / (2 Kf min Re G_o)`` (Tlusty; Altintas 2000, ch. 3). The maximum found on the
    frequency grid is refined by a bounded scalar search.

    Returns
    -------
    tuple of float
        The depth in m and its chatter frequency in Hz.
    """
    omega = _frequency_grid(tool) if frequency_rad_s is None else _frequencies(frequency_rad_s)
    real = _zoa_eigenvalues(tool, process, omega).real.max(axis=1)
    best = int(np.argmax(real))
    if real[best] <= 0.0:
        return math.inf, math.nan
    low = omega[max(best - 1, 0)]
    high = omega[min(best + 1, omega.size - 1)]

    def negative(w: float) -> float:
        return -float(_zoa_eigenvalues(tool, process, np.array([w])).real.max())

    found = minimize_scalar(negative, bounds=(low, high), method="bounded",
                            options={"xatol": 1e-9 * high})  # fmt: skip
    w, peak = (found.x, -found.fun) if -found.fun > real[best] else (omega[best], real[best])
    return 0.5 / peak, w / _TWO_PI


# ----------------------------------------------------------------------------------------
# Semi-discretization


def floquet_multipliers(
    tool: ToolDynamics,
    process: Process,
    spindle_rad_s: float,
    depth_m: float,
    *,
    steps: int | None = None,
    damping: ProcessDamping | None = None,
) -> np.ndarray:
    """Floquet (characteristic) multipliers of a cut by first-order semi-discretization.

    Insperger & Stépán 2004 (see :mod:`cnctwin.dynamics._sdm`): the eigenvalues of the
    transition matrix over one delay period cut into ``steps`` steps. The cut is
    asymptotically stable if they all lie inside the unit circle.

    Parameters
    ----------
    tool
        Tool-tip dynamics.
    process
        :class:`MillingProcess` (period: a tooth period) or :class:`OrthogonalProcess`
        (a revolution).
    spindle_rad_s
        Spindle speed in rad/s, > 0.
    depth_m
        Axial depth of cut (chip width) in m, >= 0.
    steps
        Steps per period m, >= 2; ``None``: as :func:`sdm_lobes` chooses.
    damping
        Optional process damping.

    Returns
    -------
    numpy.ndarray
        Complex multipliers, largest magnitude first (the always-zero ones left out).
    """
    speed = _finite("spindle speed (rad/s)", spindle_rad_s)
    depth = _finite("depth of cut (m)", depth_m, strict=False)
    m = _auto_grid(tool, process, speed) if steps is None else steps
    return _sdm.SdmModel.build(tool, process, m).multipliers(speed, depth, damping)


def sdm_lobes(
    tool: ToolDynamics,
    process: Process,
    spindle_rad_s: Sequence[float] | np.ndarray,
    *,
    max_depth_m: float,
    steps: int | None = None,
    depth_step_m: float | None = None,
    tolerance_m: float | None = None,
    damping: ProcessDamping | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> StabilityLobes:
    """Stability lobes by first-order semi-discretization (Insperger & Stépán 2002, 2004).

    For each speed the depth rises from 0 in steps of ``depth_step_m`` until the spectral
    radius of the transition matrix reaches 1; Brent's method then finds the crossing inside
    that step. The critical depth is the lowest unstable depth found this way: an unstable
    band thinner than the step can be missed.

    Parameters
    ----------
    tool
        Tool-tip dynamics.
    process
        :class:`MillingProcess` or :class:`OrthogonalProcess`.
    spindle_rad_s
        Spindle speeds in rad/s, > 0.
    max_depth_m
        Upper limit of the search in m; speeds stable up to it get ``inf``.
    steps
        Equal steps per period m, >= 2 (Insperger & Stépán's benchmarks use 40). The error of
        the critical depth falls as ``1 / m^2`` where teeth cut all the time, about 1 % with 20
        steps per vibration cycle, 8 % with 7, but only as ``1 / m`` where a short cut starts
        and ends inside steps (docs/stability.md). The default ``None`` takes, per speed, the
        grid of :func:`_auto_grid`: nodes at the teeth's entry and exit, 30 steps per cycle
        of the highest mode in the cut, at least 20 in any cut: within 1 % of a converged run
        from a/D = 0.01 to slotting. A fixed m giving fewer than 10 steps per cycle at the
        lowest speed is logged as a warning.
    depth_step_m
        Step of the upward search in m; default ``max_depth_m / 40``.
    tolerance_m
        Absolute tolerance of the crossing in m, on top of a relative 1e-4; default
        ``max_depth_m * 1e-6``.
    damping
        Optional process damping (depth- and speed-dependent, Royandi 2026, Eq. 3).
    progress
        Called as ``progress(done, total)`` in speeds after each speed.

    Returns
    -------
    StabilityLobes
        Method ``"sdm"``, with the chatter frequency and bifurcation of the critical
        multiplier at the critical depth.
    """
    speeds = _speeds(spindle_rad_s)
    top = _finite("max_depth_m", max_depth_m)
    step = top / 40.0 if depth_step_m is None else _finite("depth_step_m", depth_step_m)
    tol = top * 1e-6 if tolerance_m is None else _finite("tolerance_m", tolerance_m)
    highest = max(mode.frequency_rad_s for mode in tool.modes) / _TWO_PI
    if steps is not None:
        per_cycle = steps / (highest * float(process.delay_s(speeds.min())))
        if per_cycle < 10.0:
            logger.warning(
                "semi-discretization: %d steps per period are %.1f steps per cycle of the "
                "%.0f Hz mode at the lowest speed; the critical depth may be off by about "
                "%.0f %% there (use steps=None)",
                steps,
                per_cycle,
                highest,
                400.0 / per_cycle**2,
            )
    models: dict[bytes, _sdm.SdmModel] = {}
    critical = np.full(speeds.size, np.inf)
    frequency = np.full(speeds.size, np.nan)
    kinds = ["none"] * speeds.size
    for i, speed in enumerate(speeds):
        grid = _auto_grid(tool, process, speed) if steps is None else steps
        key = grid.tobytes() if isinstance(grid, np.ndarray) else repr(grid).encode()
        if key not in models:
            models[key] = _sdm.SdmModel.build(tool, process, grid)
        model = models[key]

        def excess(a: float, s: float = speed, model: _sdm.SdmModel = model) -> float:
            return model.radius(s, a, damping) - 1.0

        depth = _sdm.first_crossing(excess, top, step, tol)
        if depth is not None:
            critical[i] = depth
            frequency[i], kinds[i] = model.chatter(speed, depth, damping)
        if progress is not None:
            progress(i + 1, speeds.size)
    return StabilityLobes(speeds, critical, frequency, tuple(kinds), "sdm")


@dataclass(frozen=True)
class SdmCost:
    """The estimated cost of a semi-discretization lobe diagram (:func:`sdm_cost`).

    Attributes
    ----------
    speeds
        Number of spindle speeds.
    evaluations_per_speed
        Expected spectral-radius evaluations of the depth search per speed.
    seconds_per_evaluation
        Time of one evaluation in s, mean over the speeds (measured at the lowest and the
        highest).
    """

    speeds: int
    evaluations_per_speed: float
    seconds_per_evaluation: float

    @property
    def seconds(self) -> float:
        """Estimated time of the whole diagram in s: speeds x evaluations x time of one."""
        return self.speeds * self.evaluations_per_speed * self.seconds_per_evaluation


def sdm_cost(
    tool: ToolDynamics,
    process: Process,
    spindle_rad_s: Sequence[float] | np.ndarray,
    *,
    max_depth_m: float,
    steps: int | None = None,
    depth_step_m: float | None = None,
    damping: ProcessDamping | None = None,
) -> SdmCost:
    """Estimate the cost of :func:`sdm_lobes` with the same arguments before running it.

    One spectral-radius evaluation is timed at the lowest and at the highest speed, and the
    time of the others interpolated as a power of their number of steps (the lowest speed has
    the most); the depth search's evaluations per speed are estimated from the zero-order
    lobes: the upward steps to the ZOA's critical depth (all 40 where it lies above
    ``max_depth_m``) plus about 10 for Brent's method.

    Returns
    -------
    SdmCost
        Speeds, evaluations per speed and seconds per evaluation (s, the mean over speeds).
    """
    speeds = _speeds(spindle_rad_s)
    top = _finite("max_depth_m", max_depth_m)
    step = top / 40.0 if depth_step_m is None else _finite("depth_step_m", depth_step_m)
    sample = speeds if speeds.size <= 200 else np.linspace(speeds.min(), speeds.max(), 200)
    counts = np.array(
        [_auto_steps(tool, process, v) if steps is None else steps for v in sample], dtype=float
    )
    timings = []
    for speed in (float(sample.min()), float(sample.max())):
        grid = _auto_grid(tool, process, speed) if steps is None else steps
        model = _sdm.SdmModel.build(tool, process, grid)
        model.radius(speed, 0.5 * top, damping)  # compiled kernels loaded outside the timing
        started = time.perf_counter()
        model.radius(speed, 0.5 * top, damping)
        timings.append(max(time.perf_counter() - started, 1e-6))
    most, fewest = counts[int(np.argmin(sample))], counts[int(np.argmax(sample))]
    power = math.log(timings[0] / timings[1]) / math.log(most / fewest) if most > fewest else 0.0
    seconds = timings[1] * (counts / fewest) ** power
    zoa = zoa_lobes(tool, process, sample).critical_depth_m
    upward = np.where(np.isfinite(zoa) & (zoa < top), np.ceil(zoa / step), top / step)
    return SdmCost(int(speeds.size), float(np.mean(upward)) + 10.0, float(np.mean(seconds)))


def _auto_grid(tool: ToolDynamics, process: Process, spindle_rad_s: float) -> np.ndarray:
    """The automatic semi-discretization grid of one period, as fractions 0 ... 1.

    Nodes at every entry and exit of a tooth (:meth:`MillingProcess.breakpoints`), so that no
    step straddles a jump of ``H(t)``; between them equal steps: where a tooth cuts, at least
    30 per cycle of the highest natural frequency, 40 per period and 20 in every stretch of
    cutting however short it is (a radial immersion of 1 %, say), so that the time in the cut
    is resolved at any immersion; in free flight, solved exactly whatever its steps, 10 per
    cycle for the chatter frequency's harmonics (docs/stability.md, Accuracy).
    """
    highest = max(mode.frequency_rad_s for mode in tool.modes) / _TWO_PI
    cycles = highest * float(process.delay_s(spindle_rad_s))
    cuts = np.unique(np.concatenate(([0.0, 1.0], process.breakpoints())))
    cutting = np.any(process.interval_matrices(cuts) != 0.0, axis=(1, 2))
    nodes = [np.zeros(1)]
    for low, high, active in zip(cuts[:-1], cuts[1:], cutting, strict=True):
        width = float(high - low)
        if active:
            count = max(_MIN_CUT_STEPS, math.ceil(_CUT_STEPS_PER_CYCLE * cycles * width - 1e-9),
                        math.ceil(_MIN_STEPS * width - 1e-9))  # fmt: skip
        else:
            count = max(1, math.ceil(_FREE_STEPS_PER_CYCLE * cycles * width - 1e-9))
        nodes.append(low + width * np.arange(1, count + 1) / count)
    grid = np.concatenate(nodes)
    grid[-1] = 1.0
    return grid


def _auto_steps(tool: ToolDynamics, process: Process, spindle_rad_s: float) -> int:
    """The number of steps of :func:`_auto_grid`."""
    return int(_auto_grid(tool, process, spindle_rad_s).size - 1)


def _speeds(spindle_rad_s: Sequence[float] | np.ndarray) -> np.ndarray:
    speeds = np.atleast_1d(np.asarray(spindle_rad_s, dtype=np.float64))
    if speeds.ndim != 1 or speeds.size == 0 or not np.all(np.isfinite(speeds) & (speeds > 0)):
        raise InputError(f"spindle speeds {spindle_rad_s!r}; give one or more finite values > 0")
    return speeds


def _frequencies(frequency_rad_s: np.ndarray) -> np.ndarray:
    omega = np.asarray(frequency_rad_s, dtype=np.float64)
    if omega.ndim != 1 or omega.size < 2 or not np.all(np.isfinite(omega) & (omega > 0)):
        raise InputError("chatter frequencies: give two or more finite values > 0 rad/s")
    if np.any(np.diff(omega) <= 0):
        raise InputError("chatter frequencies must increase")
    return omega
