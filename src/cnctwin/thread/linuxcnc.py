"""LinuxCNC as a machine: a client of linuxcncrsh, LinuxCNC's text protocol over TCP.

linuxcncrsh (``man linuxcncrsh``; LinuxCNC's ``[DISPLAY] DISPLAY = linuxcncrsh`` or a
``loadusr linuxcncrsh`` beside a GUI) answers one line per request. A session says
``hello <connect password> <client> 1.1``, turns the echo off and the acknowledgement of
``set`` requests on (``set verbose on``: every ``set`` answers ``SET <WHAT> ACK`` or ``NAK``).
It reads without asking for control. linuxcncrsh lets one session at a time command (the
last to send ``set enable <password>``; the session that had it is refused from then on), so
the twin asks for control right before each command, and only with an enable password
configured. Without one every write is refused with
:class:`~cnctwin.thread.connection.CommandRejected` before anything is sent.

One :meth:`~MachineConnection.read` asks the ``get`` requests of :data:`READ_REQUESTS` one
after the other, each answer awaited before the next request: linuxcncrsh writes each answer
on its own, and answers to requests sent together wait on the client's delayed TCP
acknowledgement (8 requests sent together took 48 ms, 8 in turn 11 ms: docs/linuxcnc.md).
Mapping to the canonical signals (:data:`cnctwin.thread.signals.SIGNALS`):

- ``ABS_ACT_POS x y z ...`` -> ``x_mm``, ``y_mm``, ``z_mm``, times mm per user unit
  (``USER_LINEAR_UNITS`` read at connection: MM 1, CM 10, INCH 25.4);
- ``FEED_OVERRIDE p`` -> ``feed_override_pct``; ``SPINDLE_OVERRIDE n p`` ->
  ``spindle_override_pct`` (whole percent);
- ``PROGRAM_LINE n`` -> ``program_line``, the line of the file from 1; at the start of a run
  the lines shown while no program ran, and the run's first line, are rejected until it shows
  another (LinuxCNC shows lines of the last run for a while);
- ``PROGRAM_STATUS s`` and ``MODE m`` -> ``run_state`` and ``feed_hold`` (below);
- ``ESTOP ON|OFF`` -> ``emergency_stop`` 1, 0; ``TOOL n`` -> ``tool_number``;
- ``TIME t`` -> :attr:`Reading.source_time_s` (the control's clock, POSIX s), and
  ``heartbeat``, the count of answered reads whose ``TIME`` advanced.

``run_state``: in ``AUTO`` mode ``RUNNING`` 1 (running), ``PAUSED`` 2 (feed hold); otherwise
(idle, or an MDI command or jog running in ``MDI`` or ``MANUAL`` mode) 0 (idle) until the
session has seen a program run, then 4 (finished) when it ended on its own, or 3
(stopped) when this session aborted it, the E-stop is on, or the connection was lost while it
ran (a restarted control has lost the program). LinuxCNC has no heartbeat: ``heartbeat``
counts this session's answered reads whose ``TIME`` (the control's clock) advanced; it stops,
and the twin's watchdog trips, when the control stops answering. linuxcncrsh serves neither
the actual path speed, the spindle speed, loads nor forces: those signals are absent.

Commands (each checked against :data:`~cnctwin.thread.signals.COMMANDS` before it is sent,
then answered by the control's ACK or NAK):

- ``feed_override_pct`` -> ``set feed_override P`` (LinuxCNC takes whole percent: P is the
  value rounded);
- ``spindle_override_pct`` -> ``set spindle_override S P`` (LinuxCNC 2.9's order), and
  ``P S`` when the control refuses that (the order of later versions);
- ``feed_hold`` 1 -> ``set pause``, 0 -> ``set resume``;
- ``stop`` 1 -> ``set abort``; 0 asks nothing (an abort is not latched in LinuxCNC);
- ``emergency_stop`` 1 -> ``set estop on``; 0 is refused: an E-stop is reset at the machine.

Tool wear offsets are refused (linuxcncrsh has no request for them). Nothing is ever sent
twice: a write whose answer is lost raises :class:`ConnectionLost` and is not repeated on the
new connection.

Robustness: an answer that is not a number (``nan``, ``inf``, ``abc``; a ``GET NAK``, which
linuxcncrsh answers now and then on a loaded machine), a count that is not whole, or a value
outside the signal's plausible range goes to :attr:`Reading.rejected`;
an answer line over :data:`MAX_LINE_BYTES`, or answers out of step with the requests, fail the
read like a lost connection (the connection closes and reconnects). Requests that make
linuxcncrsh 2.9 crash (``get spindle`` and ``get spindle_override`` without a spindle number)
are never sent.
"""

from __future__ import annotations

import asyncio
import logging
import math
import os

from cnctwin.errors import ConfigError
from cnctwin.thread.config import ConnectionConfig
from cnctwin.thread.connection import (
    CommandRejected,
    ConnectionLost,
    MachineConnection,
    Reading,
    now_s,
)
from cnctwin.thread.endpoint import split_endpoint
from cnctwin.thread.signals import COMMANDS, RunState, implausible

__all__ = [
    "DEFAULT_PORT",
    "ENABLE_PASSWORD_ENV",
    "MAX_LINE_BYTES",
    "READ_REQUESTS",
    "LinuxCncConnection",
    "parse_endpoint",
]

logger = logging.getLogger(__name__)

#: linuxcncrsh's port when the endpoint names none.
DEFAULT_PORT = 5007
#: The environment variable that gives the enable password when the file does not.
ENABLE_PASSWORD_ENV = "CNCTWIN_LINUXCNC_ENABLE"
#: Longest answer line accepted, bytes (linuxcncrsh's own buffer is 4096).
MAX_LINE_BYTES = 4096
#: The ``get`` requests of one batched read, in the order they are sent.
READ_REQUESTS = (
    "abs_act_pos",
    "feed_override",
    "spindle_override",
    "program_line",
    "program_status",
    "mode",
    "estop",
    "tool",
    "time",
)
_UNIT_FACTORS = {"MM": 1.0, "CM": 10.0, "INCH": 25.4}
_STALE_LINES_KEPT = 16  # lines shown between runs held back at a run's start, newest kept
_SKIPPED_LINES = 8  # lines that answer no request (an echo) tolerated before an answer


def parse_endpoint(endpoint: str) -> tuple[str, int]:
    """Host and port of ``linuxcncrsh://HOST[:PORT]`` (port :data:`DEFAULT_PORT` when absent).

    Raises
    ------
    ConfigError
        One line naming the endpoint and the expected form.
    """
    host, port, _ = split_endpoint(
        endpoint,
        scheme="linuxcncrsh",
        default_port=DEFAULT_PORT,
        what="LinuxCNC",
        form="linuxcncrsh://HOST[:PORT]",
        example="linuxcncrsh://127.0.0.1:5007",
    )
    return host, port


class LinuxCncConnection(MachineConnection):
    """LinuxCNC over linuxcncrsh (module docstring: protocol, mapping, commands).

    Parameters
    ----------
    config
        ``[connection]`` with ``transport = "linuxcnc"``, ``endpoint =
        "linuxcncrsh://HOST:PORT"``, timeouts, backoff and ``[connection.linuxcnc]``.

    Attributes
    ----------
    host, port
        linuxcncrsh's address.
    may_command
        Whether an enable password is configured (the session asks for control with it
        before each command).
    unit_factor
        mm per LinuxCNC user length unit, read at connection.
    sent
        The command lines sent to the control, in order (the newest 1000; the request for
        control before each is not listed).
    """

    def __init__(self, config: ConnectionConfig) -> None:
        self._init_from_config(config, "linuxcnc", "LinuxCNC")
        if config.mapping:
            raise ConfigError(
                "[connection] mapping is not used with transport 'linuxcnc' (its signals are "
                "fixed: docs/linuxcnc.md); remove it"
            )
        self.host, self.port = parse_endpoint(config.endpoint)
        self.endpoint = f"linuxcncrsh://{self.host}:{self.port}"
        self.settings = config.linuxcnc
        self._enable_password = self.settings.enable_password or os.environ.get(ENABLE_PASSWORD_ENV)
        self.may_command = self._enable_password is not None
        self.unit_factor = 1.0
        self.sent: list[str] = []
        self._reader: asyncio.StreamReader | None = None
        self._writer: asyncio.StreamWriter | None = None
        self._buffer = b""
        self._lock = asyncio.Lock()
        self._ran = False  # the program was seen running since it was last idle
        self._stop_sent = False  # this session aborted it
        self._interrupted = False  # the connection was lost while it ran
        self._running = False  # the last reading showed a program running or held
        #: lines shown while no program ran, and the first a run showed: held back at the start
        #: of a run until it shows another (_drop_stale_line)
        self._stale_lines: dict[float, None] = {}
        self._holding = False
        self._beats = 0  # answers whose control clock advanced (the heartbeat)
        self._last_stamp = -math.inf

    # Transport hooks ------------------------------------------------------------------
    async def _open(self) -> None:
        self._reader, self._writer = await asyncio.open_connection(self.host, self.port)
        self._buffer = b""
        s = self.settings
        hello = await self._ask_one(f"hello {s.connect_password} {s.client_name} 1.1")
        if not hello.upper().startswith("HELLO ACK"):
            await self._close()
            raise ConfigError(
                f"linuxcncrsh at {self.host}:{self.port} refused the hello ({hello!r}): "
                "check [connection.linuxcnc] connect_password (linuxcncrsh --connectpw)"
            )
        for line in ("set verbose on", "set echo off"):
            answer = await self._ask_one(line)
            if not answer.upper().endswith(" ACK"):
                raise ConnectionLost(f"linuxcncrsh answered {answer!r} to {line!r}")
        units = (await self._ask_one("get user_linear_units")).split()
        factor = _UNIT_FACTORS.get(units[-1].upper()) if len(units) == 2 else None
        if factor is None:
            await self._close()
            raise ConfigError(
                f"LinuxCNC at {self.host}:{self.port} reports user linear units {units!r}; "
                "valid: MM, CM, INCH ([TRAJ] LINEAR_UNITS)"
            )
        self.unit_factor = factor

    async def _close(self) -> None:
        writer = self._writer
        self._reader = self._writer = None
        if writer is not None:
            writer.close()
            try:
                await asyncio.wait_for(writer.wait_closed(), 0.5)
            except (OSError, TimeoutError):
                pass

    async def _reopen(self) -> str:
        if self._ran:
            self._interrupted = True
        return await super()._reopen()

    async def _read(self) -> Reading:
        answers = await self._ask([self._get_line(name) for name in READ_REQUESTS])
        received = now_s()
        values: dict[str, float] = {}
        rejected: dict[str, str] = {}
        by_name = dict(zip(READ_REQUESTS, answers, strict=True))
        positions = by_name["abs_act_pos"].split()[1:4]
        for i, name in enumerate(("x_mm", "y_mm", "z_mm")):
            text = positions[i] if len(positions) == 3 else ""
            self._put(values, rejected, name, _number(text), "ABS_ACT_POS")
        override = by_name["feed_override"].split()
        self._put(values, rejected, "feed_override_pct", _number(override[-1]), "FEED_OVERRIDE")
        spindle = by_name["spindle_override"].split()
        self._put(
            values, rejected, "spindle_override_pct", _number(spindle[-1]), "SPINDLE_OVERRIDE"
        )
        line = by_name["program_line"].split()
        self._put(values, rejected, "program_line", _count(line[-1]), "PROGRAM_LINE")
        tool = by_name["tool"].split()
        self._put(values, rejected, "tool_number", _count(tool[-1]), "TOOL")
        estop = by_name["estop"].split()[-1].upper()
        if estop in ("ON", "OFF"):
            values["emergency_stop"] = float(estop == "ON")
        else:
            rejected["emergency_stop"] = f"ESTOP {estop!r} is neither ON nor OFF"
        status = by_name["program_status"].split()[-1].upper()
        auto = by_name["mode"].split()[-1].upper() == "AUTO"
        run_state = self._run_state(status, auto, values.get("emergency_stop") == 1.0)
        if run_state is None:
            rejected["run_state"] = f"PROGRAM_STATUS {status!r}; valid: IDLE, RUNNING, PAUSED"
        else:
            values["run_state"] = float(run_state)
            values["feed_hold"] = float(status == "PAUSED")
        self._drop_stale_line(run_state in (RunState.RUNNING, RunState.FEED_HOLD), values, rejected)
        stamp = _number(by_name["time"].split()[-1])
        if math.isfinite(stamp) and stamp > self._last_stamp:
            self._last_stamp = stamp
            self._beats += 1
        values["heartbeat"] = float(self._beats)
        return Reading(
            values=values,
            received_s=received,
            rejected=rejected,
            source_time_s=stamp if math.isfinite(stamp) and stamp > 0 else None,
        )

    async def _write(self, name: str, value: float) -> None:
        spec = COMMANDS.get(name)
        if spec is None:
            raise CommandRejected(f"{name!r} is no command; valid: {', '.join(COMMANDS)}")
        if not math.isfinite(value) or not spec.low <= value <= spec.high:  # type: ignore[operator]
            raise CommandRejected(
                f"command {name}={value!r} refused before sending: valid {spec.low:g}.."
                f"{spec.high:g} {spec.unit}"
            )
        if self._enable_password is None:
            raise CommandRejected(
                f"command {name}={value:g} refused: this LinuxCNC session is not enabled to "
                f"command (set [connection.linuxcnc] enable_password or {ENABLE_PASSWORD_ENV})"
            )
        if spec.kind == "bool" and value not in (0.0, 1.0):
            raise CommandRejected(f"command {name}={value!r} refused: valid 0 or 1")
        lines = self._command_lines(name, value)
        if not lines:
            return
        answer = await self._ask_one(f"set enable {self._enable_password}")
        if answer.upper() != "SET ENABLE ACK":
            raise CommandRejected(
                f"command {name}={value:g} not sent: linuxcncrsh at {self.host}:{self.port} "
                f"refused the enable password ({answer!r}); check [connection.linuxcnc] "
                f"enable_password or {ENABLE_PASSWORD_ENV} (linuxcncrsh --enablepw)"
            )
        for i, line in enumerate(lines):
            self.sent.append(line)
            del self.sent[:-1000]
            answer = await self._ask_one(line)
            if answer.upper().endswith(" ACK"):
                if name == "stop":
                    self._stop_sent = True
                return
            if i + 1 == len(lines):
                raise CommandRejected(
                    f"LinuxCNC refused {line!r} ({answer!r}) for {name}={value:g}: the machine "
                    "must be out of E-stop, on, and (for pause/abort) running a program"
                )

    # Helpers --------------------------------------------------------------------------
    def _get_line(self, name: str) -> str:
        if name == "spindle_override":
            return f"get spindle_override {self.settings.spindle}"
        return f"get {name}"

    def _command_lines(self, name: str, value: float) -> list[str]:
        """The request lines of one command, tried in turn until one is acknowledged."""
        if name == "feed_override_pct":
            return [f"set feed_override {round(value)}"]
        if name == "spindle_override_pct":
            n, pct = self.settings.spindle, round(value)
            return [f"set spindle_override {n} {pct}", f"set spindle_override {pct} {n}"]
        if name == "feed_hold":
            return ["set pause" if value else "set resume"]
        if name == "stop":
            return ["set abort"] if value else []
        if name == "emergency_stop" and value:
            return ["set estop on"]
        if name == "emergency_stop":
            raise CommandRejected(
                "emergency_stop=0 refused: LinuxCNC's E-stop is reset at the machine"
            )
        raise CommandRejected(f"command {name} refused: linuxcncrsh has no request for it")

    def _drop_stale_line(
        self, running: bool, values: dict[str, float], rejected: dict[str, str]
    ) -> None:
        """At the start of a run LinuxCNC 2.9 reports lines of the last run for a while: where
        it ended, or where its interpreter had read to (measured: a run after an abort at line
        20 showed 0, then 40, the line the last run's interpreter had read to, and only then
        its own first line, 15). Every line shown while no program ran, and the first line a
        run shows, are held back at the start of a run until it shows another."""
        line = values.get("program_line")
        if not running:
            self._running = self._holding = False
            if line is not None:
                self._stale_lines.pop(line, None)
                self._stale_lines[line] = None  # the newest last
                while len(self._stale_lines) > _STALE_LINES_KEPT:
                    del self._stale_lines[next(iter(self._stale_lines))]
            return
        if not self._running:  # the run begins
            self._running = self._holding = True
            if line is not None:
                self._stale_lines[line] = None
        if not self._holding or line is None:
            return
        if line in self._stale_lines:
            del values["program_line"]
            rejected["program_line"] = f"line {line:g}, shown before this run began, may be stale"
        else:
            self._holding = False
            self._stale_lines.clear()

    def _run_state(self, status: str, auto: bool, estop: bool) -> RunState | None:
        if status not in ("IDLE", "RUNNING", "PAUSED"):
            return None
        if auto and status == "RUNNING":
            self._ran, self._stop_sent, self._interrupted = True, False, False
            return RunState.RUNNING
        if auto and status == "PAUSED":
            self._ran = True
            return RunState.FEED_HOLD
        # idle, or an MDI command or a jog (running outside AUTO mode): no program runs
        if not self._ran:
            return RunState.IDLE
        if self._stop_sent or estop or self._interrupted:
            return RunState.STOPPED
        return RunState.FINISHED

    def _put(
        self,
        values: dict[str, float],
        rejected: dict[str, str],
        name: str,
        value: float,
        source: str,
    ) -> None:
        if name.endswith("_mm"):
            value *= self.unit_factor
        why = implausible(name, value)
        if why is None:
            values[name] = value
        else:
            rejected[name] = f"{source}: {why}"
            logger.warning("LinuxCNC %s: %s rejected: %s", source, name, why)

    async def _ask_one(self, line: str) -> str:
        return (await self._ask([line]))[0]

    async def _ask(self, lines: list[str]) -> list[str]:
        """Ask ``lines`` one after the other; their answers, in order."""
        answers = []
        async with self._lock:
            for line in lines:
                writer = self._writer
                if writer is None:
                    raise ConnectionLost(f"linuxcncrsh at {self.host}:{self.port} closed")
                writer.write(f"{line}\r\n".encode())
                await writer.drain()
                answers.append(await self._answer(line))
        return answers

    async def _answer(self, request: str) -> str:
        """The answer line to ``request``, skipping its echo."""
        words = request.split()
        verb, what = words[0].upper(), words[1].upper() if len(words) > 1 else ""
        for _ in range(_SKIPPED_LINES):
            answer = await self._line()
            upper = answer.upper()
            if upper == request.upper():
                continue  # the echo of the request
            if verb == "HELLO" and upper.startswith("HELLO"):
                return answer
            if verb == "GET" and (upper.split()[0] == what or upper.startswith("GET")):
                return answer  # a refusal (GET NAK) reads as garbage: the signal is rejected
            if verb == "SET" and upper.startswith(("SET ", "SET\t")):
                return answer
            logger.debug("linuxcncrsh line %r answers no request (%r)", answer, request)
        raise ConnectionLost(f"linuxcncrsh answered {request!r} out of step")

    async def _line(self) -> str:
        """The next non-empty line (linuxcncrsh ends lines with CR LF, or LF CR after a
        ``set``); at most :data:`MAX_LINE_BYTES`."""
        reader = self._reader
        if reader is None:
            raise ConnectionLost("linuxcncrsh connection closed")
        while True:
            self._buffer = self._buffer.lstrip(b"\r\n")
            cut = min(
                (i for i in (self._buffer.find(b"\r"), self._buffer.find(b"\n")) if i >= 0),
                default=-1,
            )
            if cut >= 0:
                raw, self._buffer = self._buffer[:cut], self._buffer[cut + 1 :]
                try:
                    return raw.decode("ascii").strip()
                except UnicodeDecodeError:
                    raise ConnectionLost(
                        f"linuxcncrsh sent a line that is not ASCII: {raw[:60]!r}"
                    ) from None
            if len(self._buffer) > MAX_LINE_BYTES:
                raise ConnectionLost(f"linuxcncrsh sent a line over {MAX_LINE_BYTES} bytes")
            chunk = await reader.read(MAX_LINE_BYTES)
            if not chunk:
                raise ConnectionLost(
                    f"linuxcncrsh at {self.host}:{self.port} closed the connection"
                )
            self._buffer += chunk


def _number(text: str) -> float:
    """A decimal answer as a float; NaN for text that is none (rejected by the caller)."""
    try:
        return float(text)
    except ValueError:
        return math.nan


def _count(text: str) -> float:
    """A whole-number answer; NaN when it is not one."""
    value = _number(text)
    return value if math.isfinite(value) and value == int(value) else math.nan
