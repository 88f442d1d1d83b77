"""The twin's own physics: its stock, its tools, and the physics of one cycle.

The twin keeps its *own* tri-dexel stock (the blank the configuration describes, in machine
coordinates) and cuts it at the tool positions the machine reports (Heide 2025, Sec. 2.2 and
Fig. 5, steps 2-4). It does not know about a hole in the machine's blank: where the real
blank misses material, the twin still predicts a cut, and the measured force falls out of the
band around the prediction (Heide 2025, use case 1).

Forces, torque and power come from the mechanistic model of :mod:`cnctwin.mechanics` with the
material's coefficients, exactly as the offline prediction of
:func:`cnctwin.simulation.signals.simulate_signals` does (Altintas 2012, ch. 2; Royandi 2026,
Eq. 8-12); a drill or a tap takes the drilling model through the same
:func:`cnctwin.simulation.step_forces` (docs/drilling.md).

Units: mm, mm/min, rpm and s at the edges (names say so), N, N m, W.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from cnctwin.config import MachiningConfig
from cnctwin.errors import ConfigError
from cnctwin.geometry import Cutter, DexelStock, Engagement, cut
from cnctwin.mechanics import CuttingCoefficients, DrillingMaterial
from cnctwin.simulation import CutStep, StepForces, axial_material, step_forces

__all__ = ["NO_FORCE", "TwinPhysics"]

#: The load of a step without contact.
NO_FORCE = StepForces(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


class TwinPhysics:
    """The twin's stock, tools and material; cut one position at a time.

    Parameters
    ----------
    config
        Tools (``[[tools]]`` with flute length), stock (``[stock]``, machine frame), material
        (a milling entry of the materials library) and dexel density
        (``[simulation].density_per_mm``).
    density_per_mm
        Dexel density, 1/mm; ``None`` takes the configuration's.
    waveform_steps
        Spindle angles per revolution for the peak force (fewer is faster).
    default_dt_s
        Time between positions when the machine's clock gives none, s.

    Raises
    ------
    ConfigError
        If the material is not in the library (for a drill or a tap: not in the drilling
        coefficients either) or a tool has no fluted length.
    """

    def __init__(
        self,
        config: MachiningConfig,
        *,
        density_per_mm: float | None = None,
        waveform_steps: int = 36,
        default_dt_s: float = 0.0125,
    ) -> None:
        from cnctwin.mechanics import milling_material

        try:
            material = milling_material(config.material.name)
        except ConfigError as err:
            raise ConfigError(f"material.name: {err}") from None
        self.coefficients: CuttingCoefficients = material.coefficients
        #: The cutter of every configured tool (geometry and force model), by tool number.
        self.cutters = {tool.number: Cutter.from_tool_config(tool) for tool in config.tools}
        #: Drilling coefficients of the material when a tool is a drill or a tap, else None.
        self.drilling: DrillingMaterial | None = axial_material(config.material.name, self.cutters)
        density = config.simulation.density_per_mm if density_per_mm is None else density_per_mm
        self._box = (config.stock.min_mm, config.stock.max_mm)
        self._density = density
        self.stock = DexelStock.box(config.stock.min_mm, config.stock.max_mm, density)
        self._pitch_z_mm = float(self.stock.grid.pitch_mm[2])
        self._waveform_steps = waveform_steps
        self._previous: NDArray[np.float64] | None = None
        self._previous_tool = -1
        self.steps = 0
        self.default_dt_s = default_dt_s
        #: Whether the twin's blank can be trusted to be the machine's (False when the twin
        #: attached to a program already running: it does not know what was cut before).
        self.synchronized = True

    def warm_up(self) -> None:
        """Compile (or load) the cut and force kernels before the first cycle.

        numba compiles lazily, per argument types; the types depend on the stock's grid, so
        the warm-up cuts a throw-away copy of the configured blank (same box, same density)
        with each tool, at its corner. The twin's own stock is untouched.
        """
        lo, hi = self._box
        for number, cutter in self.cutters.items():
            stock = DexelStock.box(lo, hi, self._density)
            previous = None
            for dx in (0.0, 0.5 * cutter.radius_mm):
                position = np.array((lo[0] + dx, lo[1], hi[2] - 0.5 * cutter.radius_mm))
                engagement = cut(stock, cutter, position, previous, 0.05, self.default_dt_s)
                previous = position
                if engagement.contact:
                    self.forces(engagement, number, 1000.0, 0.05)
        self.steps = 0

    def reset_stock(self) -> None:
        """A fresh blank (the machine started its program again)."""
        lo, hi = self._box
        self.stock = DexelStock.box(lo, hi, self._density)
        self._previous = None
        self.synchronized = True

    def forget_position(self) -> None:
        """Start a new path: the next cut has no previous position (after a gap)."""
        self._previous = None

    def cut(
        self,
        position_mm: NDArray[np.float64],
        tool: int,
        spindle_rpm: float,
        feed_mm_min: float,
        dt_s: float,
    ) -> tuple[Engagement | None, float]:
        """Cut the twin's stock at one tool position (Heide 2025, Sec. 2.2).

        Parameters
        ----------
        position_mm
            Tool tip, machine frame, mm.
        tool
            Tool number in the spindle; an unknown tool (or 0) cuts nothing.
        spindle_rpm
            Spindle speed, rpm (its magnitude is used).
        feed_mm_min
            Path speed, mm/min.
        dt_s
            Machine time since the previous position, s (the cycle time when not > 0).

        Returns
        -------
        tuple
            The engagement (None without a known tool) and the feed per tooth, mm.
        """
        cutter = self.cutters.get(tool)
        if cutter is None:
            self._previous = None
            self._previous_tool = tool
            return None, 0.0
        if tool != self._previous_tool:
            self._previous = None
            self._previous_tool = tool
        rpm = abs(spindle_rpm)
        fz = feed_mm_min / (rpm * cutter.flutes) if rpm > 1.0 and feed_mm_min > 0.0 else 0.0
        if not math.isfinite(fz):
            fz = 0.0
        if not (math.isfinite(dt_s) and dt_s > 0.0):
            dt_s = self.default_dt_s
        engagement = cut(self.stock, cutter, position_mm, self._previous, fz, dt_s)
        self._previous = position_mm
        return engagement, fz

    def forces(
        self, engagement: Engagement, tool: int, spindle_rpm: float, feed_per_tooth_mm: float
    ) -> StepForces:
        """Mean forces (N), peak force (N), torque (N m) and power (W) of one cut.

        Parameters
        ----------
        engagement
            The engagement of :meth:`cut`.
        tool
            Tool number (one of :attr:`cutters`).
        spindle_rpm
            Spindle speed, rpm.
        feed_per_tooth_mm
            Feed per tooth, mm.

        Returns
        -------
        StepForces
            All zero without contact or feed
            (:func:`cnctwin.simulation.signals.step_forces` otherwise).
        """
        cutter = self.cutters.get(tool)
        if cutter is None or not engagement.contact or feed_per_tooth_mm <= 0.0:
            return NO_FORCE
        self.steps += 1
        step = CutStep(
            self.steps,
            0.0,
            (0.0, 0.0, 0.0),
            0,
            tool,
            cutter,
            abs(spindle_rpm),
            feed_per_tooth_mm,
            engagement,
        )
        return step_forces(
            step,
            self.coefficients,
            self._pitch_z_mm,
            waveform_steps=self._waveform_steps,
            drilling=self.drilling,
        )
