"""Step 9e of the cycle: chatter detected in the machine's vibration signal, and avoided.

**Detection.** Every cycle :class:`ChatterStage` reads the samples the machine's vibration
sensor took since the last cycle (``MachineConnection.read_block``, a block such as the
virtual machine's tool-tip displacement at 10 kHz, x and y) and pushes them into two
:class:`~cnctwin.dynamics.StreamingChatterDetector` (one per channel): windows of
``window_s`` every ``hop_s``, each judged by its energy off the tooth-passing harmonics
(:mod:`cnctwin.dynamics.chatter_detection`; Ward 2021, Sec. 4.3). The harmonics are those of
the measured spindle speed and the tool's teeth; when the speed moves by more than
``speed_tolerance_pct`` the detectors start again at the new speed (a window must not mix
two speeds). A window counts only while the twin sees the tool cut (``contact``), when it
starts ``entry_s`` or more after the cut began or its engagement last changed (``ae_mm`` or
``ap_mm`` by more than ``engagement_tolerance_mm``: a step of force rings the tool's modes at
their natural frequencies, off the harmonics, for a few time constants ``1 / (zeta wn)``
even where the cut is stable, and the tool entering or leaving the material changes the
engagement all the way) and the cycle's vibration RMS is at least
``min_rms_um`` (in air the sensor's noise alone has no harmonics); ``confirm_windows``
chattering windows in a row are chatter.

**Avoidance.** The stability roadmap of the program (Ward 2021, Sec. 3.4, Eq. 6:
:func:`cnctwin.dynamics.program_roadmap` with the tool's modes of ``stability_file``) gives
each cutting line the nearest stable speed to the programmed one within the machine's
spindle limits, with ``margin`` on the depth. On chatter in a line whose roadmap speed is
not the programmed one, the stage asks for the spindle override ``100 x roadmap / programmed``
% (within ``[control.spindle_override]``) and scales the feed override by the same factor
(within ``[control.feed_override]``), so the chip load (feed per tooth ``F / (N n)``) stays.
Where the roadmap calls the programmed speed stable (chatter the model did not predict) or
finds no stable speed, it commands nothing and records an event. The decisions are those
of the rule ``chatter_avoidance``: they pass the safety filter (enable switch, bounds, rate
limits) and obey the lost-machine policy (docs/control.md). One avoidance per line.

The read runs alongside the cycle: :class:`ChatterRequest`, placed right after the read
stage, sends it (:meth:`MachineConnection.start_read_block`: over OPC UA the request is in
the socket when the step returns), so the machine answers while the physics stages run, and
the chatter stage takes the answer. A machine that has not answered within 1 ms of the
chatter stage's turn is asked no more until it has, and its samples are taken in a later
cycle (they carry their own sample index, so nothing is lost or counted twice; a cycle
without new samples shows the last outputs).

**Lost machine.** While the connection is down the stage commands nothing and reads
nothing; afterwards the detectors start again (the windows across the gap would join
vibration from before and after it) and samples the machine no longer holds are counted as
a gap (an event).

Names it adds to :attr:`CycleState.predicted` (units in the names):
``chatter_ratio`` (the newest window's energy ratio, the larger of x and y),
``chatter_frequency_hz`` (its dominant peak off the harmonics), ``chatter_detected`` (1 from
the confirming window until a stable window), ``chatter_vibration_um`` (RMS of the cycle's
samples about their mean, x and y together), ``chatter_stable_rpm`` (the roadmap's speed for
the line; NaN without one) and ``chatter_avoided`` (1 once the line's avoidance was asked).
Events: ``chatter`` (detected, with the sensor time of the confirming window's end),
``chatter_unavoidable`` and ``chatter_gap``.
"""

from __future__ import annotations

import asyncio
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import Field, ValidationInfo, field_validator, model_validator
from pydantic_core import PydanticCustomError

from cnctwin.config import Section, resolve_file
from cnctwin.control import Decision
from cnctwin.dynamics import (
    DetectorSettings,
    RoadmapSegment,
    StreamingChatterDetector,
    WindowVerdict,
)
from cnctwin.errors import ConfigError, DataError
from cnctwin.thread import ConnectionLost, MachineConnection, SampleBlock, drop_answer
from cnctwin.twin.state import CycleState, TwinEvent

if TYPE_CHECKING:
    from cnctwin.config import MachiningConfig
    from cnctwin.control import ControlConfig
    from cnctwin.dynamics import StabilityRoadmap

__all__ = [
    "CHATTER_PREDICTIONS",
    "RULE",
    "ChatterConfig",
    "ChatterRequest",
    "ChatterStage",
    "chatter_stage",
]

#: The rule name of the stage's decisions.
RULE = "chatter_avoidance"

#: Longest wait for the machine's samples in a cycle, s; a slower answer is taken in the next
#: cycle (the read goes on meanwhile), so a busy machine does not hold up the cycle.
_WAIT_S = 0.001

#: The names the stage adds (units in the names).
CHATTER_PREDICTIONS = (
    "chatter_ratio",
    "chatter_frequency_hz",
    "chatter_detected",
    "chatter_vibration_um",
    "chatter_stable_rpm",
    "chatter_avoided",
)


class ChatterConfig(Section):
    """Online chatter detection and avoidance (``[twin.chatter]``; docs/chatter-live.md).

    Attributes
    ----------
    enabled
        Run the stage (off by default). It commands only when ``[control]`` is enabled.
    block
        The machine's sample block to read (the virtual machine's ``"vibration"``).
    window_s, hop_s
        Detector window and hop, s (``hop_s`` <= ``window_s``).
    threshold
        Energy ratio off the harmonics above which a window chatters, 0 < threshold < 1.
    confirm_windows
        Chattering windows in a row that make chatter.
    min_rms_um
        Least vibration RMS of a cycle's samples for its windows to be judged, um.
    entry_s
        Windows that start less than this after the cut began or its engagement changed are
        not judged, s.
    engagement_tolerance_mm
        A change of the twin's ``ae_mm`` or ``ap_mm`` beyond this is a new engagement, mm
        (at least the twin's dexel pitch, whose steps the engagement jitters by).
    speed_tolerance_pct
        Spindle-speed change that restarts the detectors at the new speed, %.
    avoid
        Command the roadmap's stable speed on chatter (needs ``stability_file``).
    stability_file
        Stability file with the tool's modes (docs/stability.md), relative to this file.
    margin
        The roadmap's factor on the depth of cut, >= 1.
    """

    enabled: bool = False
    block: str = Field(default="vibration", min_length=1, max_length=64)
    window_s: float = Field(default=0.05, ge=0.002, le=10.0)
    hop_s: float = Field(default=0.025, ge=0.001, le=10.0)
    threshold: float = Field(default=0.2, gt=0.0, lt=1.0)
    confirm_windows: int = Field(default=2, ge=1, le=100)
    min_rms_um: float = Field(default=0.5, ge=0.0, le=1e4)
    entry_s: float = Field(default=0.03, ge=0.0, le=60.0)
    engagement_tolerance_mm: float = Field(default=0.6, gt=0.0, le=100.0)
    speed_tolerance_pct: float = Field(default=0.5, gt=0.0, le=50.0)
    avoid: bool = True
    stability_file: Path | None = None
    margin: float = Field(default=1.2, ge=1.0, le=10.0)

    @field_validator("stability_file")
    @classmethod
    def _relative_to_file(cls, value: Path | None, info: ValidationInfo) -> Path | None:
        return resolve_file(value, info)

    @model_validator(mode="after")
    def _consistent(self) -> ChatterConfig:
        if self.hop_s > self.window_s:
            raise PydanticCustomError(
                "chatter_hop",
                "hop_s = {hop} s is longer than window_s = {window} s; give hop_s <= window_s",
                {"hop": self.hop_s, "window": self.window_s},
            )
        if self.enabled and self.avoid and self.stability_file is None:
            raise PydanticCustomError(
                "chatter_modes",
                "avoid = true needs stability_file (the tool's modes for the roadmap); "
                "give it or set avoid = false",
            )
        return self


@dataclass
class _Detectors:
    """One detector per channel, made for one spindle speed."""

    rpm: float
    first_index: int  # sensor sample index of the detectors' first sample
    channels: tuple[StreamingChatterDetector, ...]


class ChatterStage:
    """Online chatter detection and avoidance in the cycle (module notes).

    Parameters
    ----------
    config
        ``[twin.chatter]``.
    connection
        The machine (its sample block).
    teeth
        Teeth of each tool by number.
    roadmap
        The program's stability roadmap (``None``: detection only).
    spindle_bounds, feed_bounds
        ``(min_pct, max_pct)`` of ``[control.spindle_override]`` and ``[control.feed_override]``.
    """

    name = "chatter"

    def __init__(
        self,
        config: ChatterConfig,
        connection: MachineConnection,
        teeth: dict[int, int],
        roadmap: StabilityRoadmap | None,
        spindle_bounds: tuple[float, float],
        feed_bounds: tuple[float, float],
    ) -> None:
        self.config = config
        self.connection = connection
        self.teeth = teeth
        self.roadmap = roadmap
        self.spindle_bounds = spindle_bounds
        self.feed_bounds = feed_bounds
        self._segments: dict[tuple[int, int], RoadmapSegment] = {}
        if roadmap is not None:
            for segment in roadmap.segments:
                self._segments.setdefault((segment.tool, segment.line), segment)
        self._next = 0  # next sample index wanted
        self._detectors: _Detectors | None = None
        self._run = 0  # chattering windows in a row
        self._detected = False
        self._avoided: set[tuple[int, int]] = set()
        self._blind = False
        self._served = False  # a valid block has come: a later bad one is the machine's fault
        self._latest: tuple[float, float] = (math.nan, math.nan)
        self._pending: asyncio.Future[SampleBlock] | None = None
        self._outputs: dict[str, float] = {}
        self._cut_since_s = math.nan  # machine time the current engagement began (NaN in air)
        self._engagement = (math.nan, math.nan)  # its ae, ap, mm
        self._detections: list[dict[str, float]] = []
        self._avoidances: list[dict[str, float]] = []

    def request(self, state: CycleState) -> None:
        """Send the read of the samples since the last block (unless one is on its way), so
        that the machine answers while the cycle's other stages run."""
        if not state.connected or self._pending is not None:
            return
        self._pending = self._read_from_next()

    async def process(self, state: CycleState) -> CycleState:
        """Read the new samples, detect, and on chatter ask for the roadmap's speed."""
        if not state.connected:
            self._blind = True
            if self._pending is not None:
                drop_answer(self._pending)
                self._pending = None
            return state
        if self._blind:  # after a gap: the windows start again
            self._blind = False
            self._restart()
        if self._pending is None:  # without a ChatterRequest stage: sent now
            self._pending = self._read_from_next()
        if not self._pending.done():
            await asyncio.wait({self._pending}, timeout=_WAIT_S)
        if not self._pending.done():  # no answer yet: the samples come next cycle
            self._carry(state)
            return state
        task, self._pending = self._pending, None
        try:
            block = task.result()
        except ConnectionLost:
            self._blind = True
            return state
        except DataError as err:
            if not self._served:  # the machine serves no usable block: a configuration error
                raise DataError(f"twin.chatter: {err}") from None
            # a garbage block from a machine that served good ones: rejected, never fed; the
            # windows start again with the next good block
            state.events.append(TwinEvent("chatter_block_rejected", str(err), state.received_s, {}))
            self._blind = True
            return state
        self._served = True
        if block.first_index > self._next and self._next > 0:
            state.events.append(
                TwinEvent(
                    "chatter_gap",
                    f"{block.first_index - self._next} vibration samples lost",
                    state.received_s,
                    {"lost": block.first_index - self._next},
                )
            )
            self._restart()
        self._next = block.end_index
        p = state.predicted
        samples = np.asarray(block.samples, dtype=np.float64)
        rms = math.nan  # a cycle of fewer than two samples has no RMS about their mean
        if samples.shape[0] > 1:
            rms = float(np.sqrt(np.mean(np.sum((samples - samples.mean(axis=0)) ** 2, axis=1))))
        p["chatter_vibration_um"] = rms
        segment = self._segments.get((state.tool, state.line))
        p["chatter_stable_rpm"] = segment.scheduled_rpm if segment is not None else math.nan
        p["chatter_avoided"] = float((state.tool, state.line) in self._avoided)
        rpm = abs(state.measured.get("spindle_rpm", math.nan))
        teeth = self.teeth.get(state.tool, 0)
        contact = bool(p.get("contact", 0.0))
        engagement = (p.get("ae_mm", math.nan), p.get("ap_mm", math.nan))
        tolerance = self.config.engagement_tolerance_mm
        if not contact:
            self._cut_since_s = math.nan
        elif not math.isfinite(self._cut_since_s) or not all(
            abs(a - b) <= tolerance for a, b in zip(engagement, self._engagement, strict=True)
        ):
            self._cut_since_s = state.measured.get("t_s", math.nan)
            self._engagement = engagement
        judged = contact and rms >= self.config.min_rms_um
        if samples.shape[0] and math.isfinite(rpm) and rpm >= 1.0 and teeth >= 1:
            detectors = self._for_speed(rpm, teeth, block.first_index, block.rate_hz)
            for window in self._push(detectors, samples):
                self._judge(state, window, judged, detectors, block.rate_hz)
        p["chatter_ratio"], p["chatter_frequency_hz"] = self._latest
        p["chatter_detected"] = float(self._detected)
        if self._detected and self.config.avoid and state.tool > 0:
            self._avoid(state, segment)
        self._outputs = {name: p[name] for name in CHATTER_PREDICTIONS if name in p}
        return state

    def _carry(self, state: CycleState) -> None:
        """A cycle without new samples shows the last cycle's outputs."""
        state.predicted.update(self._outputs)

    def _read_from_next(self) -> asyncio.Future[SampleBlock]:
        """The read of the samples from the next one wanted on, sent."""
        return self.connection.start_read_block(self.config.block, self._next)

    def _restart(self) -> None:
        self._cut_since_s = math.nan
        self._detectors = None
        self._run = 0
        self._detected = False

    def _for_speed(self, rpm: float, teeth: int, first_index: int, rate_hz: float) -> _Detectors:
        """The detectors for this speed: new ones when it moved beyond the tolerance."""
        held = self._detectors
        tolerance = self.config.speed_tolerance_pct / 100.0
        if held is not None and abs(rpm - held.rpm) <= tolerance * held.rpm:
            return held
        c = self.config
        settings = DetectorSettings(
            sample_rate_hz=rate_hz,
            spindle_rpm=rpm,
            teeth=teeth,
            window_s=c.window_s,
            hop_s=c.hop_s,
            threshold=c.threshold,
            speed_tolerance=tolerance,
        )
        self._detectors = _Detectors(
            rpm,
            first_index,
            (StreamingChatterDetector(settings), StreamingChatterDetector(settings)),
        )
        self._run = 0
        return self._detectors

    @staticmethod
    def _push(
        detectors: _Detectors, samples: np.ndarray
    ) -> list[tuple[WindowVerdict, WindowVerdict]]:
        x, y = detectors.channels
        return list(zip(x.push(samples[:, 0]), y.push(samples[:, 1]), strict=True))

    def _judge(
        self,
        state: CycleState,
        windows: tuple[WindowVerdict, WindowVerdict],
        judged: bool,
        detectors: _Detectors,
        rate_hz: float,
    ) -> None:
        """Count a completed window pair toward chatter; raise the event on confirmation."""
        top = max(windows, key=lambda w: w.energy_ratio)
        self._latest = (top.energy_ratio, top.chatter_frequency_hz)
        start_s = detectors.first_index / rate_hz + top.start_s
        if not (judged and start_s >= self._cut_since_s + self.config.entry_s):
            self._run = 0
            return
        if not top.chatter:
            self._run = 0
            self._detected = False
            return
        self._run += 1
        if self._run >= self.config.confirm_windows and not self._detected:
            self._detected = True
            end_s = detectors.first_index / rate_hz + top.end_s
            self._detections.append(
                {
                    "line": state.line,
                    "window_end_s": end_s,
                    "after_engagement_s": end_s - self._cut_since_s,
                    "frequency_hz": top.chatter_frequency_hz,
                    "energy_ratio": top.energy_ratio,
                    "spindle_rpm": detectors.rpm,
                }
            )
            state.events.append(
                TwinEvent(
                    "chatter",
                    f"chatter at {top.chatter_frequency_hz:.0f} Hz (energy ratio "
                    f"{top.energy_ratio:.2f}) at {detectors.rpm:.0f} rpm, line {state.line}",
                    state.received_s,
                    {
                        "window_end_s": end_s,
                        "frequency_hz": top.chatter_frequency_hz,
                        "energy_ratio": top.energy_ratio,
                        "spindle_rpm": detectors.rpm,
                        "line": state.line,
                    },
                )
            )

    def run_results(self) -> dict[str, Any]:
        """What the stage found over the run (for the run's summary): each confirmed chatter
        (``window_end_s``, s of the vibration block's clock; ``after_engagement_s``, s after
        the cut's current engagement began, its ae and ap steady; Hz; rpm) and each spindle
        speed change it asked for (``machine_s``, the machine's clock, s; rpm; %)."""
        return {"detections": list(self._detections), "avoidances": list(self._avoidances)}

    def _avoid(self, state: CycleState, segment: RoadmapSegment | None) -> None:
        """Ask for the roadmap's stable speed, the feed scaled to keep the chip load."""
        key = (state.tool, state.line)
        if key in self._avoided:
            return
        self._avoided.add(key)
        state.predicted["chatter_avoided"] = 1.0
        m = state.measured
        spindle = m.get("spindle_override_pct", math.nan)
        feed = m.get("feed_override_pct", math.nan)
        if segment is None or not segment.has_stable_speed or segment.programmed_stable:
            why = (
                "no roadmap segment for this line"
                if segment is None
                else "the roadmap finds no stable speed within the limits"
                if not segment.has_stable_speed
                else "the roadmap calls the programmed speed stable"
            )
            state.events.append(
                TwinEvent(
                    "chatter_unavoidable",
                    f"chatter in line {state.line}: {why}; nothing commanded",
                    state.received_s,
                    {"line": state.line, "tool": state.tool},
                )
            )
            return
        if not (math.isfinite(spindle) and spindle > 0.0 and math.isfinite(feed)):
            return
        low, high = self.spindle_bounds
        target = min(max(100.0 * segment.scheduled_rpm / segment.programmed_rpm, low), high)
        feed_low, feed_high = self.feed_bounds
        feed_target = min(max(feed * target / spindle, feed_low), feed_high)
        values = {
            "chatter_ratio": self._latest[0],
            "chatter_frequency_hz": self._latest[1],
            "chatter_stable_rpm": segment.scheduled_rpm,
            "spindle_override_pct": spindle,
            "feed_override_pct": feed,
        }
        self._avoidances.append(
            {
                "line": state.line,
                "machine_s": state.measured.get("t_s", math.nan),
                "programmed_rpm": segment.programmed_rpm,
                "stable_rpm": segment.scheduled_rpm,
                "spindle_override_pct": target,
            }
        )
        reason = (
            f"chatter at {self._latest[1]:.0f} Hz in line {state.line}: roadmap speed "
            f"{segment.scheduled_rpm:.0f} rpm for {segment.programmed_rpm:.0f} programmed"
        )
        state.commands.append(
            Decision(
                state.time_s,
                RULE,
                "spindle_override",
                target,
                f"{reason}: spindle override {spindle:.0f} -> {target:.1f} %",
                values,
            )
        )
        state.commands.append(
            Decision(
                state.time_s,
                RULE,
                "feed_override",
                feed_target,
                f"{reason}: feed override {feed:.0f} -> {feed_target:.1f} % (chip load kept)",
                values,
            )
        )


class ChatterRequest:
    """The cycle step that sends a :class:`ChatterStage`'s block read early (module notes):
    placed right after the read stage, it lets the machine answer while the physics stages
    run instead of while the cycle waits."""

    name = "chatter_request"

    def __init__(self, stage: ChatterStage) -> None:
        self.stage = stage

    def process(self, state: CycleState) -> CycleState:
        """Send the chatter stage's read; the state passes unchanged."""
        self.stage.request(state)
        return state


def chatter_stage(
    config: MachiningConfig,
    connection: MachineConnection,
    program: str | os.PathLike[str] | None,
    *,
    chatter: ChatterConfig | None = None,
    control: ControlConfig | None = None,
) -> ChatterStage:
    """The chatter stage of a run configuration: its ``[twin.chatter]``, the teeth of its
    ``[[tools]]``, the override bounds of its ``[control]`` and, with ``avoid``, the
    stability roadmap of ``program`` (:func:`cnctwin.dynamics.program_roadmap`: the
    configured blank, the tool's modes of ``stability_file``, the machine's speed limit).

    Parameters
    ----------
    config
        The run configuration (a :class:`~cnctwin.twin.config.RunConfig`).
    connection
        The machine.
    program
        The NC program file the machine runs (``None``: no roadmap, detection only unless
        ``avoid``).
    chatter, control
        Default: the configuration's ``twin.chatter`` and ``control``.

    Raises
    ------
    ConfigError
        With ``avoid`` but no program file; for a stability file that cannot be read.
    """
    from cnctwin.dynamics import load_stability_config, program_roadmap

    c = chatter if chatter is not None else config.twin.chatter  # type: ignore[attr-defined]
    ctl = control if control is not None else config.control  # type: ignore[attr-defined]
    roadmap = None
    if c.avoid:
        if program is None:
            raise ConfigError(
                "twin.chatter.avoid needs the NC program file (twin.program or "
                "virtual.program) for the stability roadmap; give it or set avoid = false"
            )
        assert c.stability_file is not None  # checked by the model
        stability = load_stability_config(c.stability_file)
        roadmap = program_roadmap(program, config, stability, margin=c.margin)
    spindle, feed = ctl.spindle_override, ctl.feed_override
    return ChatterStage(
        c,
        connection,
        {tool.number: tool.flutes for tool in config.tools},
        roadmap,
        (spindle.min_pct, spindle.max_pct),
        (feed.min_pct, feed.max_pct),
    )
