"""A machine connection to an in-process virtual machine: the twin's fast path for tests.

:class:`LocalConnection` speaks the same :class:`~cnctwin.thread.MachineConnection` interface
as the OPC UA and Modbus clients, but reads :meth:`snapshot` and applies :meth:`command` of a
machine object in the same process, without a network. In *lockstep* mode each read first
advances the machine by a fixed step of machine time, so a test runs as fast as the CPU
allows and gives the same result every time; otherwise something else (a
:class:`~cnctwin.virtual.MachineClock`) advances the machine in real or scaled time.
"""

from __future__ import annotations

import math
from collections.abc import Awaitable
from typing import Protocol, TypeVar

from cnctwin.errors import ConfigError, DataError
from cnctwin.thread import (
    COMMANDS,
    SIGNALS,
    ConnectionLost,
    MachineConnection,
    Reading,
    SampleBlock,
    now_s,
)

__all__ = ["LocalConnection", "MachineSource"]

_T = TypeVar("_T")


class MachineSource(Protocol):
    """What a local connection needs of a machine (a VirtualMachine satisfies it)."""

    def snapshot(self) -> dict[str, float]:
        """Current value of every signal, by canonical name."""
        ...

    def command(self, name: str, value: float) -> None:
        """Apply one command at once."""
        ...

    def step(self, dt_s: float) -> None:
        """Advance machine time by ``dt_s`` s."""
        ...


class LocalConnection(MachineConnection):
    """A :class:`MachineConnection` to a machine object in this process.

    Parameters
    ----------
    machine
        The machine (``snapshot()``, ``command(name, value)``, ``step(dt_s)``).
    step_s
        Lockstep: advance the machine by this much machine time (s) before every read;
        ``None`` (default) reads whatever state the machine is in.
    tick_s
        Lockstep: the machine's own step, s; ``step_s`` is split into ticks of about this
        length (``None``: one step of ``step_s``).
    timeout_s
        Request timeout, s (reads here never block; kept for the interface).

    Notes
    -----
    :meth:`drop` and :meth:`restore` simulate a lost and a restored link for tests: while
    dropped, every request fails with :class:`ConnectionLost` and reconnection attempts are
    refused.
    """

    def __init__(
        self,
        machine: MachineSource,
        *,
        step_s: float | None = None,
        tick_s: float | None = None,
        timeout_s: float = 2.0,
    ) -> None:
        super().__init__(timeout_s=timeout_s)
        self.machine = machine
        self.step_s = step_s
        self._ticks = 1 if step_s is None or tick_s is None else max(1, round(step_s / tick_s))
        self._up = True
        self.endpoint = "local://"

    def drop(self) -> None:
        """Cut the link: requests fail until :meth:`restore`."""
        self._up = False

    def restore(self) -> None:
        """Mend the link: the next reconnection attempt succeeds."""
        self._up = True

    async def _open(self) -> None:
        if not self._up:
            raise ConnectionLost("local link is down")

    async def _close(self) -> None:
        return None

    async def _read(self) -> Reading:
        if not self._up:
            raise ConnectionLost("local link is down")
        if self.step_s is not None:
            dt = self.step_s / self._ticks
            for _ in range(self._ticks):
                self.machine.step(dt)
        values: dict[str, float] = {}
        rejected: dict[str, str] = {}
        for name, raw in self.machine.snapshot().items():
            if name not in SIGNALS:
                continue
            try:
                value = float(raw)
            except (TypeError, ValueError):
                rejected[name] = f"not a number: {raw!r}"
                continue
            if not math.isfinite(value):
                rejected[name] = f"not finite: {value!r}"
                continue
            values[name] = value
        return Reading(values, now_s(), rejected)

    def _start_read_block(self, name: str, since: int) -> Awaitable[SampleBlock]:
        """The block taken now; the awaitable only hands it over."""
        if not self._up:
            raise ConnectionLost("local link is down")
        block = getattr(self.machine, "block", None)
        if block is None:
            raise DataError(f"block {name!r}: the machine serves no sample blocks")
        result: SampleBlock = block(name, since)
        return _answer(result)

    async def _write(self, name: str, value: float) -> None:
        await self._start_write(name, value)

    def _start_write(self, name: str, value: float) -> Awaitable[None]:
        """The command applied now; the awaitable only answers."""
        if not self._up:
            raise ConnectionLost("local link is down")
        if name not in COMMANDS:
            raise ConfigError(f"{name!r} is not a command; valid: {', '.join(COMMANDS)}")
        self.machine.command(name, value)
        return _answer(None)


async def _answer(value: _T) -> _T:
    """An answer that is there already."""
    return value
