"""The virtual machine: a simulated CNC mill that runs an NC program on the project's physics.

Each :meth:`VirtualMachine.step` of ``dt`` seconds (the tick):

1. the axes follow the program's path (:class:`~cnctwin.virtual._motion.PathFollower`): feed
   moves at ``F x feed override``, rapids at the rapid rate, dwells, with the axis acceleration
   limits of ``[machine.axes]``; feed hold and stop decelerate the axes to rest;
2. the tool tip cuts the machine's own tri-dexel stock (:func:`cnctwin.geometry.cut`, Heide 2025
   Sec. 2.2), which may have holes the twin does not know of (:mod:`cnctwin.virtual.faults`);
3. the engagement of the cut gives the per-revolution mean cutting forces, torque and power of
   the mechanistic model with the tool's teeth and helix and the material's coefficients
   (:func:`cnctwin.simulation.step_forces` without its peak force, as the offline signals and
   the twin: Altintas 2012 ch. 2, Royandi 2026 Eq. 8-12; the drilling model for a drill or a
   tap, docs/drilling.md);
4. the cutting torque loads the spindle drive (Christiand 2024, Eq. 10-18,
   :class:`cnctwin.drives.SpindleDrive`), which follows ``S x spindle override`` and gives the
   spindle speed, current and torque;
5. the feed drives carry the cutting force, Coulomb friction and the inertia of the moving mass
   (axis loads in % of a rated force);
6. Gaussian sensor noise (seeded) is added and the signals are published (:meth:`snapshot`).

Signals are those of :data:`cnctwin.thread.signals.SIGNALS`, in their units: positions are the
axes' machine coordinates of the controlled point (tool tip + tool length offset + length wear
offset), forces those a dynamometer under the workpiece measures (the force on the workpiece,
the opposite of the force on the tool), each the mean over the tick (see docs/virtual-machine.md).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterator
from contextlib import ExitStack
from dataclasses import replace
from importlib.resources import as_file
from pathlib import Path

import numpy as np

from cnctwin.config import MachiningConfig, ToolConfig, load_config
from cnctwin.drives import RAD_S_PER_RPM, EventState, SpindleDrive
from cnctwin.errors import ConfigError, DataError, NCError
from cnctwin.examples import example_file
from cnctwin.geometry import Cutter, DexelStock, Engagement, cut
from cnctwin.mechanics import CuttingCoefficients, milling_material
from cnctwin.nc import PLANE_AXES, CutterComp, Interpreter, Plane, Segment
from cnctwin.simulation import CutStep, axial_material, spindle_drive_parameters, step_forces
from cnctwin.thread import COMMANDS, SIGNALS, RunState, SampleBlock
from cnctwin.virtual._motion import PathFollower
from cnctwin.virtual.config import HoleFault, VirtualMachineConfig
from cnctwin.virtual.faults import FaultEvent, FaultInjector, blank_with_holes
from cnctwin.virtual.vibration import BLOCK_NAME, VibrationSensor

__all__ = ["VirtualMachine", "check_command"]

logger = logging.getLogger(__name__)

#: Signals that get sensor noise, with the :class:`NoiseConfig` family of each.
_NOISY = (
    ("x_mm", "position_mm"),
    ("y_mm", "position_mm"),
    ("z_mm", "position_mm"),
    ("feed_mm_min", "feed_mm_min"),
    ("spindle_rpm", "spindle_rpm"),
    ("spindle_torque_nm", "torque_nm"),
    ("spindle_current_a", "current_a"),
    ("spindle_power_w", "power_w"),
    ("load_x_pct", "load_pct"),
    ("load_y_pct", "load_pct"),
    ("load_z_pct", "load_pct"),
    ("force_x_n", "force_n"),
    ("force_y_n", "force_n"),
    ("force_z_n", "force_n"),
)
_STOPPED_STATES = (RunState.STOPPED, RunState.FINISHED, RunState.FAULT)
_LOADS = ("load_x_pct", "load_y_pct", "load_z_pct")
#: Below this speed (rpm) a spindle braking to rest is switched off.
_SPINDLE_OFF_RPM = 5.0
#: Spindle speed of the vibration kernels' warm-up, rpm: any speed compiles the same code.
_WARM_UP_RPM = 6000.0


class _Tool:
    """A tool's cutter (for the cut and the force model) and its breakage."""

    __slots__ = ("config", "cutter", "broken")

    def __init__(self, config: ToolConfig) -> None:
        self.config = config
        self.cutter = Cutter.from_tool_config(config)
        #: (lost length, the stub's cutter or None when nothing is left) once broken.
        self.broken: tuple[float, Cutter | None] | None = None


class VirtualMachine:
    """A simulated CNC mill executing an NC program, driven tick by tick.

    Parameters
    ----------
    config
        The ``[virtual]`` table: program, tick, noise, seed, faults.
    physics
        Machine, tools, stock, material and dexel density of the simulated machine; ``None``:
        the file ``config.physics_config``, else the packaged ``demo.toml``.

    Raises
    ------
    ConfigError
        On a material missing from the materials library, a tool without a fluted length, an
        unknown spindle preset, an unreadable program.
    NCError
        On an error in the program's first block.

    Notes
    -----
    The machine starts running the program at once (``run_state`` RUNNING, ``t_s`` 0); a stop
    latches until :meth:`restart`. Commands (:meth:`command`) apply at once and are read back
    by the next :meth:`snapshot`.
    """

    def __init__(
        self, config: VirtualMachineConfig, physics: MachiningConfig | None = None
    ) -> None:
        self.config = config
        self.physics = physics if physics is not None else _load_physics(config)
        p = self.physics
        try:
            material = milling_material(p.material.name)
        except ConfigError as err:
            raise ConfigError(f"material.name: {err}") from None
        self._coefficients = material.coefficients
        self._drive_params = spindle_drive_parameters(p.machine.spindle)
        self._resistance = self._drive_params.motor.resistance
        self._tools = {tool.number: _Tool(tool) for tool in p.tools}
        self._drilling = axial_material(
            p.material.name, {n: tool.cutter for n, tool in self._tools.items()}
        )
        self._density = (
            config.density_per_mm
            if config.density_per_mm is not None
            else p.simulation.density_per_mm
        )
        self._program_path = config.program
        self._program_text = _read_program(config.program)
        axes = p.machine.axes
        self._accel = (axes.x.max_accel_mm_s2, axes.y.max_accel_mm_s2, axes.z.max_accel_mm_s2)
        self._velocity = (
            axes.x.max_velocity_mm_min / 60.0,
            axes.y.max_velocity_mm_min / 60.0,
            axes.z.max_velocity_mm_min / 60.0,
        )
        noise = config.noise
        self._noise_sigma = np.array([getattr(noise, family) for _, family in _NOISY])
        self._noise_names = tuple(name for name, _ in _NOISY)
        self._noise_on = bool(np.any(self._noise_sigma > 0.0))
        self._rng = np.random.default_rng(config.seed)
        drives = config.axes
        self._rated_n = drives.rated_force_n
        self._friction_n = drives.friction_n
        self._mass_kg = drives.moving_mass_kg
        self._holes = [f for f in config.faults if isinstance(f, HoleFault)]
        self._values: dict[str, float] = dict.fromkeys(SIGNALS, 0.0)
        self._values["feed_override_pct"] = 100.0
        self._values["spindle_override_pct"] = 100.0
        self._values["work_offset"] = 1.0
        self._heartbeat = 0
        self._vibration = _vibration_sensor(config, p, self._coefficients)
        self._start_run()

    def warm_up(self) -> None:
        """Compile (or load) the vibration sensor's kernels (``[virtual.vibration]``) before
        the clock starts: see :meth:`VibrationSensor.warm_up`. The machine is untouched.

        Raises
        ------
        ConfigError
            For a vibrating tool the time-domain model does not take.
        """
        if self._vibration is not None:
            self._vibration.warm_up(_WARM_UP_RPM)

    # ------------------------------------------------------------------ program runs
    def _start_run(self) -> None:
        """Start the program from its beginning with a fresh blank (a new program run)."""
        p = self.physics
        setup = p.nc_setup()
        self._interpreter = Interpreter(setup)
        name = str(self._program_path) if self._program_path is not None else "demo.ngc"
        segments: Iterator[Segment] = self._interpreter.run_text(self._program_text, name)
        self._follower = PathFollower(
            segments,
            rapid_mm_min=p.machine.rapid_mm_min,
            accel_mm_s2=self._accel,
            velocity_mm_s=self._velocity,
            junction_deviation_mm=self.config.junction_deviation_mm,
            start_mm=setup.initial_position_mm,
        )
        self._stock = blank_with_holes(p.stock, self._density, self._holes)
        grid = self._stock.grid
        self._stock_lo = grid.origin_mm
        self._stock_hi = tuple(o + s for o, s in zip(grid.origin_mm, grid.size_mm, strict=True))
        self._pitch_z = grid.pitch_mm[2]
        self._faults = FaultInjector(self.config.faults)
        for tool in self._tools.values():
            tool.broken = None
        self._spindle = SpindleDrive(self._drive_params)
        self._segment: Segment | None = None
        self._t = 0.0
        self._run_state = RunState.RUNNING
        self._stop_latched = False
        self._hold = False
        self._alarm: str | None = None
        self._prev_tcp: tuple[float, float, float] | None = None
        self._prev_tool = 0
        self._prev_pos = self._follower.position_mm
        self._prev_vel = (0.0, 0.0, 0.0)
        self._cut_steps = 0
        v = self._values
        v["feed_hold"] = 0.0
        v["stop"] = 0.0
        v["emergency_stop"] = 0.0
        v["run_state"] = float(RunState.RUNNING)
        self._publish_motion(self._follower.position_mm, 0.0)

    def restart(self) -> None:
        """A new program run: the program from the start on a fresh blank; a stop unlatches.

        Overrides and wear offsets keep their values; the heartbeat keeps counting.
        """
        logger.info("program restarted")
        self._start_run()

    # ------------------------------------------------------------------ public state
    @property
    def time_s(self) -> float:
        """Machine time since the program run started, s."""
        return self._t

    @property
    def run_state(self) -> RunState:
        """State of program execution."""
        return self._run_state

    @property
    def finished(self) -> bool:
        """Whether the program run is over (ended, stopped or faulted) and the axes are at rest."""
        return self._run_state in _STOPPED_STATES and self._follower.speed_mm_s == 0.0

    @property
    def alarm(self) -> str | None:
        """Why the machine went to FAULT (one line), else ``None``."""
        return self._alarm

    @property
    def stock(self) -> DexelStock:
        """The machine's own stock (with its holes), as cut so far."""
        return self._stock

    @property
    def fault_events(self) -> list[FaultEvent]:
        """The faults that have started, in order (the ground truth of an injection)."""
        return list(self._faults.events)

    @property
    def tool_wear_mm(self) -> float:
        """The tool's true flank wear VB, mm (ground truth of a flank-wear fault; 0 without
        one). A real machine does not report it: it is not a signal."""
        return self._faults.flank_wear_mm()

    @property
    def tick_s(self) -> float:
        """The configured simulation step, s."""
        return self.config.tick_s

    def block(self, name: str, since: int) -> SampleBlock:
        """The samples of a fast signal from index ``since`` on: ``"vibration"``, the tool-tip
        displacement sensor of ``[virtual.vibration]`` (x along the feed, y across it, um;
        :mod:`cnctwin.virtual.vibration`).

        Raises
        ------
        DataError
            For another name, or a machine without ``[virtual.vibration]``.
        """
        if name != BLOCK_NAME or self._vibration is None:
            raise DataError(
                f"block {name!r}: this virtual machine serves "
                + ("'vibration'" if self._vibration is not None else "no blocks")
                + " (set [virtual.vibration] stability_file for a vibration sensor)"
            )
        return self._vibration.block(since)

    def snapshot(self) -> dict[str, float]:
        """Current value of every signal of :data:`~cnctwin.thread.signals.SIGNALS`.

        Returns
        -------
        dict
            Signal name -> value in the signal's unit; integers and flags as floats. Commands
            read back the value last accepted.
        """
        return dict(self._values)

    # ------------------------------------------------------------------ commands
    def command(self, name: str, value: float) -> None:
        """Apply a command at once; the next :meth:`snapshot` reads it back.

        Parameters
        ----------
        name
            A name of :data:`~cnctwin.thread.signals.COMMANDS`.
        value
            In the command's unit and range (flags: 0 or 1).

        Raises
        ------
        ConfigError
            On an unknown name, a value that is not a finite number, or one outside the range;
            the message names the value and what is valid.

        Notes
        -----
        ``stop`` = 1 latches: axes decelerate to rest, the spindle stops, ``run_state`` is
        STOPPED until :meth:`restart`; writing 0 does not unlatch it (``stop`` reads back 1).
        ``emergency_stop`` = 1 latches too: the machine goes to FAULT (alarm "emergency
        stop"), the axes brake to rest at their acceleration limits, the spindle stops;
        ``stop`` reads back 1 with it, and only :meth:`restart` clears both.
        ``feed_hold`` = 1 decelerates the axes to rest (dwells pause) until it is set to 0.
        ``tool_length_wear_mm`` shifts the Z axis (and the tool tip) at once;
        ``tool_radius_wear_mm`` moves the path while the program's cutter radius compensation
        (G41/G42) is on, as a larger compensation radius would (see :func:`_radius_wear_shift`),
        and is only stored and read back otherwise.
        """
        number = check_command(name, value)
        if name == "stop":
            if number == 1.0 and not self._stop_latched:
                self._stop_latched = True
                self._run_state = RunState.STOPPED
                self._values["run_state"] = float(RunState.STOPPED)
                logger.info("t=%.4f s: stop (latched)", self._t)
            elif number == 0.0 and self._stop_latched:
                logger.info("stop=0 ignored: a stop stays latched until the program restarts")
            self._values["stop"] = 1.0 if self._stop_latched else 0.0
            return
        if name == "emergency_stop":
            if number == 1.0 and self._values["emergency_stop"] != 1.0:
                self._values["emergency_stop"] = 1.0
                self._stop_latched = True
                self._values["stop"] = 1.0
                self._fault("emergency stop")
            elif number == 0.0 and self._values["emergency_stop"] == 1.0:
                logger.info("emergency_stop=0 ignored: it stays latched until the program restarts")
            return
        if name == "feed_hold":
            self._hold = number == 1.0
            if self._run_state in (RunState.RUNNING, RunState.FEED_HOLD):
                self._run_state = RunState.FEED_HOLD if self._hold else RunState.RUNNING
                self._values["run_state"] = float(self._run_state)
        self._values[name] = number

    # ------------------------------------------------------------------ the tick
    def step(self, dt_s: float) -> None:
        """Advance the machine by ``dt_s`` seconds of machine time.

        Parameters
        ----------
        dt_s
            Tick length, s (finite, > 0); the clock calls it with ``tick_ms`` / 1000.

        Raises
        ------
        ConfigError
            On a tick that is not finite and > 0.
        """
        if not (math.isfinite(dt_s) and dt_s > 0.0):
            raise ConfigError(f"step(dt_s={dt_s!r}); give a finite tick > 0 s")
        v = self._values
        self._t += dt_s
        self._heartbeat += 1
        follower = self._follower
        running = self._run_state in (RunState.RUNNING, RunState.FEED_HOLD)
        hold = self._hold or not running
        if not follower.finished:
            try:
                follower.advance(dt_s, v["feed_override_pct"] / 100.0, hold)
            except NCError as err:
                self._fault(f"NC program: {err}")
                follower.advance(dt_s, 0.0, True)
        move = follower.move
        if move is not None:
            self._segment = move.segment
        elif self._run_state in (RunState.RUNNING, RunState.FEED_HOLD):
            self._run_state = RunState.FINISHED
            logger.info("t=%.4f s: program finished", self._t)
        seg = self._segment
        position = follower.position_mm
        speed_mm_min = follower.travelled_mm / dt_s * 60.0

        # Spindle reference: S x override, signed by the direction, 0 once the run is over.
        ref_rpm = 0.0
        tool_number = 0
        line = 0
        offset = (0.0, 0.0, 0.0)
        if seg is not None:
            state = seg.state
            tool_number = state.tool
            line = seg.line
            offset = state.tool_offset_mm
            v["work_offset"] = float(state.coordinate_system)
            if self._run_state not in _STOPPED_STATES:
                ref_rpm = seg.spindle_rpm * state.spindle_direction * v["spindle_override_pct"]
                ref_rpm /= 100.0
        self._faults.update(self._t, line, tool_number, dt_s, self._cut_steps > 0)

        # The cut: the tool tip (with wear offset and breakage) through the machine's stock.
        wear_z = v["tool_length_wear_mm"]
        shift = _radius_wear_shift(seg, follower.tangent, v["tool_radius_wear_mm"])
        axes_pos = (position[0] + shift[0], position[1] + shift[1], position[2] + wear_z)
        tcp = (axes_pos[0] - offset[0], axes_pos[1] - offset[1], axes_pos[2] - offset[2])
        spindle_rpm = self._spindle.state.speed / RAD_S_PER_RPM
        forces = (0.0, 0.0, 0.0)
        torque = 0.0
        contact = False
        vibrating: tuple[Engagement, float] | None = None  # the cut the sensor sees
        tool = self._tools.get(tool_number)
        if tool is None and tool_number != 0 and self._run_state not in _STOPPED_STATES:
            self._fault(f"tool T{tool_number} has no geometry in [[tools]] (line {line})")
        if tool_number != self._prev_tool:
            self._prev_tcp = None  # a new tool: no previous position (as simulate_cut does)
            self._prev_tool = tool_number
        if tool is not None:
            cutter, lift = self._cutter(tool, tool_number)
            cut_tcp = (tcp[0], tcp[1], tcp[2] + lift)
            if cutter is not None and self._near_stock(cutter, cut_tcp):
                rpm = abs(spindle_rpm)
                fz = speed_mm_min / (rpm * cutter.flutes) if rpm >= 1.0 else 0.0
                engagement = cut(self._stock, cutter, cut_tcp, self._prev_tcp, fz, dt_s)
                if engagement.contact:
                    contact = True
                    vibrating = (engagement, fz)
                    fx, fy, fz_n, torque, mean_n = self._mean_load(
                        engagement, tool_number, cutter, fz, rpm
                    )
                    scale = self._faults.load_scale()
                    chatter = self._faults.vibration_n(self._t, mean_n * scale)
                    forces = (
                        fx * scale + chatter[0],
                        fy * scale + chatter[1],
                        fz_n * scale,
                    )
                    torque = torque * scale + self._faults.rubbing_torque_nm(
                        engagement, cutter.flutes
                    )
            self._prev_tcp = cut_tcp
        self._cut_steps = self._cut_steps + 1 if contact else 0
        sensor = self._vibration
        if sensor is not None:
            cutting = vibrating is not None and tool_number == sensor.tool_number
            engaged, fz_mm = vibrating if cutting and vibrating is not None else (None, 0.0)
            sensor.update(self._t, spindle_rpm, engaged, fz_mm)

        # Spindle drive, loaded by the cutting torque (Christiand 2024, Eq. 15). After M5, a
        # stop or the end the drive brakes the spindle to rest (reference 0), then switches off.
        enabled = ref_rpm != 0.0 or abs(spindle_rpm) > _SPINDLE_OFF_RPM
        events = EventState(enabled, speed_mm_min > 0.0, contact)
        sample = self._spindle.step(dt_s, ref_rpm, torque, events)

        # Feed drives: cutting force on the tool + friction + inertia, % of rated.
        prev_pos, prev_vel = self._prev_pos, self._prev_vel
        velocity = (
            (position[0] - prev_pos[0]) / dt_s,
            (position[1] - prev_pos[1]) / dt_s,
            (position[2] - prev_pos[2]) / dt_s,
        )
        for k, name in enumerate(_LOADS):
            accel_m_s2 = (velocity[k] - prev_vel[k]) / dt_s * 1e-3
            friction = math.copysign(self._friction_n, velocity[k]) if velocity[k] else 0.0
            drive_n = forces[k] + friction + self._mass_kg * accel_m_s2
            v[name] = 100.0 * drive_n / self._rated_n
        self._prev_pos = position
        self._prev_vel = velocity

        v["t_s"] = self._t
        self._publish_motion(axes_pos, speed_mm_min)
        v["spindle_rpm"] = sample.speed_rpm
        v["spindle_rpm_command"] = ref_rpm
        v["spindle_torque_nm"] = sample.torque
        v["spindle_current_a"] = sample.current
        # Input power of the motor: mechanical output plus copper loss (the lumped model's
        # K_e and K_T differ, so V i is not a power balance).
        v["spindle_power_w"] = sample.torque * sample.speed + self._resistance * sample.current**2
        v["force_x_n"] = -forces[0]
        v["force_y_n"] = -forces[1]
        v["force_z_n"] = -forces[2]
        v["program_line"] = float(line)
        v["tool_number"] = float(tool_number)
        v["run_state"] = float(self._run_state)
        v["heartbeat"] = float(self._heartbeat)
        if self._noise_on:
            noise = self._rng.standard_normal(self._noise_sigma.size) * self._noise_sigma
            for name, value in zip(self._noise_names, noise.tolist(), strict=True):
                v[name] += value
            v["feed_mm_min"] = max(v["feed_mm_min"], 0.0)

    # ------------------------------------------------------------------ helpers
    def _publish_motion(self, axes_pos: tuple[float, float, float], speed_mm_min: float) -> None:
        v = self._values
        v["x_mm"], v["y_mm"], v["z_mm"] = axes_pos
        v["feed_mm_min"] = speed_mm_min

    def _mean_load(
        self, engagement: Engagement, tool: int, cutter: Cutter, fz_mm: float, rpm: float
    ) -> tuple[float, float, float, float, float]:
        """Per-revolution mean force on the tool (machine X, Y, Z; N), torque (N m) and force
        magnitude (N) of a cut: :func:`cnctwin.simulation.step_forces` without its peak force
        (the milling model, Altintas 2012 ch. 2, or the drilling model for a drill or a tap)."""
        step = CutStep(
            self._cut_steps, self._t, (0.0, 0.0, 0.0), 0, tool, cutter, rpm, fz_mm, engagement
        )
        load = step_forces(
            step, self._coefficients, self._pitch_z, waveform_steps=0, drilling=self._drilling
        )
        return (load.fx_n, load.fy_n, load.fz_n, load.torque_nm, load.mean_n)

    def _fault(self, message: str) -> None:
        """Alarm: stop the axes and the spindle, run_state FAULT."""
        if self._run_state == RunState.FAULT:
            return
        self._alarm = message
        self._run_state = RunState.FAULT
        self._values["run_state"] = float(RunState.FAULT)
        logger.error("t=%.4f s: machine fault: %s", self._t, message)

    def _cutter(self, tool: _Tool, number: int) -> tuple[Cutter | None, float]:
        """The cutter that cuts and how far its tip sits above the nominal tip (mm)."""
        lost = self._faults.lost_length_mm(number, tool.cutter.flute_length_mm)
        if lost <= 0.0:
            return tool.cutter, 0.0
        if tool.broken is None or tool.broken[0] != lost:
            remaining = tool.cutter.flute_length_mm - lost
            stub = (
                replace(
                    tool.cutter,
                    kind="flat",
                    flute_length_mm=remaining,
                    corner_radius_mm=0.0,
                    tip_diameter_mm=0.0,
                    tip_angle_rad=0.0,
                    web_mm=0.0,
                    pitch_mm=0.0,
                )
                if remaining > 1e-3
                else None
            )
            tool.broken = (lost, stub)
        return tool.broken[1], lost

    def _near_stock(self, cutter: Cutter, tcp: tuple[float, float, float]) -> bool:
        """Whether the cutter's envelope at ``tcp`` (mm) can reach the stock's box."""
        r = cutter.radius_mm
        lo, hi = self._stock_lo, self._stock_hi
        return (
            tcp[0] + r >= lo[0]
            and tcp[0] - r <= hi[0]
            and tcp[1] + r >= lo[1]
            and tcp[1] - r <= hi[1]
            and tcp[2] <= hi[2]
            and tcp[2] + cutter.flute_length_mm >= lo[2]
        )


def _radius_wear_shift(
    seg: Segment | None, tangent: tuple[float, float, float], wear_mm: float
) -> tuple[float, float, float]:
    """Where the radius wear offset moves the controlled point, mm (machine X, Y, Z).

    With cutter radius compensation on, the path is the programmed contour's parallel at the
    compensation radius ``r`` on the compensation side; a wear offset ``w`` makes it the
    parallel at ``r + w``, which is the path at ``r`` moved by ``w`` along its normal toward
    that side (parallel curves compose). This is exact along lines and arcs; at a corner the
    compensator joins (an arc at a convex corner stays a parallel; at a concave corner the
    point steps to the next move's parallel instead of the moves' shortened intersection).
    Zero without compensation, in a dwell, or at rest at the end.
    """
    if seg is None or wear_mm == 0.0 or seg.state.cutter_comp == CutterComp.OFF:
        return (0.0, 0.0, 0.0)
    i0, i1, _ = PLANE_AXES[Plane(seg.state.plane)]
    norm = math.hypot(tangent[i0], tangent[i1])
    if norm <= 0.0:
        return (0.0, 0.0, 0.0)
    scale = (wear_mm if seg.state.cutter_comp == CutterComp.LEFT else -wear_mm) / norm
    shift = [0.0, 0.0, 0.0]
    shift[i0] = -scale * tangent[i1]  # the left normal of (t0, t1) is (-t1, t0)
    shift[i1] = scale * tangent[i0]
    return (shift[0], shift[1], shift[2])


def check_command(name: str, value: float) -> float:
    """A command's value as a float, checked against :data:`~cnctwin.thread.COMMANDS`.

    Parameters
    ----------
    name
        A command's name.
    value
        In the command's unit (flags: 0 or 1).

    Returns
    -------
    float
        The value, in the command's unit.

    Raises
    ------
    ConfigError
        On an unknown name, a value that is not a finite number, or one outside the range;
        the message names the value and what is valid.
    """
    spec = COMMANDS.get(name)
    if spec is None:
        raise ConfigError(
            f"command {name!r} is unknown; valid commands: {', '.join(sorted(COMMANDS))}"
        )
    valid = f"{spec.low:g} to {spec.high:g} {spec.unit}"
    if spec.kind == "bool":
        valid = "0 or 1"
    if isinstance(value, bool):
        number = float(value)
    else:
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise ConfigError(f"command {name}={value!r} is not a number; valid: {valid}") from None
    if not math.isfinite(number):
        raise ConfigError(f"command {name}={value!r} is not finite; valid: {valid}")
    assert spec.low is not None and spec.high is not None  # every command has a range
    if spec.kind == "bool" and number not in (0.0, 1.0):
        raise ConfigError(f"command {name}={value!r}; valid: {valid}")
    if not spec.low <= number <= spec.high:
        raise ConfigError(f"command {name}={value!r} is out of range; valid: {valid}")
    return number


def _vibration_sensor(
    config: VirtualMachineConfig, physics: MachiningConfig, coefficients: CuttingCoefficients
) -> VibrationSensor | None:
    """The vibration sensor of ``[virtual.vibration]``, or ``None`` without a stability file."""
    vibration = config.vibration
    if vibration.stability_file is None:
        return None
    tool = next((t for t in physics.tools if t.number == vibration.tool), None)
    if tool is None:
        numbers = ", ".join(str(t.number) for t in physics.tools) or "none"
        raise ConfigError(
            f"virtual.vibration.tool = {vibration.tool}: no such tool in [[tools]] "
            f"(numbers: {numbers})"
        )
    return VibrationSensor(vibration, tool, coefficients, seed=config.seed)


def _load_physics(config: VirtualMachineConfig) -> MachiningConfig:
    """The physics configuration: ``physics_config``, else the packaged demo.toml."""
    if config.physics_config is not None:
        return load_config(config.physics_config)
    with ExitStack() as stack:
        path = stack.enter_context(as_file(example_file("demo.toml")))
        return load_config(path)


def _read_program(path: Path | None) -> str:
    """The program's text: the file, else the packaged demo.ngc."""
    if path is None:
        return example_file("demo.ngc").read_text(encoding="utf-8")
    try:
        return path.read_text(encoding="utf-8")
    except OSError as err:
        raise ConfigError(f"virtual.program: cannot read {path}: {err.strerror}") from err
    except UnicodeDecodeError as err:
        raise ConfigError(f"virtual.program: {path} is not UTF-8 text: {err.reason}") from err
