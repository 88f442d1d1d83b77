"""Requests started without waiting (MachineConnection.start_write, start_read_block).

The base class's fallback, for a transport that can send only by awaiting (Modbus, ADS,
LinuxCNC, MQTT): the request goes out at the event loop's next turn, its answer comes in the
future, and every failure (at the send or after, a refusal, a missing block) comes through the
future as the awaiting methods raise it.
"""

from __future__ import annotations

import asyncio

import pytest

from cnctwin.errors import DataError
from cnctwin.thread import (
    CommandRejected,
    ConnectionLost,
    ConnectionState,
    MachineConnection,
    Reading,
    drop_answer,
)


class Awaiting(MachineConnection):
    """A transport whose write goes out when awaited (``failure``: how it fails)."""

    def __init__(self) -> None:
        super().__init__(timeout_s=1.0)
        self.state = ConnectionState.CONNECTED
        self.sent: list[tuple[str, float]] = []
        self.failure: Exception | None = None

    async def _open(self) -> None:
        return None

    async def _close(self) -> None:
        return None

    async def _read(self) -> Reading:
        return Reading({}, 0.0)

    async def _write(self, name: str, value: float) -> None:
        self.sent.append((name, value))
        if self.failure is not None:
            raise self.failure


def test_the_fallback_sends_at_the_next_turn_and_answers_in_the_future() -> None:
    async def test() -> None:
        conn = Awaiting()
        answer = conn.start_write("feed_override_pct", 60.0)
        assert conn.sent == [] and not answer.done()  # the fallback cannot send without awaiting
        assert await answer is None
        assert conn.sent == [("feed_override_pct", 60.0)]

    asyncio.run(test())


def test_failures_come_through_the_future() -> None:
    async def test() -> None:
        conn = Awaiting()
        conn.failure = CommandRejected("BadOutOfRange")
        with pytest.raises(CommandRejected, match="BadOutOfRange"):
            await conn.start_write("feed_override_pct", 151.0)
        assert conn.state is ConnectionState.CONNECTED
        blocks = conn.start_read_block("vibration", 0)
        assert blocks.done()  # refused at the send: this transport has no blocks
        with pytest.raises(DataError, match="carries no sample blocks"):
            blocks.result()
        conn.failure = OSError("connection reset")
        with pytest.raises(ConnectionLost, match="write of feed_override_pct=60.0 failed"):
            await conn.start_write("feed_override_pct", 60.0)
        assert conn.state is ConnectionState.RECONNECTING  # and it reconnects
        gone = conn.start_write("feed_override_pct", 60.0)
        assert gone.done() and isinstance(gone.exception(), ConnectionLost)
        await conn.close()

    asyncio.run(test())


def test_a_dropped_answer_still_comes_and_its_failure_is_taken() -> None:
    async def test() -> None:
        conn = Awaiting()
        conn.failure = CommandRejected("BadOutOfRange")
        waiting = conn.start_write("feed_override_pct", 151.0)
        drop_answer(waiting)  # nobody waits for it: the write still goes out
        await asyncio.sleep(0.005)
        assert conn.sent == [("feed_override_pct", 151.0)]
        assert waiting.done() and not waiting.cancelled()
        conn.state = ConnectionState.RECONNECTING
        failed = conn.start_write("feed_override_pct", 60.0)
        drop_answer(failed)  # taken: no "exception was never retrieved" at collection
        assert failed.done() and not failed.cancelled()

    asyncio.run(test())
