"""Everything the twin sees and decides, queued for the historian off the critical path.

The :class:`~cnctwin.store.historian.Historian` only queues in ``record_*`` (microseconds);
its writer thread commits in batches. The recorder turns a cycle's state into those calls:
measured signals as *samples*, the twin's filtered values, features and predictions as
*predictions*, and events and decisions with their reasons.

Only a cycle whose reading is a new sample (:attr:`CycleState.new_sample`) gives a frame: a
frozen or paused machine leaves a gap in the record, not copies of its last values. A
signal invalid in that sample (:attr:`CycleState.rejected`) is recorded as NaN; the event
``signal_invalid`` says why.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from typing import Any

from cnctwin.errors import DataError
from cnctwin.store import Historian
from cnctwin.thread import SIGNALS
from cnctwin.twin.state import CycleState, TwinEvent

__all__ = ["Recorder"]

logger = logging.getLogger(__name__)


class Recorder:
    """Records one run of the twin.

    Parameters
    ----------
    historian
        Where to record.
    meta
        What describes the run (config file, endpoint, program).
    t0_s
        ``time.monotonic()`` of the run's start: recorded times are seconds since it.

    Attributes
    ----------
    samples
        Sample frames (one per new sample) queued.
    events
        Events queued.
    decisions
        Decisions queued.
    """

    def __init__(self, historian: Historian, meta: Mapping[str, object], t0_s: float) -> None:
        self.historian = historian
        self.run_id = historian.start_run(meta)
        self.t0_s = t0_s
        self.samples = 0
        self.events = 0
        self.decisions = 0

    @property
    def location(self) -> str:
        """The database (path or URL without password)."""
        return self.historian.location

    def cycle(self, state: CycleState) -> None:
        """Queue the measured and predicted values of one cycle (nothing without a new sample)."""
        if not (state.connected and state.new_sample):
            return
        t = (state.received_s if math.isfinite(state.received_s) else state.deadline_s) - self.t0_s
        measured = dict(state.measured)
        measured.update({name: math.nan for name in state.rejected if name in SIGNALS})
        try:
            self.historian.record_samples(self.run_id, t, measured)
            predicted: dict[str, float] = dict(state.predicted)
            predicted.update({f"filtered_{k}": v for k, v in state.filtered.items()})
            predicted.update(state.features)
            self.historian.record_prediction(self.run_id, t, predicted)
        except DataError as err:  # a value the historian refuses must not stop the twin
            logger.warning("cycle %d not recorded: %s", state.index, err)
            return
        self.samples += 1

    def event(self, event: TwinEvent) -> None:
        """Queue an event."""
        self.historian.record_event(
            self.run_id, event.t_s - self.t0_s, event.kind, event.message, event.data
        )
        self.events += 1

    def decision(
        self,
        t_s: float,
        rule: str,
        command: str,
        value: float,
        reason: str,
        accepted: bool,
        readback: float | None,
    ) -> None:
        """Queue a decision with its reason, the safety filter's verdict and the read-back."""
        self.historian.record_decision(
            self.run_id, t_s - self.t0_s, rule, command, value, reason, accepted, readback
        )
        self.decisions += 1

    def end(self, status: str, summary: Mapping[str, Any]) -> None:
        """Commit everything queued and close the run."""
        self.historian.end_run(self.run_id, status, dict(summary))
