"""The action stage does not wait for the machine (cnctwin.twin.actions, docs/control.md).

A write goes out in the cycle that decides it and is settled in a later one, from that cycle's
reading and the write's answer: confirmed only by a reading that shows it, not confirmed when
none does within ``readback_timeout_s``, not carried out on a refusal or a lost link,
superseded by a later write of another value; a stop is sent and watched at once. The
machine here is a stand-in whose answers the test gives, and the twin's clock is the cycle
states' ``time_s``: nothing depends on how fast this machine runs.
"""

from __future__ import annotations

import asyncio
import math
import time
from collections.abc import Awaitable, Callable, Coroutine
from typing import Any

from cnctwin.control import ControlConfig, Decision, SafetyFilter
from cnctwin.thread import (
    CommandRejected,
    ConnectionState,
    MachineConnection,
    Reading,
)
from cnctwin.twin.actions import ActionStage, CommandResult
from cnctwin.twin.state import CycleState

TIMEOUT_S = 0.25


class Machine(MachineConnection):
    """Takes each write when it is sent; answers it when the test says (:meth:`answer`)."""

    def __init__(self) -> None:
        super().__init__()
        self.state = ConnectionState.CONNECTED
        self.sent: list[tuple[str, float]] = []
        self.answers: list[asyncio.Future[None]] = []

    async def _open(self) -> None:
        return None

    async def _close(self) -> None:
        return None

    async def _read(self) -> Reading:
        raise AssertionError("the action stage reads nothing itself")

    async def _write(self, name: str, value: float) -> None:
        raise AssertionError("the action stage does not wait for a write")

    def _start_write(self, name: str, value: float) -> Awaitable[None]:
        self.sent.append((name, value))
        answer: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        self.answers.append(answer)
        return answer

    async def answer(self, index: int, error: Exception | None = None) -> None:
        """Answer write ``index`` (a refusal or a loss with ``error``); let it arrive."""
        if error is None:
            self.answers[index].set_result(None)
        else:
            self.answers[index].set_exception(error)
        await asyncio.sleep(0.005)  # the loop hands the answer over long before this ends


def stage(machine: Machine, **control: Any) -> ActionStage:
    config = ControlConfig(enabled=True, min_interval_s=0.01, **control)
    return ActionStage(machine, SafetyFilter(config), readback_timeout_s=TIMEOUT_S)


def cycle(
    index: int,
    time_s: float,
    measured: dict[str, float],
    *decisions: Decision,
    received_s: float | None = None,
) -> CycleState:
    """A cycle whose reading (``measured``) arrived now, or at ``received_s``."""
    state = CycleState(
        index,
        0.0,
        time_s,
        connected=True,
        received_s=time.monotonic() if received_s is None else received_s,
        new_sample=True,
    )
    state.measured = dict(measured)
    state.commands.extend(decisions)
    return state


def feed(time_s: float, value: float) -> Decision:
    return Decision(time_s, "slow_down", "feed_override", value, f"feed to {value:g} %")


def run(test: Callable[[], Coroutine[Any, Any, None]]) -> None:
    asyncio.run(test())


def test_a_write_is_sent_in_its_cycle_and_confirmed_by_a_later_reading() -> None:
    async def test() -> None:
        machine = Machine()
        actions = stage(machine)
        first = actions.process(cycle(0, 1.0, {"feed_override_pct": 100.0}, feed(1.0, 60.0)))
        # the command went out before the stage returned; nothing is settled yet
        assert machine.sent == [("feed_override_pct", 60.0)]
        assert first.decisions == [] and actions.in_flight == 1
        await machine.answer(0)
        # a reading taken before the write cannot show it, even when it carries the value
        early = cycle(1, 1.0125, {"feed_override_pct": 60.0}, received_s=0.0)
        assert actions.process(early).decisions == []
        shown = cycle(2, 1.025, {"feed_override_pct": 60.0})
        (result,) = actions.process(shown).decisions
        assert isinstance(result, CommandResult)
        assert result.confirmed and result.readback == 60.0 and result.note == ""
        assert result.confirmed_s == shown.received_s and result.written_s <= shown.received_s
        assert actions.safety.commanded["feed_override_pct"].confirmed
        assert actions.in_flight == 0 and actions.results == [result]

    run(test)


def test_an_answered_write_the_machine_never_shows_times_out_not_confirmed() -> None:
    async def test() -> None:
        machine = Machine()
        actions = stage(machine)
        actions.process(cycle(0, 1.0, {"feed_override_pct": 100.0}, feed(1.0, 60.0)))
        await machine.answer(0)
        # the machine keeps showing 100 %: waited for until readback_timeout_s is over
        shown = {"feed_override_pct": 100.0}
        assert actions.process(cycle(1, 1.0 + TIMEOUT_S - 0.01, shown)).decisions == []
        (result,) = actions.process(cycle(2, 1.0 + TIMEOUT_S, shown)).decisions
        assert not result.confirmed and result.readback == 100.0
        assert "no read-back showed it within readback_timeout_s" in result.note
        assert math.isnan(result.confirmed_s) and actions.in_flight == 0

    run(test)


def test_a_write_without_an_answer_is_not_confirmed_by_the_reading_alone() -> None:
    async def test() -> None:
        machine = Machine()
        actions = stage(machine)
        actions.process(cycle(0, 1.0, {"feed_override_pct": 100.0}, feed(1.0, 60.0)))
        await asyncio.sleep(0.005)  # the write waits for its answer
        shown = {"feed_override_pct": 60.0}
        assert actions.process(cycle(1, 1.1, shown)).decisions == []
        (result,) = actions.process(cycle(2, 1.0 + TIMEOUT_S, shown)).decisions
        assert not result.confirmed and "no answer within" in result.note
        await machine.answer(0)  # an answer after the time is up changes nothing
        assert actions.process(cycle(3, 1.3, shown)).decisions == []
        assert actions.results == [result]

    run(test)


def test_a_refused_write_is_recorded_as_not_carried_out() -> None:
    async def test() -> None:
        machine = Machine()
        actions = stage(machine)
        actions.process(cycle(0, 1.0, {"feed_override_pct": 100.0}, feed(1.0, 60.0)))
        await machine.answer(0, CommandRejected("machine refused feed_override_pct=60"))
        # even a reading that shows the value does not confirm a refused write
        (result,) = actions.process(cycle(1, 1.0125, {"feed_override_pct": 60.0})).decisions
        assert not result.confirmed and result.readback is None
        assert result.note.startswith("not carried out: machine refused")

    run(test)


def test_a_write_on_a_lost_link_is_not_carried_out_in_its_own_cycle() -> None:
    async def test() -> None:
        machine = Machine()
        actions = stage(machine)
        machine.state = ConnectionState.RECONNECTING  # the link went down since the read
        state = actions.process(cycle(0, 1.0, {"feed_override_pct": 100.0}, feed(1.0, 60.0)))
        (result,) = state.decisions
        assert not result.confirmed and "not carried out" in result.note
        assert machine.sent == [] and actions.in_flight == 0

    run(test)


def test_a_later_write_of_another_value_supersedes_an_earlier_one() -> None:
    async def test() -> None:
        machine = Machine()
        actions = stage(machine)
        actions.process(cycle(0, 1.0, {"feed_override_pct": 100.0}, feed(1.0, 60.0)))
        state = actions.process(cycle(1, 1.05, {"feed_override_pct": 100.0}, feed(1.05, 50.0)))
        (earlier,) = state.decisions  # settled when the later one went out
        assert earlier.verdict.value == 60.0 and not earlier.confirmed
        assert earlier.note == "superseded by feed_override_pct=50"
        await machine.answer(1)
        (later,) = actions.process(cycle(2, 1.06, {"feed_override_pct": 50.0})).decisions
        assert later.verdict.value == 50.0 and later.confirmed
        assert machine.sent == [("feed_override_pct", 60.0), ("feed_override_pct", 50.0)]

    run(test)


def test_two_writes_of_the_same_value_are_both_confirmed_by_one_reading() -> None:
    async def test() -> None:
        machine = Machine()
        actions = stage(machine)
        actions.process(cycle(0, 1.0, {"feed_override_pct": 100.0}, feed(1.0, 60.0)))
        # the reading does not show it yet and min_interval_s is over: sent again
        actions.process(cycle(1, 1.05, {"feed_override_pct": 100.0}, feed(1.05, 60.0)))
        assert machine.sent == [("feed_override_pct", 60.0)] * 2 and actions.in_flight == 2
        await machine.answer(0)
        await machine.answer(1)
        results = actions.process(cycle(2, 1.06, {"feed_override_pct": 60.0})).decisions
        assert [r.confirmed for r in results] == [True, True]

    run(test)


def test_writes_in_flight_when_the_machine_is_lost_are_not_confirmed_nor_sent_again() -> None:
    async def test() -> None:
        machine = Machine()
        actions = stage(machine)
        actions.process(cycle(0, 1.0, {"feed_override_pct": 100.0}, feed(1.0, 60.0)))
        lost = CycleState(1, 0.0, 1.0125)  # the read failed
        actions.connection_lost(lost)
        (result,) = lost.decisions
        assert not result.confirmed and "lost before a read-back" in result.note
        # the answer that comes after the loss changes nothing
        await machine.answer(0)
        assert actions.process(cycle(2, 1.1, {"feed_override_pct": 60.0})).decisions == []
        assert len(actions.results) == 1 and machine.sent == [("feed_override_pct", 60.0)]
        # until the watchdog says the machine is back, a decision is recorded, not written
        later = cycle(3, 1.2, {"feed_override_pct": 60.0}, feed(1.2, 40.0))
        (held,) = actions.process(later).decisions
        assert not held.confirmed and held.note == "not written: the machine is lost"
        assert machine.sent == [("feed_override_pct", 60.0)]

    run(test)


def test_the_end_of_the_run_records_the_writes_in_flight() -> None:
    async def test() -> None:
        machine = Machine()
        actions = stage(machine)
        actions.process(cycle(0, 1.0, {"feed_override_pct": 100.0}, feed(1.0, 60.0)))
        actions.close()
        (result,) = actions.results
        assert not result.confirmed and "run ended" in result.note
        assert actions.in_flight == 0

    run(test)


def test_a_stop_is_sent_and_watched_at_once_and_confirmed_by_motion_without_its_answer() -> None:
    async def test() -> None:
        machine = Machine()
        actions = stage(machine)
        moving = {"x_mm": 0.0, "y_mm": 0.0, "z_mm": 0.0, "t_s": 0.0, "feed_mm_min": 600.0}
        halt = Decision(1.0, "halt", "stop", 1.0, "force out of band")
        actions.process(cycle(0, 1.0, moving, halt))
        assert machine.sent == [("stop", 1.0)] and actions.stopping
        assert actions.stop_outcome == "pending"
        # the machine never answers the write: its motion alone confirms the stop
        confirmed_in = []
        for k in range(1, 5):
            rest = {**moving, "t_s": 0.01 * k, "feed_mm_min": 0.0}
            state = actions.process(cycle(k, 1.0 + 0.01 * k, rest))
            confirmed_in += [k for e in state.events if e.kind == "stop_confirmed"]
        # rest_readings = 2: the second reading at rest confirms, as before the change
        assert confirmed_in == [2] and actions.stop_outcome == "confirmed"
        assert actions.in_flight == 1  # the write itself waits for its answer still

    run(test)
