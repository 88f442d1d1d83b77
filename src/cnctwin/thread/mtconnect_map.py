"""Which MTConnect data item feeds which canonical signal, and in what unit.

A signal is found in an agent's probe by a *selector* (docs/mtconnect.md):

* ``TYPE[:SUBTYPE][@COMPONENT]`` -- the first data item of that type (and sub-type) whose
  component is named ``COMPONENT`` (``POSITION:ACTUAL@X`` is the X axis' actual position);
* ``id=DATA_ITEM`` -- the data item of that id or name (``id=Xabs``).

:data:`DEFAULT_MAP` gives each signal a list of selectors tried in turn (the standard's
current type first, the deprecated one after it, e.g. ``ROTARY_VELOCITY`` then
``SPINDLE_SPEED``); ``[connection] mapping`` replaces a signal's list with one selector, or
removes the signal with ``"none"``.

Values arrive in the data item's ``units`` (the MTConnect Standard, Part 2, "Device
Information Model", gives each type its units: POSITION in MILLIMETER, PATH_FEEDRATE in
MILLIMETER/SECOND, ROTARY_VELOCITY in REVOLUTION/MINUTE, LOAD and overrides in PERCENT) and
are converted to the signal's unit by :data:`UNIT_FACTORS`: feed rate x 60 (mm/s -> mm/min),
the others x 1. The event enumerations EXECUTION and EMERGENCY_STOP map to
:class:`~cnctwin.thread.signals.RunState` codes and 0/1 by :data:`EXECUTION_STATES` and
:data:`EMERGENCY_STOP_STATES`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from cnctwin.errors import ConfigError, DataError
from cnctwin.thread.mtconnect_documents import DataItem, Devices, number
from cnctwin.thread.signals import SIGNALS, RunState

__all__ = [
    "DEFAULT_MAP",
    "DEFAULT_UNITS",
    "EMERGENCY_STOP_STATES",
    "EXECUTION_STATES",
    "RUN_STATE_EXECUTION",
    "UNIT_FACTORS",
    "MappedItem",
    "Selector",
    "convert",
    "parse_selector",
    "resolve_map",
]

#: Canonical signal -> selectors tried in turn (the first that matches a data item wins).
DEFAULT_MAP: dict[str, tuple[str, ...]] = {
    "x_mm": ("POSITION:ACTUAL@X", "POSITION@X"),
    "y_mm": ("POSITION:ACTUAL@Y", "POSITION@Y"),
    "z_mm": ("POSITION:ACTUAL@Z", "POSITION@Z"),
    "feed_mm_min": ("PATH_FEEDRATE:ACTUAL", "PATH_FEEDRATE"),
    "spindle_rpm": ("ROTARY_VELOCITY:ACTUAL", "SPINDLE_SPEED:ACTUAL", "SPINDLE_SPEED"),
    "spindle_rpm_command": ("ROTARY_VELOCITY:COMMANDED", "SPINDLE_SPEED:COMMANDED"),
    "spindle_torque_nm": ("TORQUE@C", "TORQUE@S"),
    "spindle_current_a": ("AMPERAGE@C", "AMPERAGE@S"),
    "spindle_power_w": ("WATTAGE@C", "WATTAGE@S"),
    "load_x_pct": ("LOAD@X",),
    "load_y_pct": ("LOAD@Y",),
    "load_z_pct": ("LOAD@Z",),
    "program_line": ("LINE_NUMBER:ABSOLUTE", "LINE_NUMBER"),
    "tool_number": ("TOOL_NUMBER",),
    "run_state": ("EXECUTION",),
    "emergency_stop": ("EMERGENCY_STOP",),
    "feed_override_pct": ("PATH_FEEDRATE_OVERRIDE:PROGRAMMED", "PATH_FEEDRATE_OVERRIDE"),
    "spindle_override_pct": ("ROTARY_VELOCITY_OVERRIDE", "SPINDLE_SPEED_OVERRIDE"),
}

#: MTConnect units -> (canonical unit, factor): canonical value = MTConnect value x factor.
UNIT_FACTORS: dict[str, tuple[str, float]] = {
    "MILLIMETER": ("mm", 1.0),
    "MILLIMETER/SECOND": ("mm/min", 60.0),
    "MILLIMETER/MINUTE": ("mm/min", 1.0),  # not a standard unit, but adapters send it natively
    "REVOLUTION/MINUTE": ("rpm", 1.0),
    "PERCENT": ("%", 1.0),
    "NEWTON": ("N", 1.0),
    "NEWTON_METER": ("N m", 1.0),
    "AMPERE": ("A", 1.0),
    "WATT": ("W", 1.0),
    "SECOND": ("s", 1.0),
    "COUNT": ("1", 1.0),
}

#: Units a data item type reports in when its probe does not say (MTConnect Part 2).
DEFAULT_UNITS: dict[str, str] = {
    "POSITION": "MILLIMETER",
    "PATH_FEEDRATE": "MILLIMETER/SECOND",
    "ROTARY_VELOCITY": "REVOLUTION/MINUTE",
    "SPINDLE_SPEED": "REVOLUTION/MINUTE",
    "LOAD": "PERCENT",
    "TORQUE": "NEWTON_METER",
    "AMPERAGE": "AMPERE",
    "WATTAGE": "WATT",
    "PATH_FEEDRATE_OVERRIDE": "PERCENT",
    "ROTARY_VELOCITY_OVERRIDE": "PERCENT",
    "SPINDLE_SPEED_OVERRIDE": "PERCENT",
}

#: EXECUTION values -> :class:`RunState` code.
EXECUTION_STATES: dict[str, RunState] = {
    "READY": RunState.IDLE,
    "ACTIVE": RunState.RUNNING,
    "FEED_HOLD": RunState.FEED_HOLD,
    "INTERRUPTED": RunState.FEED_HOLD,
    "WAIT": RunState.FEED_HOLD,
    "STOPPED": RunState.STOPPED,
    "OPTIONAL_STOP": RunState.STOPPED,
    "PROGRAM_STOPPED": RunState.STOPPED,
    "PROGRAM_OPTIONAL_STOP": RunState.STOPPED,
    "PROGRAM_COMPLETED": RunState.FINISHED,
}

#: :class:`RunState` -> the EXECUTION value an agent reports (the virtual machine's agent; a
#: FAULT is reported as STOPPED with a SYSTEM condition at FAULT).
RUN_STATE_EXECUTION: dict[RunState, str] = {
    RunState.IDLE: "READY",
    RunState.RUNNING: "ACTIVE",
    RunState.FEED_HOLD: "FEED_HOLD",
    RunState.STOPPED: "STOPPED",
    RunState.FINISHED: "PROGRAM_COMPLETED",
    RunState.FAULT: "STOPPED",
}

#: EMERGENCY_STOP values -> the ``emergency_stop`` flag.
EMERGENCY_STOP_STATES: dict[str, float] = {"ARMED": 0.0, "TRIGGERED": 1.0}

_ENUMS: dict[str, Mapping[str, float]] = {
    "EXECUTION": {k: float(v) for k, v in EXECUTION_STATES.items()},
    "EMERGENCY_STOP": EMERGENCY_STOP_STATES,
}


@dataclass(frozen=True)
class Selector:
    """A parsed selector: by ``type``/``sub_type``/``component``, or by ``key`` (id or name)."""

    text: str
    type: str | None = None
    sub_type: str | None = None
    component: str | None = None
    key: str | None = None

    def matches(self, item: DataItem) -> bool:
        """Whether ``item`` is the data item this selector names."""
        if self.key is not None:
            return item.id == self.key or item.name == self.key
        return (
            item.type == self.type
            and (self.sub_type is None or item.sub_type == self.sub_type)
            and (self.component is None or item.component_name == self.component)
        )


def parse_selector(text: str, signal: str) -> Selector:
    """Parse ``TYPE[:SUBTYPE][@COMPONENT]`` or ``id=DATA_ITEM``.

    Raises
    ------
    ConfigError
        A malformed selector, naming the signal.
    """
    raw = text.strip()
    if raw.startswith("id="):
        key = raw[3:].strip()
        if key:
            return Selector(raw, key=key)
    else:
        head, _, component = raw.partition("@")
        kind, _, sub = head.partition(":")
        if kind and kind.replace("_", "").isalnum() and kind.upper() == kind:
            return Selector(raw, kind, sub or None, component or None)
    raise ConfigError(
        f"[connection] mapping of {signal!r}: selector {text!r}; valid: TYPE[:SUBTYPE]"
        "[@COMPONENT] (e.g. POSITION:ACTUAL@X) or id=DATA_ITEM_ID"
    )


@dataclass(frozen=True)
class MappedItem:
    """The data item that feeds one signal, and how its value converts.

    Attributes
    ----------
    signal
        Canonical name.
    item
        The data item.
    selector
        The selector that found it.
    factor
        Canonical value = MTConnect value x factor (``None`` for an enumeration).
    """

    signal: str
    item: DataItem
    selector: str
    factor: float | None


def _factor(signal: str, item: DataItem) -> float | None:
    """Unit factor of ``item`` for ``signal``; raise ConfigError when the units do not fit."""
    if item.type in _ENUMS:
        return None
    unit = SIGNALS[signal].unit
    if unit == "1" and item.units is None:
        return 1.0
    units = item.units or DEFAULT_UNITS.get(item.type)
    target = UNIT_FACTORS.get(units or "")
    if target is None or target[0] != unit:
        raise ConfigError(
            f"MTConnect data item {item.id!r} ({item.type}, units {units}) cannot feed "
            f"{signal!r} in {unit}"
        )
    return target[1]


def resolve_map(devices: Devices, mapping: Mapping[str, str]) -> dict[str, MappedItem]:
    """The data item of each signal in an agent's probe.

    Parameters
    ----------
    devices
        The probe.
    mapping
        ``[connection] mapping``: signal -> selector (or ``"none"``), overriding
        :data:`DEFAULT_MAP`.

    Returns
    -------
    dict
        Signal -> mapped item, for the signals whose selector matched a data item with
        fitting units; a default selector that matches nothing is left out.

    Raises
    ------
    ConfigError
        An unknown signal, a malformed selector, or a selector of ``mapping`` that matches
        no data item or one whose units do not fit.
    """
    selectors: dict[str, tuple[Selector, ...]] = {
        signal: tuple(parse_selector(s, signal) for s in texts)
        for signal, texts in DEFAULT_MAP.items()
    }
    for signal, text in mapping.items():
        if signal not in SIGNALS:
            raise ConfigError(
                f"[connection] mapping names unknown signal {signal!r} "
                f"(valid: {', '.join(SIGNALS)})"
            )
        if text.strip().lower() == "none":
            selectors.pop(signal, None)
        else:
            selectors[signal] = (parse_selector(text, signal),)
    resolved: dict[str, MappedItem] = {}
    for signal, options in selectors.items():
        for selector in options:
            item = next((i for i in devices.data_items if selector.matches(i)), None)
            if item is None:
                continue
            try:
                factor = _factor(signal, item)
            except ConfigError:
                if signal in mapping:
                    raise
                continue
            resolved[signal] = MappedItem(signal, item, selector.text, factor)
            break
        else:
            if signal in mapping:
                raise ConfigError(
                    f"[connection] mapping of {signal!r}: {mapping[signal]!r} matches no data "
                    f"item of the agent's probe (devices: {', '.join(devices.devices)})"
                )
    return resolved


def convert(mapped: MappedItem, text: str) -> float:
    """The canonical value of an observation's text.

    Raises
    ------
    DataError
        ``UNAVAILABLE``, a value that is not a finite number, an unknown enumeration value,
        or a value outside the signal's plausible range; the message names the data item.
    """
    item = mapped.item
    if mapped.factor is None:
        table = _ENUMS[item.type]
        if text not in table:
            raise DataError(
                f"{item.id}: {item.type} value {text[:40]!r}; valid: {', '.join(table)}"
            )
        return table[text]
    try:
        value = number(text) * mapped.factor
    except DataError as err:
        raise DataError(f"{item.id}: {err}") from None
    spec = SIGNALS[mapped.signal]
    if spec.kind == "int" and value != round(value):
        raise DataError(f"{item.id}: {text!r} is not a whole number")
    if (spec.low is not None and value < spec.low) or (spec.high is not None and value > spec.high):
        raise DataError(f"{item.id}: {value:g} {spec.unit} outside the plausible range")
    return value
