"""Milling vibration as a stream: the time-domain model advanced piece by piece as a cut changes.

:func:`cnctwin.dynamics.simulate_milling` integrates one cut of fixed speed, depth and
immersion from rest. A machine's cut changes while it runs: the spindle speed follows an
override, the feed changes, the tool enters and leaves the material. :class:`MillingStream`
integrates the same model (Royandi 2026, Eq. 1-12 with the tool's modes; the regenerative chip
``h = f_z sin(phi) + u . (r(t) - r(t - T))`` against the surface the last cutting tooth left;
module notes of :mod:`cnctwin.dynamics.time_domain`) over any number of consecutive pieces,
each with its own conditions, carrying the modal state, the cutting force and the cut surface
from one piece to the next (:func:`cnctwin.dynamics._time_domain_kernels.march`).

The grid of ``m`` steps per tooth period is fixed when the stream is made (from its
``design_rpm``): a speed change changes the step ``dt = 60 / (N n m)``, not the grid of
angles, so the surface stays where it is. A change of depth or immersion rebuilds the angle
tables and keeps the surface; the axial slices are as many as the depth needs (as
:func:`~cnctwin.dynamics.simulate_milling`'s default, for the depth rounded up to whole
:data:`DEPTH_QUANTUM_M`), and when their number changes the surface is interpolated onto the
new slices (each slice's remembered surface at its height). When the tool enters the
material (a piece with depth after one without) the surface is the nominal one the previous
tooth left, as at the start of :func:`~cnctwin.dynamics.simulate_milling`: the entry's step
of force seeds the vibration.
Where the immersion widens during a cut (the tool entering a side cut), the angles and
slices new to the cut get that nominal surface too: material no tooth has cut yet, which a
tooth meets with the nominal chip ``f_z sin(phi)`` (plus the vibration's share).

Units: SI (m, s, rad/s, N).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cnctwin.dynamics import _time_domain_kernels as _k
from cnctwin.dynamics.stability import MillingProcess, ToolDynamics
from cnctwin.dynamics.time_domain import (
    _angle_tables,
    _cutter_geometry,
    _Modal,
    _modal_matrices,
    _slices,
    _steps,
    _Tables,
)
from cnctwin.errors import InputError
from cnctwin.geometry import Cutter
from cnctwin.mechanics import CuttingCoefficients

__all__ = ["CutConditions", "MillingStream"]

_TWO_PI = 2.0 * math.pi
#: Relative change of speed, depth or immersion (rad) below which the matrices or tables of
#: the last piece are kept.
_SAME = 1e-4
#: The slices are counted for the depth rounded up to a multiple of this, m.
DEPTH_QUANTUM_M = 0.5e-3


@dataclass(frozen=True)
class CutConditions:
    """The cut during one piece of the stream.

    Attributes
    ----------
    spindle_rad_s
        Spindle speed Omega, rad/s, > 0.
    depth_m
        Axial depth of cut a_p, m, >= 0 (0: the tool is in air).
    entry_rad, exit_rad
        Immersion interval, rad, ``0 <= entry < exit <= 2 pi`` (frame of
        :mod:`cnctwin.mechanics.engagement`: x along the feed).
    feed_per_tooth_m
        Feed per tooth f_z, m, >= 0.
    """

    spindle_rad_s: float
    depth_m: float
    entry_rad: float
    exit_rad: float
    feed_per_tooth_m: float


class MillingStream:
    """The time-domain milling model advanced in consecutive pieces (module notes).

    Parameters
    ----------
    tool
        Tool-tip modes (SI).
    cutter
        A flat end mill (teeth, helix, radius), no runout.
    coefficients
        Cutting coefficients (shear Ktc, Krc in Pa; edge Kte, Kre in N/m).
    design_rpm
        The speed the grid is made for, rpm (its steps per tooth period: 200 per cycle of the
        highest mode there, at least 200, unless ``steps_per_tooth`` is given).
    steps_per_tooth
        Steps per tooth period m (>= 20), default as :func:`~cnctwin.dynamics.simulate_milling`.

    Raises
    ------
    InputError
        For a cutter that is not a flat end mill without runout, or a value out of range.
    """

    def __init__(
        self,
        tool: ToolDynamics,
        cutter: Cutter,
        coefficients: CuttingCoefficients,
        *,
        design_rpm: float,
        steps_per_tooth: int | None = None,
    ) -> None:
        if not (math.isfinite(design_rpm) and design_rpm > 0.0):
            raise InputError(f"design_rpm={design_rpm!r}; give a speed > 0 rpm")
        self.tool = tool
        self.teeth = cutter.flutes
        self.coefficients = coefficients
        probe = MillingProcess(cutter.flutes, coefficients.ktc, coefficients.krc, 0.0, math.pi)
        self._helix, self._radius = _cutter_geometry(cutter, probe)
        speed = design_rpm * _TWO_PI / 60.0
        period = _TWO_PI / (speed * self.teeth)
        highest = max(mode.frequency_rad_s for mode in tool.modes) / _TWO_PI
        self.steps_per_tooth = _steps(steps_per_tooth, highest * period)
        self._design_rad_s = speed
        self._highest_hz = highest
        self.slices = 1
        grid = self.teeth * self.steps_per_tooth
        self._state = np.zeros(2 * len(tool.modes))
        self._force = np.zeros(2)
        self._surface = np.zeros((grid, 1))
        self._step = 0
        self._advance_m = 0.0
        self._time_s = 0.0
        self._in_cut = False
        self._matrices: tuple[float, _Modal] | None = None
        self._tables: tuple[tuple[float, float, float], _Tables] | None = None
        self._air: _Tables | None = None
        self._inside: np.ndarray | None = None  # the angles in the cut in the last piece

    @property
    def time_s(self) -> float:
        """Time simulated so far, s (the time of the next step's output)."""
        return self._time_s

    def step_s(self, spindle_rad_s: float) -> float:
        """The step length at a spindle speed, s: a tooth period over ``steps_per_tooth``."""
        return _TWO_PI / (spindle_rad_s * self.teeth * self.steps_per_tooth)

    def advance(self, conditions: CutConditions, steps: int) -> np.ndarray:
        """Integrate ``steps`` steps under ``conditions``.

        Parameters
        ----------
        conditions
            The cut over these steps.
        steps
            Number of steps, >= 1, each :meth:`step_s` long.

        Returns
        -------
        numpy.ndarray
            (steps, 8): per step displacement x, y (m), velocity x, y (m/s), acceleration x,
            y (m/s^2), cutting force x, y on the tool (N); the first row is the state at
            :attr:`time_s` before the call.
        """
        c = conditions
        if not (math.isfinite(c.spindle_rad_s) and c.spindle_rad_s > 0.0):
            raise InputError(f"spindle_rad_s={c.spindle_rad_s!r}; give a speed > 0 rad/s")
        if steps < 1:
            raise InputError(f"steps={steps!r}; give at least 1")
        dt = self.step_s(c.spindle_rad_s)
        modal = self._modal(c.spindle_rad_s, dt)
        cutting = c.depth_m > 0.0 and c.exit_rad > c.entry_rad
        out = np.empty((steps, 8))
        if cutting:
            self._fit_slices(c.depth_m)
            tables = self._angle_tables(c)
            nominal = self._nominal(tables.sin, c.feed_per_tooth_m)
            held = self._inside
            if not self._in_cut or held is None or held.shape != tables.inside.shape:
                self._surface[:] = nominal
                if not self._in_cut:  # the entry: the force of this step is the cut's
                    self._force[:] = self._entry_force(modal, tables, c.feed_per_tooth_m)
            else:  # where the cut widened, the material is as the last tooth left it nominally
                fresh = tables.inside & ~held
                self._surface[fresh] = nominal[fresh]
            self._inside = tables.inside
        else:
            tables = self._air_tables()
        self._in_cut = cutting
        _k.march(
            modal.transition,
            modal.hold,
            modal.ramp,
            modal.tip,
            modal.accel_state,
            modal.accel_force,
            self._state,
            self._force,
            self._step,
            self._advance_m,
            self.steps_per_tooth,
            c.feed_per_tooth_m,
            tables.inside,
            tables.sin,
            tables.cos,
            tables.cut_x,
            tables.cut_y,
            tables.edge_x,
            tables.edge_y,
            self._surface,
            True,
            out,
        )
        self._step += steps
        self._advance_m += c.feed_per_tooth_m * steps / self.steps_per_tooth
        self._time_s += steps * dt
        return out

    def _modal(self, speed: float, dt: float) -> _Modal:
        held = self._matrices
        if held is None or abs(held[0] - speed) > _SAME * speed:
            held = (speed, _modal_matrices(self.tool, 0.0, dt))
            self._matrices = held
        return held[1]

    def _angle_tables(self, c: CutConditions) -> _Tables:
        key = (c.depth_m, c.entry_rad, c.exit_rad)
        held = self._tables
        if (
            held is None
            or held[1].inside.shape[1] != self.slices
            or any(
                abs(a - b) > _SAME * max(abs(b), 1e-3) for a, b in zip(key, held[0], strict=True)
            )
        ):
            process = MillingProcess(
                self.teeth, self.coefficients.ktc, self.coefficients.krc, c.entry_rad, c.exit_rad
            )
            lag = c.depth_m * math.tan(self._helix) / self._radius if self._radius > 0 else 0.0
            tables = _angle_tables(
                process,
                self.steps_per_tooth,
                self.slices,
                c.depth_m,
                lag,
                self.coefficients.kte,
                self.coefficients.kre,
                self._helix,
                False,
            )
            held = (key, tables)
            self._tables = held
        return held[1]

    def _air_tables(self) -> _Tables:
        """Tables of no contact (the tool in air: no force)."""
        if self._air is None or self._air.inside.shape[1] != self.slices:
            t = self._angle_tables(CutConditions(1.0, 1e-3, 0.0, math.pi, 0.0))
            self._air = t._replace(inside=np.zeros_like(t.inside))
        return self._air

    def _fit_slices(self, depth_m: float) -> None:
        """As many slices as ``depth_m`` needs; the surface interpolated onto new ones."""
        rounded = math.ceil(depth_m / DEPTH_QUANTUM_M - 1e-9) * DEPTH_QUANTUM_M
        lag = rounded * math.tan(self._helix) / self._radius if self._radius > 0 else 0.0
        count = _slices(None, lag, self._design_rad_s, self._highest_hz)
        if count == self.slices:
            return
        old = (np.arange(self.slices) + 0.5) / self.slices
        new = (np.arange(count) + 0.5) / count
        self._surface = np.ascontiguousarray(
            np.array([np.interp(new, old, row) for row in self._surface])
        )
        self.slices = count

    def _entry_force(self, modal: _Modal, tables: _Tables, feed: float) -> tuple[float, float]:
        """The cutting force (N) at the current step on entering the cut, the surface updated."""
        n = modal.tip.shape[1]
        rx, ry = modal.tip @ self._state[:n]
        return _k.cutting_force(
            self._step,
            self._advance_m + float(rx),
            float(ry),
            self.steps_per_tooth,
            feed,
            tables.inside,
            tables.sin,
            tables.cos,
            tables.cut_x,
            tables.cut_y,
            tables.edge_x,
            tables.edge_y,
            self._surface,
            True,
            True,
        )

    def _nominal(self, sin_t: np.ndarray, feed: float) -> np.ndarray:
        """The surface the previous tooth left on an undeflected path, per angle and slice (m):
        the cut's entry, and where the immersion widens into material no tooth has cut."""
        m = self.steps_per_tooth
        grid = sin_t.shape[0]
        phase = ((np.arange(grid) - self._step) % m) / m  # each angle's place in its tooth period
        return sin_t * (self._advance_m + feed * (phase - 1.0))[:, None]
