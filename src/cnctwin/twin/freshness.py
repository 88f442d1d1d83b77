"""Whether a reading of the machine is a new sample, and how old it is.

A cycle reads the machine whether or not the machine has produced anything new: a
subscription's cache, a Modbus register bank and an OPC UA Read all answer with the last
values while the machine is frozen, paused or stuck behind a gateway. :class:`Freshness`
tells a new sample from a repeat, per reading, by the best evidence the transport carries:

1. the machine's time stamp (OPC UA SourceTimestamp, :attr:`Reading.source_time_s`): a
   reading is new when its newest time stamp is later than the last one seen;
2. else a sample counter (Modbus ``heartbeat``, :attr:`Reading.sequence`): new when it moved;
3. else the receive time (:attr:`Reading.received_s`): every answered read is new.

The age of a reading is the twin's wall clock minus the machine's time stamp (case 1: the
two clocks must agree to well within ``max_sample_age_s``, e.g. both on NTP), else the time
since the last new sample on the twin's monotonic clock. A reading older than
``max_sample_age_s`` is *stale*: not a current sample whatever its time stamp says.

Units: s throughout; time stamps are POSIX s (UTC), receive times ``time.monotonic()`` s.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

from cnctwin.thread import Reading

__all__ = ["Freshness", "SampleCheck"]


@dataclass(frozen=True, slots=True)
class SampleCheck:
    """The verdict on one reading.

    Attributes
    ----------
    new
        A new, current sample: the twin computes and records it.
    stale
        Older than ``max_sample_age_s``.
    age_s
        Age of the newest value, s (see the module's text for the clock).
    basis
        ``"source time"``, ``"sample counter"`` or ``"receive time"``: what told new from old.
    """

    new: bool
    stale: bool
    age_s: float
    basis: str


class Freshness:
    """Tells new samples from repeats and measures their age.

    Parameters
    ----------
    max_sample_age_s
        Age beyond which a reading is stale, s (``[twin] max_sample_age_s``).
    wall_clock
        POSIX time now, s (default ``time.time``); tests pass a controllable clock.
    monotonic
        Monotonic time now, s (default ``time.monotonic``, the clock of
        :attr:`Reading.received_s`).

    Attributes
    ----------
    last_fresh_s
        Receive time (monotonic s) of the last new, current sample; ``None`` before the
        first. A gap in the machine's data starts here.
    repeats
        Readings taken as no new sample.
    stale_readings
        Readings taken as stale.
    """

    def __init__(
        self,
        max_sample_age_s: float,
        *,
        wall_clock: Callable[[], float] = time.time,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        self.max_sample_age_s = max_sample_age_s
        self.wall_clock = wall_clock
        self.monotonic = monotonic
        self.last_fresh_s: float | None = None
        self.repeats = 0
        self.stale_readings = 0
        self._source_s: float | None = None
        self._sequence: float | None = None
        self._received_s: float | None = None

    def check(self, reading: Reading) -> SampleCheck:
        """Judge one reading; remember it as the reference for the next."""
        source = reading.source_time_s
        if source is not None and math.isfinite(source):
            basis = "source time"
            new = self._source_s is None or source > self._source_s
            if new:
                self._source_s = source
            age = self.wall_clock() - self._source_s
        else:
            if reading.sequence is not None:
                basis = "sample counter"
                new = self._sequence is None or reading.sequence != self._sequence
                self._sequence = reading.sequence
            else:
                basis = "receive time"
                new = self._received_s is None or reading.received_s > self._received_s
            self._received_s = reading.received_s
            since = self.last_fresh_s
            age = 0.0 if new or since is None else self.monotonic() - since
        stale = age > self.max_sample_age_s
        if stale:
            self.stale_readings += 1
        elif new:
            self.last_fresh_s = reading.received_s
        else:
            self.repeats += 1
        return SampleCheck(new and not stale, stale, age, basis)
