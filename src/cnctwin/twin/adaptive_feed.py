"""Step 9d of the cycle: adaptive feed control (Ward 2021, Eq. 7) and its teach-in mode.

Ward 2021 (Sec. 3.5) closes a loop around the feed override: the simulated cutting force
``F_sim = ||Q_XY(p)||_2 f_act`` (``Q_XY``: force per unit feed at the cutter-workpiece
engagement of the tool position ``p``; ``f_act``: the actual feed) is compared with a
reference ``F_ref(p)``, and the error times an engagement-based gain ``K(p)`` changes the
feed::

    delta_f = K(p) (F_ref(p) - ||Q_XY(p)||_2 f_act)                       (Eq. 7)

Here ``Q(p) = F / f_act`` comes from the twin's own engagement at the tool position (the
dexel cut of the cut stage and the mechanistic forces of the force stage: ``predicted_*``)
or, with ``source = "measured"``, from the measured force or spindle power. The gain is
``K(p) = gain / Q(p)``, so that each command closes the fraction ``gain`` of the gap to the
feed that gives the reference, whatever the engagement (a slot and a light side cut converge
alike). In override terms (``f_act = f_prog ov / 100``)::

    ov_new = ov (1 + gain (F_ref / F - 1))        %

The command goes to the actions stage as a decision of the rule ``adaptive_feed``, so it
passes the safety filter like any rule's (enable switch, bounds, rate limit, one command per
interval) and obeys the lost-machine policy of docs/control.md. The stage asks for no value
outside ``[control.feed_override]`` ``min_pct``/``max_pct`` and commands at most every
``interval_s``, and only a change of at least ``deadband_pct``.

**Entry and exit protection.** Where the value is below ``engagement_threshold`` times the
reference (air, or the thin engagement of entering and leaving the material, where ``Q``
is small and Eq. 7 would raise the feed without bound), the loop is open and the stage
commands ``entry_pct``: the tool enters the material at a reduced feed, and the loop takes
over once the cut is established.

**Teach-in** (``teach_file``), in the manner of the adaptive feed control of commercial
controls: while the file does not exist, the run is a teach-in cut: the stage commands
nothing and learns the mean value (power or force) of each program section (one NC line) in
contact; it writes the file at each section's end. A run with the file present holds each
section's learnt value as its reference.

Names it adds to :attr:`CycleState.predicted`: ``adaptive_feed_reference`` and
``adaptive_feed_value`` (N for ``quantity = "force"``, W for ``"power"``),
``adaptive_feed_target_pct`` (%, the override asked for; NaN while teaching),
``adaptive_feed_engaged`` (1 in closed loop, 0 open) and ``adaptive_feed_teaching``
(1 during a teach-in cut).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from pydantic import Field, ValidationInfo, field_validator, model_validator
from pydantic_core import PydanticCustomError

from cnctwin.config import Section
from cnctwin.control import Decision
from cnctwin.errors import ConfigError
from cnctwin.finite_json import dumps
from cnctwin.thread import RunState
from cnctwin.twin.state import CycleState, TwinEvent

if TYPE_CHECKING:
    from cnctwin.config import MachiningConfig
    from cnctwin.geometry import Cutter, EngagementMap

__all__ = [
    "ADAPTIVE_FEED_PREDICTIONS",
    "AdaptiveFeedConfig",
    "AdaptiveFeedStage",
    "program_engagement_map",
]

#: The names the adaptive feed stage adds (units: see the module).
ADAPTIVE_FEED_PREDICTIONS = (
    "adaptive_feed_reference",
    "adaptive_feed_value",
    "adaptive_feed_target_pct",
    "adaptive_feed_engaged",
    "adaptive_feed_teaching",
)

#: The rule name of the stage's decisions (historian, safety filter).
RULE = "adaptive_feed"

#: A cut area ahead this many times the one at the tool lowers the feed before it arrives.
_AHEAD_MARGIN = 1.1


class AdaptiveFeedConfig(Section):
    """Adaptive feed control (``[twin.adaptive_feed]``; Ward 2021, Eq. 7).

    Attributes
    ----------
    enabled
        Run the controller (off by default). It commands only when ``[control]`` is enabled;
        otherwise its decisions are recorded as blocked.
    quantity
        ``"force"`` (XY resultant, N) or ``"power"`` (spindle power, W).
    source
        ``"predicted"`` (the twin's simulated force or power, Ward's ``F_sim``) or
        ``"measured"`` (``force_x_n``/``force_y_n`` or ``spindle_power_w``, filtered where
        a filter is configured).
    reference
        The reference, N or W (by ``quantity``); exactly one of it and ``teach_file``.
    teach_file
        JSON file of learnt references per program line, relative to the configuration
        file: absent, the run teaches it; present, the run holds it.
    gain
        Fraction of the gap to the reference's feed closed per command, 0 to 1.
    interval_s
        Least time between two commands, s.
    deadband_pct
        Least change of the override worth a command, %.
    entry_pct
        Feed override while the loop is open (air, entry, exit), %.
    engagement_threshold
        The loop closes when the value reaches this fraction of the reference.
    lookahead_mm
        Path length of the engagement map (Ward 2021, Sec. 3.2) looked ahead of the tool, mm;
        0 turns the lookahead off (the loop then only reacts). Needs the program.
    map_step_mm
        Path length between two locations of the engagement map, mm.
    """

    enabled: bool = False
    quantity: Literal["force", "power"] = "force"
    source: Literal["predicted", "measured"] = "predicted"
    reference: float | None = Field(default=None, gt=0.0, le=1e7)
    teach_file: Path | None = None
    gain: float = Field(default=0.5, gt=0.0, le=1.0)
    interval_s: float = Field(default=0.1, ge=0.0, le=60.0)
    deadband_pct: float = Field(default=0.5, ge=0.0, le=50.0)
    entry_pct: float = Field(default=60.0, ge=0.0, le=150.0)
    engagement_threshold: float = Field(default=0.25, gt=0.0, lt=1.0)
    lookahead_mm: float = Field(default=5.0, ge=0.0, le=1000.0)
    map_step_mm: float = Field(default=0.25, ge=0.01, le=10.0)

    @field_validator("teach_file")
    @classmethod
    def _relative_to_file(cls, value: Path | None, info: ValidationInfo) -> Path | None:
        if value is None:
            return None
        base = (info.context or {}).get("base_dir", Path.cwd())
        return (Path(base) / value).resolve()

    @model_validator(mode="after")
    def _one_reference(self) -> AdaptiveFeedConfig:
        if self.enabled and (self.reference is None) == (self.teach_file is None):
            raise PydanticCustomError(
                "adaptive_reference",
                "give exactly one of reference (N or W) and teach_file",
            )
        return self


class AdaptiveFeedStage:
    """The adaptive feed controller in the cycle (see the module).

    Parameters
    ----------
    config
        The ``[twin.adaptive_feed]`` table.
    min_pct, max_pct
        The safety filter's feed override bounds (``[control.feed_override]``), %.
    engagement_map
        The program's engagement map for the lookahead (:func:`program_engagement_map`), or
        ``None``: the loop only reacts, and the loop is open wherever the tool is not
        engaged.

    Attributes
    ----------
    references
        Learnt or loaded reference per program line (N or W); empty with a fixed reference.
    teaching
        The run is a teach-in cut.

    Raises
    ------
    cnctwin.errors.ConfigError
        When the teach-in file exists but is not one this stage wrote.
    """

    per_sample = True
    name = "adaptive_feed"

    def __init__(
        self,
        config: AdaptiveFeedConfig,
        min_pct: float,
        max_pct: float,
        engagement_map: EngagementMap | None = None,
    ) -> None:
        from cnctwin.geometry import MapCursor

        self.config = config
        self.engagement_map = engagement_map
        self._cursor = None
        if engagement_map is not None:
            engagement_map.warm_up()  # before the first cycle, not in it
            self._cursor = MapCursor(engagement_map)
        self._area = None if engagement_map is None else engagement_map.column("cut_area_mm2")
        self.min_pct = min_pct
        self.max_pct = max_pct
        self.references: dict[int, float] = {}
        self.teaching = False
        self._sums: dict[int, tuple[float, int]] = {}
        self._line = -1
        self._last_s = -math.inf
        self._last_pct = math.nan
        self._commands = 0
        self._peak = 0.0  # the largest controlled value while engaged, N or W
        self._lowest_pct = math.inf
        if config.teach_file is not None:
            if config.teach_file.is_file():
                self.references = _load(config.teach_file, config.quantity)
            else:
                self.teaching = True

    def forget(self) -> None:
        """After a gap: the next command is not held back by one from before it, and the
        lookahead searches the whole path again (the tool moved while the twin was blind)."""
        self._last_s = -math.inf
        self._last_pct = math.nan
        if self._cursor is not None:
            self._cursor.reset()

    def _lookahead(self, state: CycleState) -> tuple[float, float] | None:
        """Cut area (mm^2, volume per mm of path) at the tool and the largest within
        ``lookahead_mm`` ahead on the engagement map; ``None`` without a map or match."""
        from cnctwin.geometry import MatchStatus

        if self._cursor is None or self._area is None or state.position_mm is None:
            return None
        match = self._cursor.lookup(state.position_mm)
        if match.status == MatchStatus.OFF_PATH:
            return None
        assert self.engagement_map is not None
        n = math.ceil(self.config.lookahead_mm / self.engagement_map.step_mm)
        ahead = self._area[match.location : match.location + n + 2]
        return match.cut_area_mm2, float(np.max(ahead)) if ahead.size else 0.0

    def _value(self, state: CycleState) -> float:
        """This sample's force (N) or power (W), by ``quantity`` and ``source``."""
        c = self.config
        p = state.predicted
        if c.source == "predicted":
            key = "predicted_force_xy_n" if c.quantity == "force" else "predicted_power_w"
            return p.get(key, math.nan)

        def read(name: str) -> float:
            return state.filtered.get(name, state.measured.get(name, math.nan))

        if c.quantity == "force":
            return math.hypot(read("force_x_n"), read("force_y_n"))
        return read("spindle_power_w")

    def process(self, state: CycleState) -> CycleState:
        """Add the ``adaptive_feed_*`` predictions; append a feed-override decision."""
        if not state.connected:
            return state
        p = state.predicted
        value = self._value(state)
        contact = bool(p.get("contact", 0.0))
        running = state.measured.get("run_state") == RunState.RUNNING
        if state.line != self._line:
            self._close_section(state)
            self._line = state.line
        p["adaptive_feed_value"] = value
        p["adaptive_feed_teaching"] = float(self.teaching)
        if self.teaching:
            if contact and running and math.isfinite(value) and value > 0.0:
                total, n = self._sums.get(state.line, (0.0, 0))
                self._sums[state.line] = (total + value, n + 1)
            p.update(adaptive_feed_target_pct=math.nan, adaptive_feed_engaged=0.0)
            p["adaptive_feed_reference"] = math.nan
            return state
        reference = self._reference(state.line)
        p["adaptive_feed_reference"] = reference
        override = state.measured.get("feed_override_pct", math.nan)
        feeding = running and state.measured.get("feed_mm_min", 0.0) > 0.0
        if not (feeding and math.isfinite(override) and math.isfinite(reference)):
            p.update(adaptive_feed_target_pct=math.nan, adaptive_feed_engaged=0.0)
            return state
        engaged = (
            contact
            and math.isfinite(value)
            and value >= self.config.engagement_threshold * reference
        )
        seen = self._lookahead(state)
        if engaged:
            self._peak = max(self._peak, value)
            target = override * (1.0 + self.config.gain * (reference / value - 1.0))
            why = f"{self.config.quantity} {value:.0f} vs reference {reference:.0f}"
            if seen is not None and seen[1] > seen[0] * _AHEAD_MARGIN:
                # more engagement ahead: never raise; lower as Q(p) will rise (Ward's K(p))
                target = min(target, override * max(seen[0], 0.0) / seen[1] or override)
                why += f", cut area {seen[0]:.1f} -> {seen[1]:.1f} mm^2 ahead"
        elif seen is not None and seen[1] <= 0.0:
            target = min(100.0, self.max_pct)
            why = f"no material within {self.config.lookahead_mm:g} mm ahead"
        else:
            target = self.config.entry_pct
            why = "entry/exit protection: engagement below the threshold"
        target = min(max(target, self.min_pct), self.max_pct)
        p.update(adaptive_feed_target_pct=target, adaptive_feed_engaged=float(engaged))
        self._command(state, target, override, why, value, reference)
        return state

    def run_results(self) -> dict[str, Any]:
        """What the loop did over the run (for the run's summary): the quantity, the fixed
        reference (N or W; ``None`` with per-line references), the largest controlled value
        while engaged (N or W; 0 if never engaged), the feed-override commands and the lowest
        override commanded (%; ``None`` without a command)."""
        return {
            "quantity": self.config.quantity,
            "reference": self.config.reference,
            "peak_engaged": self._peak,
            "commands": self._commands,
            "lowest_override_pct": self._lowest_pct if self._commands else None,
        }

    def _reference(self, line: int) -> float:
        """The reference at this program line, N or W (NaN where none was learnt)."""
        if self.config.reference is not None:
            return self.config.reference
        return self.references.get(line, math.nan)

    def _command(
        self,
        state: CycleState,
        target: float,
        override: float,
        why: str,
        value: float,
        reference: float,
    ) -> None:
        """Append a decision when the interval has passed and the change is worth one."""
        c = self.config
        if state.time_s - self._last_s < c.interval_s:
            return
        last = self._last_pct if math.isfinite(self._last_pct) else override
        if abs(target - last) < c.deadband_pct and abs(target - override) < c.deadband_pct:
            return
        self._last_s, self._last_pct = state.time_s, target
        self._commands += 1
        self._lowest_pct = min(self._lowest_pct, target)
        state.commands.append(
            Decision(
                state.time_s,
                RULE,
                "feed_override",
                target,
                f"adaptive feed: {why}: feed override {override:.0f} -> {target:.0f} %",
                {
                    "adaptive_feed_value": value if math.isfinite(value) else 0.0,
                    "adaptive_feed_reference": reference,
                    "feed_override_pct": override,
                },
            )
        )

    def _close_section(self, state: CycleState) -> None:
        """A teach-in section ended: keep its mean and write the file."""
        if not self.teaching or self._line not in self._sums:
            return
        total, n = self._sums.pop(self._line)
        self.references[self._line] = total / n
        path = self.config.teach_file
        assert path is not None
        document = {
            "quantity": self.config.quantity,
            "sections": {str(k): v for k, v in sorted(self.references.items())},
        }
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(dumps(document) + "\n", encoding="utf-8")
        state.events.append(
            TwinEvent(
                "adaptive_feed_taught",
                f"adaptive feed: line {self._line} learnt {total / n:.1f} "
                f"{'N' if self.config.quantity == 'force' else 'W'} ({n} samples)",
                state.received_s,
                {"line": self._line, "reference": total / n, "samples": n},
            )
        )


def program_engagement_map(
    config: MachiningConfig,
    cutters: Mapping[int, Cutter],
    step_mm: float,
    program: str | os.PathLike[str] | None = None,
    text: str | None = None,
) -> EngagementMap:
    """The engagement map of the program on the configured blank (Ward 2021, Sec. 3.2).

    Parameters
    ----------
    config
        Machine, tools and blank.
    cutters
        The tools by number.
    step_mm
        Path length between two locations, mm.
    program, text
        The NC program (file or text).

    Raises
    ------
    cnctwin.errors.NCError
        On an error in the program.
    """
    from cnctwin.geometry import DexelStock, EngagementMap
    from cnctwin.nc import Interpreter

    interpreter = Interpreter(config.nc_setup())
    segments = (
        interpreter.run_file(Path(program))
        if program is not None
        else interpreter.run_text(text or "", "program")
    )
    stock = DexelStock.box(config.stock.min_mm, config.stock.max_mm, 1.0 / step_mm)
    return EngagementMap.build(segments, stock, cutters, step_mm=step_mm)


def _load(path: Path, quantity: str) -> dict[int, float]:
    """The references per line of a teach-in file (N or W).

    Raises
    ------
    cnctwin.errors.ConfigError
        On a file that is not a teach-in file of this quantity.
    """
    where = f"twin.adaptive_feed.teach_file {path}"
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
        sections = document["sections"]
        learnt = {int(k): float(v) for k, v in sections.items()}
        kind = document["quantity"]
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as err:
        raise ConfigError(
            f"{where}: not a teach-in file ({err}); delete it to teach the program again"
        ) from None
    if kind != quantity:
        raise ConfigError(
            f"{where}: learnt {kind!r}, but quantity = {quantity!r}; delete it to teach again"
        )
    bad = [k for k, v in learnt.items() if not (math.isfinite(v) and v > 0.0)]
    if bad:
        raise ConfigError(f"{where}: line {bad[0]}: reference must be a finite value > 0")
    return learnt
