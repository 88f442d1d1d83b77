"""The twin's cycles at a real-time priority (``[twin] realtime_priority``; docs/twin.md).

On a computer shared with other work, most of the cycle's lateness is not its own work but
waiting for a processor: under Linux's ordinary scheduler (CFS) a thread woken by its timer
or its socket may wait a time slice of a few milliseconds behind a busy process
(docs/benchmarks.md: the twin's cycle p99 with every stage on, 4.8-7.1 ms wall against 3-4 ms
of its own CPU). Under SCHED_FIFO (POSIX real-time scheduling, ``sched(7)``) a woken thread
runs at once, ahead of every ordinary thread, for as long as it does not sleep; the kernel
still keeps 5 % of each second for ordinary threads (``/proc/sys/kernel/sched_rt_runtime_us``)
so a run-away cycle cannot lock a processor up.

A processor is not all the cycle waits for: the historian's writer and the other threads of
the process hold Python's GIL in turn. So that a thread holding the GIL is never preempted by
an ordinary process while the cycle waits for it (a priority inversion), every thread of the
process runs at the same SCHED_FIFO priority, and a thread that wants the GIL back waits at most
:data:`SWITCH_INTERVAL_S` (0.5 ms; Python's switch interval, 5 ms by default) before the
holder must let go.

:func:`cycle_priority` does both for the run and puts every thread's policy and priority and
the switch interval back afterwards; threads started meanwhile inherit the policy from the
thread that starts them. Only the running cycles get it: building the twin (compiling kernels,
seconds of work) runs at the ordinary priority. :func:`check_cycle_priority` tries the
priority once before anything starts, so that a system that refuses it says so before
connecting.

Linux only; it needs root, ``CAP_SYS_NICE`` or a real-time priority limit for the user
(``rtprio`` in ``/etc/security/limits.conf``, ``LimitRTPRIO=`` of a systemd unit).
"""

from __future__ import annotations

import os
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager

from cnctwin.errors import ConfigError

__all__ = ["SWITCH_INTERVAL_S", "check_cycle_priority", "cycle_priority"]

#: Python's switch interval while the cycles run at a real-time priority, s: the longest the
#: cycle waits for the GIL from another thread of the process (module notes).
SWITCH_INTERVAL_S = 0.0005


def check_cycle_priority(priority: int) -> None:
    """Whether this thread may run at SCHED_FIFO ``priority``: set and put back at once.

    Parameters
    ----------
    priority
        ``[twin] realtime_priority``, 0 (nothing asked) to 98.

    Raises
    ------
    cnctwin.errors.ConfigError
        If the system has no SCHED_FIFO or this user may not use it.
    """
    with cycle_priority(priority):
        pass


@contextmanager
def cycle_priority(priority: int) -> Iterator[None]:
    """Run every thread of the process under SCHED_FIFO at ``priority`` (0: leave them as they
    are), with Python's switch interval at most :data:`SWITCH_INTERVAL_S`, and put each
    thread's policy and priority and the switch interval back on leaving.

    Parameters
    ----------
    priority
        SCHED_FIFO priority, 1 to 98 (99 is the kernel's own watchdogs'); 0 changes nothing.

    Raises
    ------
    cnctwin.errors.ConfigError
        If the system has no SCHED_FIFO or this user may not use it.
    """
    if priority == 0:
        yield
        return
    if not hasattr(os, "sched_setscheduler"):
        raise ConfigError(
            f"[twin] realtime_priority = {priority}: this system has no SCHED_FIFO "
            "(Linux only); set it to 0"
        )
    saved: dict[int, tuple[int, os.sched_param]] = {}
    try:
        for thread in _threads():
            try:
                held = (os.sched_getscheduler(thread), os.sched_getparam(thread))
                os.sched_setscheduler(thread, os.SCHED_FIFO, os.sched_param(priority))
            except ProcessLookupError:  # the thread ended meanwhile
                continue
            saved[thread] = held
    except PermissionError:
        _put_back(saved)
        raise ConfigError(
            f"[twin] realtime_priority = {priority}: this user may not use real-time "
            "scheduling (it needs root, CAP_SYS_NICE or an rtprio limit, e.g. in "
            "/etc/security/limits.conf); set it to 0"
        ) from None
    interval = sys.getswitchinterval()
    sys.setswitchinterval(min(interval, SWITCH_INTERVAL_S))
    try:
        yield
    finally:
        sys.setswitchinterval(interval)
        _put_back(saved)


def _threads() -> list[int]:
    """The thread ids of this process, the calling thread's (0) first."""
    try:
        others = [int(name) for name in os.listdir("/proc/self/task")]
    except OSError:  # no /proc: the calling thread alone
        others = []
    return [0, *(t for t in others if t != threading.get_native_id())]


def _put_back(saved: dict[int, tuple[int, os.sched_param]]) -> None:
    for thread, (policy, param) in saved.items():
        try:
            os.sched_setscheduler(thread, policy, param)
        except ProcessLookupError:  # it ended while the cycles ran
            continue
