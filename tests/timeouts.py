"""Every wall-clock limit of the tests, in one place, with its reason (docs/testing.md).

A limit here only ends a wait that would otherwise hang (a server that never starts, a reply
that never comes); it never measures speed: timing targets (cycle period, p99, overruns,
latency) are measured in benchmarks/. Each limit is about 100x what the wait takes on a quiet
machine, so the suite passes with the CPU oversubscribed (``.ci/stress``: two busy loops per
core beside ``pytest -n 2``, which slows a step 10-20x on the 2-core CI machine) while a real
hang still fails within minutes. Tests of timing logic use virtual time instead
(tests/virtual_time.py).
"""

from __future__ import annotations

#: One in-process OPC UA server start, s: asyncua builds its standard address space in about
#: 1 s quiet; under .ci/stress it took more than 20 s.
SERVER_START_S = 120.0

#: A test's whole asyncio body, s: up to two server starts (a restart) plus its requests, each
#: a few ms quiet.
BODY_S = 2 * SERVER_START_S + 60.0

#: A ``cnctwin`` child process (demo, run, virtual serve) to its first recorded event or
#: sample, s: Python and numba imports, cached kernels and a server start, 5-10 s quiet.
CHILD_START_S = 300.0
