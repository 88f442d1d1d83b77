"""Writing a tool wear offset to the machine: the safety filter, the write, the read-back.

A wear-offset correction (Bolyn 2023's lathe twin, :mod:`cnctwin.wear.compensation`, after a
measured part) is an explicit step, not a rule's reflex: :func:`write_tool_offset` reads the
machine, passes the new offset through :meth:`cnctwin.control.SafetyFilter.check_offset`
(control enabled, the tool active, one step and the total bounded in mm), writes it, and reads
it back until the machine shows it. With ``[control] enabled = false`` nothing connects to the
machine and the decision is returned as blocked. A read-only transport (MTConnect) refuses the
write; a lost connection leaves it undone. Either way the result says so in one line, and the
decision keeps its reason.

Axes (the dimension a correction is measured on):

- ``"diameter"``: a lathe's X on a diameter; the radius wear offset (one side) moves by half
  the correction;
- ``"radius"``: the radius wear offset moves by the correction;
- ``"length"``: the length wear offset (Z) moves by the correction.

A correction is the signed change of the produced dimension (positive: larger), as Bolyn's
twin gives it; for an external feature that is the same sign as the wear offset, for an
internal one (a bore) the opposite (``internal=True``).
"""

from __future__ import annotations

import asyncio
import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from cnctwin.control import OFFSET_COMMANDS, Decision, SafetyFilter, Verdict
from cnctwin.errors import InputError
from cnctwin.thread import CommandRejected, ConnectionLost, MachineConnection
from cnctwin.twin.config import RunConfig
from cnctwin.twin.session import open_connection

__all__ = ["OFFSET_AXES", "OffsetAxis", "OffsetWrite", "apply_correction", "write_tool_offset"]

logger = logging.getLogger(__name__)

OffsetAxis = Literal["diameter", "radius", "length"]

#: Axis -> (wear-offset command, wear offset per unit of the dimension's correction).
OFFSET_AXES: dict[str, tuple[str, float]] = {
    "diameter": ("tool_radius_wear_mm", 0.5),
    "radius": ("tool_radius_wear_mm", 1.0),
    "length": ("tool_length_wear_mm", 1.0),
}
assert all(command in OFFSET_COMMANDS for command, _ in OFFSET_AXES.values())

#: Rule name of a wear-offset decision made from a measured part.
OFFSET_RULE = "wear_compensation"


@dataclass(frozen=True, slots=True)
class OffsetWrite:
    """What became of one wear-offset correction.

    Attributes
    ----------
    verdict
        The safety filter's verdict (its decision carries the reason).
    before_mm
        The machine's wear offset before the write, mm (``None`` when not read).
    readback_mm
        The machine's wear offset after the write, mm (``None`` when not written or not read).
    confirmed
        Whether the read-back shows the value written.
    error
        Why a passed write was not carried out (refused, connection lost), else empty.
    """

    verdict: Verdict
    before_mm: float | None
    readback_mm: float | None
    confirmed: bool
    error: str = ""

    def to_dict(self) -> dict[str, object]:
        """JSON-ready summary (mm; ``None`` where unknown)."""
        decision = self.verdict.decision
        return {
            "command": self.verdict.command,
            "value_mm": decision.value,
            "outcome": self.verdict.outcome,
            "note": self.verdict.note,
            "reason": decision.reason,
            "before_mm": self.before_mm,
            "readback_mm": self.readback_mm,
            "confirmed": self.confirmed,
            "error": self.error,
        }


async def write_tool_offset(
    connection: MachineConnection | None,
    safety: SafetyFilter,
    *,
    tool: int,
    axis: OffsetAxis,
    correction_mm: float,
    reason: str,
    internal: bool = False,
    readback_timeout_s: float = 2.0,
) -> OffsetWrite:
    """Move tool ``tool``'s wear offset by a correction of the dimension, with read-back.

    Parameters
    ----------
    connection
        The machine, connected; may be ``None`` only when control is disabled.
    safety
        The safety filter (its ``[control]`` table enables writing and bounds the offset).
    tool
        Tool number (the machine's active tool, else the write is blocked).
    axis
        ``"diameter"``, ``"radius"`` or ``"length"`` (see the module notes).
    correction_mm
        Signed change of the produced dimension, mm.
    reason
        Why, one line (recorded with the decision).
    internal
        The dimension is internal (a bore): the offset moves against the correction.
    readback_timeout_s
        How long to poll the machine for the read-back, s.

    Raises
    ------
    InputError
        On an unknown axis or a correction that is not finite.
    """
    if axis not in OFFSET_AXES:
        raise InputError(f"offset axis {axis!r}; valid: {', '.join(OFFSET_AXES)}")
    if not math.isfinite(correction_mm):
        raise InputError(f"correction {correction_mm!r} mm is not finite")
    command, per_unit = OFFSET_AXES[axis]
    step = correction_mm * per_unit * (-1.0 if internal else 1.0)
    now = time.monotonic()
    if not safety.config.enabled or connection is None:
        decision = Decision(now, OFFSET_RULE, "tool_offset", None, reason)
        verdict = safety.check_offset(decision, command, tool, {})
        return OffsetWrite(verdict, None, None, False)
    try:
        reading = await connection.read()
    except ConnectionLost as err:
        decision = Decision(now, OFFSET_RULE, "tool_offset", None, reason)
        verdict = safety.check_offset(decision, command, tool, {})
        return OffsetWrite(verdict, None, None, False, f"machine not read: {err}")
    values = reading.values
    before = values.get(command)
    target = (before + step) if before is not None else None
    decision = Decision(
        now, OFFSET_RULE, "tool_offset", target, f"{reason} (T{tool} {axis} {correction_mm:+g} mm)"
    )
    verdict = safety.check_offset(decision, command, tool, values)
    if not verdict.send or verdict.value is None:
        logger.info("wear offset %s not written: %s", command, verdict.note)
        return OffsetWrite(verdict, before, None, False)
    value = verdict.value
    try:
        await connection.write(command, value)
    except (ConnectionLost, CommandRejected) as err:
        logger.warning("wear offset %s=%g not carried out: %s", command, value, err)
        return OffsetWrite(verdict, before, None, False, str(err))
    deadline = time.monotonic() + readback_timeout_s
    readback: float | None = None
    while True:
        try:
            readback = await connection.read_signal(command)
        except ConnectionLost as err:
            return OffsetWrite(verdict, before, None, False, f"read-back lost: {err}")
        if abs(readback - value) <= 1e-4:
            safety.observe({command: readback})
            return OffsetWrite(verdict, before, readback, True)
        if time.monotonic() >= deadline:
            break
        await asyncio.sleep(0.01)
    logger.warning("wear offset %s=%g not confirmed by read-back (%r)", command, value, readback)
    return OffsetWrite(verdict, before, readback, False, "not confirmed by read-back")


def apply_correction(
    config: RunConfig,
    *,
    tool: int,
    axis: OffsetAxis,
    correction_mm: float,
    reason: str,
    internal: bool = False,
    base_dir: Path | None = None,
) -> OffsetWrite:
    """Connect to ``[connection]`` and write one correction (:func:`write_tool_offset`).

    With ``[control] enabled = false`` nothing connects: the result is the blocked decision.
    A machine that does not answer gives a result with ``error`` set (nothing written).

    Parameters
    ----------
    config
        A twin configuration: its ``[connection]`` and ``[control]`` tables are used.
    tool, axis, correction_mm, reason, internal
        As :func:`write_tool_offset` (mm).
    base_dir
        Folder of the configuration file (relative certificate paths).
    """
    if axis not in OFFSET_AXES:
        raise InputError(f"offset axis {axis!r}; valid: {', '.join(OFFSET_AXES)}")
    command = OFFSET_AXES[axis][0]
    safety = SafetyFilter(config.control)

    async def run() -> OffsetWrite:
        if not config.control.enabled:
            return await write_tool_offset(
                None, safety, tool=tool, axis=axis, correction_mm=correction_mm,
                reason=reason, internal=internal,
            )  # fmt: skip
        connection = open_connection(config.connection, base_dir)
        try:
            await connection.connect()
        except ConnectionLost as err:
            decision = Decision(time.monotonic(), OFFSET_RULE, "tool_offset", None, reason)
            verdict = Verdict(decision, "blocked", command, None, "machine not reached")
            return OffsetWrite(verdict, None, None, False, str(err))
        try:
            return await write_tool_offset(
                connection, safety, tool=tool, axis=axis, correction_mm=correction_mm,
                reason=reason, internal=internal,
            )  # fmt: skip
        finally:
            await connection.close()

    result = asyncio.run(run())
    verdict = result.verdict
    logger.info(
        "decision %s: tool_offset T%d %s -> %s%s (%s)%s",
        verdict.decision.rule, tool, command, verdict.outcome,
        f" [{verdict.note}]" if verdict.note else "", verdict.decision.reason,
        f" [{result.error}]" if result.error else "",
    )  # fmt: skip
    return result
