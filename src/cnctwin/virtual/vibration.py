"""The virtual machine's regenerative vibration and its tool-tip displacement sensor.

Each tick the machine hands :class:`VibrationSensor` the cut of that tick (spindle speed, the
engagement's axial depth and immersion, the feed per tooth); the sensor advances the
time-domain milling model with the tool's modes to the tick's end
(:class:`cnctwin.dynamics.MillingStream`; Royandi 2026, Eq. 1-12 with the regenerative chip):
an unstable depth grows into chatter, a stable one settles to the forced vibration at the
tooth period. The tool-tip displacement (x along the feed, y across it, um) is sampled at
``sample_rate_hz`` (linear interpolation between integration steps, which are 20 or more times
shorter), sensor noise added, and kept in a ring of ``buffer_s`` seconds from which a reader
takes the samples since its last read (:meth:`VibrationSensor.block`).

The immersion of a tick is the span of the engagement's contact intervals (the first entry
to the last exit over the slices, in the frame of :mod:`cnctwin.mechanics.engagement`); the
depth its ``ap_mm``. The mean cutting forces the machine serves stay those of its
mechanistic model (docs/virtual-machine.md); the vibration is a sensor of its own.

Units: um for the samples, Hz, s; SI inside the model.
"""

from __future__ import annotations

import math
import threading

import numpy as np

from cnctwin.config import ToolConfig
from cnctwin.dynamics import CutConditions, MillingStream, load_stability_config
from cnctwin.errors import ConfigError, InputError
from cnctwin.geometry import Cutter, Engagement
from cnctwin.mechanics import CuttingCoefficients
from cnctwin.thread import SampleBlock
from cnctwin.virtual.config import VibrationConfig

__all__ = ["BLOCK_NAME", "VibrationSensor"]

#: The name the machine serves the samples under.
BLOCK_NAME = "vibration"
_RPM = math.pi / 30.0


class VibrationSensor:
    """The cut's vibration and its displacement sensor (module notes).

    Parameters
    ----------
    config
        ``[virtual.vibration]`` (its ``stability_file`` set).
    tool
        The tool in the spindle (a flat end mill).
    coefficients
        The material's cutting coefficients (SI).
    seed
        Seed of the sensor noise.

    Raises
    ------
    ConfigError
        For a stability file that cannot be read, or (at the first cut) a tool the
        time-domain model does not take (not a flat end mill, runout).

    Notes
    -----
    The integration grid is made for the spindle speed of the first cut (200 steps per cycle
    of the highest mode there, at least 200 per tooth period); only ``tool`` vibrates (the
    stability file's modes are its own), other tools cut as in air.
    """

    def __init__(
        self,
        config: VibrationConfig,
        tool: ToolConfig,
        coefficients: CuttingCoefficients,
        *,
        seed: int = 0,
    ) -> None:
        if config.stability_file is None:
            raise ConfigError("virtual.vibration.stability_file: give the tool's modes")
        self.modes = load_stability_config(config.stability_file).tool_dynamics()
        self.cutter = Cutter.from_tool_config(tool)
        self.coefficients = coefficients
        self.config = config
        self.tool_number = tool.number
        self.rate_hz = config.sample_rate_hz
        self.stream: MillingStream | None = None
        self._offset_s = 0.0  # machine time at which the stream started
        self._design_rpm = math.nan
        self._noise_m = config.noise_um * 1e-6
        self._rng = np.random.default_rng(seed)
        self._ring = np.zeros((max(16, math.ceil(config.buffer_s * self.rate_hz)), 2))
        self._count = 0  # samples taken
        # The machine's thread stores while a server's thread reads (virtual.opcua_server).
        self._ring_lock = threading.Lock()
        self._last_t = 0.0  # machine time and displacement (m) of the last output
        self._last_r = np.zeros(2)

    def _stream(self, rpm: float) -> MillingStream:
        """A stream of the model, its grid made for ``rpm`` (rpm)."""
        try:
            return MillingStream(
                self.modes,
                self.cutter,
                self.coefficients,
                design_rpm=rpm,
                steps_per_tooth=self.config.steps_per_tooth,
            )
        except InputError as err:
            raise ConfigError(f"virtual.vibration: tool T{self.tool_number}: {err}") from None

    def _start(self, rpm: float) -> MillingStream:
        """The model's stream, its grid made for the speed of the first cut."""
        stream = self._stream(rpm)
        self._design_rpm = rpm
        self._offset_s = self._last_t
        return stream

    def warm_up(self, rpm: float) -> None:
        """Compile (or load from numba's cache) the time-domain kernels before the machine
        runs, so that its first cut does not stall its clock (tens of seconds on a first run
        after installing): a throw-away stream integrates a few steps of a cut at ``rpm``
        (rpm, > 0) and in air. The sensor itself is untouched.

        Raises
        ------
        ConfigError
            For a tool the time-domain model does not take (as the first cut would).
        """
        stream = self._stream(rpm)
        spindle_rad_s = rpm * _RPM
        cut = CutConditions(spindle_rad_s, 1e-3, 0.0, 0.5 * math.pi, 5e-5)
        stream.advance(cut, 4)
        stream.advance(CutConditions(spindle_rad_s, 0.0, 0.0, 0.0, 0.0), 4)

    @property
    def samples_taken(self) -> int:
        """Samples taken since the sensor started."""
        return self._count

    def update(
        self,
        t_end_s: float,
        spindle_rpm: float,
        engagement: Engagement | None,
        feed_per_tooth_mm: float,
    ) -> None:
        """Integrate the cut to machine time ``t_end_s`` and sample it.

        Parameters
        ----------
        t_end_s
            Machine time at the end of the tick, s.
        spindle_rpm
            Spindle speed during the tick, rpm (below 1 rpm: the tool does not cut).
        engagement
            The tick's engagement; ``None`` or no contact: the tool is in air.
        feed_per_tooth_mm
            Feed per tooth, mm.
        """
        rpm = abs(spindle_rpm)
        conditions = _conditions(rpm, engagement, feed_per_tooth_mm)
        if self.stream is None:
            if conditions is None:  # before the first cut: the tool at rest
                self._sample(np.array([self._last_t, t_end_s]), np.zeros((2, 2)))
                self._last_t = t_end_s
                return
            self.stream = self._start(rpm)
        if conditions is None:  # in air: the modes ring down at the grid's design speed
            conditions = CutConditions(self._design_rpm * _RPM, 0.0, 0.0, 0.0, 0.0)
        stream = self.stream
        dt = stream.step_s(conditions.spindle_rad_s)
        steps = math.ceil((t_end_s - self._offset_s - stream.time_s) / dt)
        if steps < 1:
            return
        t0 = self._offset_s + stream.time_s
        rows = stream.advance(conditions, steps)
        times = np.concatenate(([self._last_t], t0 + np.arange(steps) * dt))
        self._sample(times, np.vstack((self._last_r, rows[:, 0:2])))
        self._last_t = float(times[-1])
        self._last_r = rows[-1, 0:2].copy()

    def _sample(self, times: np.ndarray, r_m: np.ndarray) -> None:
        """Sample the displacement ``r_m`` (m) known at ``times`` (s) up to the last time."""
        first = self._count
        last = math.floor(times[-1] * self.rate_hz + 1e-9)
        if last < first:
            return
        at = np.arange(first, last + 1) / self.rate_hz
        sampled = np.column_stack([np.interp(at, times, r_m[:, k]) for k in (0, 1)])
        if self._noise_m > 0.0:
            sampled += self._rng.normal(0.0, self._noise_m, sampled.shape)
        self._store(sampled * 1e6)

    def block(self, since: int) -> SampleBlock:
        """The samples from index ``since`` on (from the oldest kept, if older), um, x and y.

        Parameters
        ----------
        since
            Index of the first sample wanted (>= 0); the samples taken so far: an empty block.
        """
        with self._ring_lock:
            size = self._ring.shape[0]
            count = self._count
            start = min(max(int(since), count - size, 0), count)
            samples = self._ring[np.arange(start, count) % size]  # fancy indexing: a copy
        return SampleBlock(BLOCK_NAME, start, self.rate_hz, samples)

    def _store(self, samples: np.ndarray) -> None:
        size = self._ring.shape[0]
        samples = samples[-size:]
        with self._ring_lock:
            index = (self._count + np.arange(samples.shape[0])) % size
            self._ring[index] = samples
            self._count += samples.shape[0]


def _conditions(
    rpm: float, engagement: Engagement | None, feed_per_tooth_mm: float
) -> CutConditions | None:
    """The cut of a tick in the model's terms, or ``None`` in air (or the spindle at rest)."""
    if engagement is None or not engagement.contact or rpm < 1.0:
        return None
    starts = np.asarray(engagement.interval_start_rad)
    ends = np.asarray(engagement.interval_end_rad)
    if starts.size == 0 or engagement.ap_mm <= 0.0:
        return None  # bottom contact only: no flank cut
    return CutConditions(
        spindle_rad_s=rpm * _RPM,
        depth_m=engagement.ap_mm * 1e-3,
        entry_rad=float(starts.min()),
        exit_rad=float(ends.max()),
        feed_per_tooth_m=max(feed_per_tooth_mm, 0.0) * 1e-3,
    )
