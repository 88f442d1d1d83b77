"""``[twin] realtime_priority``: the cycles run under SCHED_FIFO at the asked priority, as the
kernel itself reports it (``sched_getscheduler``/``sched_getparam`` of the cycle's thread),
the build and everything after the run at the ordinary scheduler; a system that refuses it
is a one-line configuration error before connecting."""

from __future__ import annotations

import asyncio
import os
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import pytest
from twin_helpers import STEP_S

from cnctwin.errors import ConfigError
from cnctwin.twin import LocalConnection, RunConfig, run_session
from cnctwin.twin.priority import SWITCH_INTERVAL_S, check_cycle_priority, cycle_priority
from cnctwin.virtual import VirtualMachine

REPO = Path(__file__).resolve().parents[2]


def _fifo_allowed() -> bool:
    if not hasattr(os, "sched_setscheduler"):
        return False
    policy, param = os.sched_getscheduler(0), os.sched_getparam(0)
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
    except PermissionError:
        return False
    os.sched_setscheduler(0, policy, param)
    return True


needs_fifo = pytest.mark.skipif(
    not _fifo_allowed(), reason="this user may not use SCHED_FIFO (not root, no CAP_SYS_NICE)"
)


def _with_priority(base: RunConfig, priority: int) -> RunConfig:
    assert base.virtual is not None
    twin = base.twin.model_copy(update={"realtime_priority": priority})
    return base.model_copy(update={"twin": twin, "control": base.control.model_copy()})


@needs_fifo
def test_the_cycles_run_at_the_asked_fifo_priority_and_only_they(demo_config: RunConfig) -> None:
    """The cycle's thread and every other thread of the process (here one started before the
    run, as the historian's writer is) at SCHED_FIFO 7 while the cycles run, the GIL's switch
    interval at 0.5 ms; the build before and everything after at the ordinary scheduler."""
    config = _with_priority(demo_config, 7)
    assert config.virtual is not None
    vm = VirtualMachine(config.virtual, config)
    conn = LocalConnection(vm, step_s=STEP_S, tick_s=vm.tick_s)
    done = threading.Event()
    other = threading.Thread(target=done.wait, daemon=True)
    other.start()
    assert other.native_id is not None
    seen: list[tuple[int, int, int]] = []
    at_start: list[int] = []
    stop = asyncio.Event()
    switch = sys.getswitchinterval()
    intervals: set[float] = set()

    def on_cycle(state: Any) -> None:
        seen.append(
            (
                os.sched_getscheduler(0),
                os.sched_getparam(0).sched_priority,
                os.sched_getscheduler(other.native_id),
            )
        )
        intervals.add(sys.getswitchinterval())
        if len(seen) >= 20:
            stop.set()

    try:
        asyncio.run(
            run_session(
                config,
                connection=conn,
                stop_event=stop,
                on_cycle=on_cycle,
                on_start=lambda twin: at_start.append(os.sched_getscheduler(0)),
                realtime=False,
            )
        )
        assert at_start == [os.SCHED_OTHER]  # the build ran at the ordinary scheduler
        assert seen and set(seen) == {(os.SCHED_FIFO, 7, os.SCHED_FIFO)}
        assert intervals == {min(switch, SWITCH_INTERVAL_S)}  # the GIL back within 0.5 ms
        # and what follows is as before
        assert os.sched_getscheduler(0) == os.sched_getscheduler(other.native_id)
        assert os.sched_getscheduler(0) == os.SCHED_OTHER
        assert sys.getswitchinterval() == switch
    finally:
        done.set()
        other.join()


@needs_fifo
def test_the_priority_is_put_back_when_the_run_fails() -> None:
    switch = sys.getswitchinterval()
    with pytest.raises(RuntimeError), cycle_priority(3):
        assert os.sched_getscheduler(0) == os.SCHED_FIFO
        raise RuntimeError("a stage failed")
    assert os.sched_getscheduler(0) == os.SCHED_OTHER
    assert sys.getswitchinterval() == switch


def test_a_refused_priority_is_one_line_before_connecting(
    demo_config: RunConfig, monkeypatch: pytest.MonkeyPatch
) -> None:
    """What the kernel answers a user without the right (EPERM), simulated: refused before
    the machine is touched, with the value, the key and what to do."""

    def refuse(pid: int, policy: int, param: os.sched_param) -> None:
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    config = _with_priority(demo_config, 10)
    assert config.virtual is not None

    class Untouched(LocalConnection):
        async def connect(self) -> None:
            raise AssertionError("connected before the priority was checked")

    vm = VirtualMachine(config.virtual, config)
    with pytest.raises(ConfigError) as refused:
        asyncio.run(run_session(config, connection=Untouched(vm, step_s=STEP_S, tick_s=vm.tick_s)))
    message = str(refused.value)
    assert "\n" not in message
    assert "realtime_priority = 10" in message and "set it to 0" in message
    check_cycle_priority(0)  # nothing asked: nothing tried


def test_out_of_range_priorities_are_refused_by_the_cli(tmp_path: Path) -> None:
    examples = REPO / "src" / "cnctwin" / "examples"
    source = (examples / "demo_twin.toml").read_text()
    (tmp_path / "demo_twin.ngc").write_bytes((examples / "demo_twin.ngc").read_bytes())
    for bad in ("99", "-1", "1.5", "nan"):
        text = source.replace("[twin]\n", f"[twin]\nrealtime_priority = {bad}\n", 1)
        assert text != source
        (tmp_path / "twin.toml").write_text(text)
        run = subprocess.run(
            [sys.executable, "-m", "cnctwin", "run", "--config", str(tmp_path / "twin.toml")],
            capture_output=True,
            text=True,
            env={**os.environ, "PYTHONPATH": str(REPO / "src")},
            timeout=120,
        )
        assert run.returncode == 2, (bad, run.stderr)
        assert "realtime_priority" in run.stderr and "Traceback" not in run.stderr
        assert len(run.stderr.strip().splitlines()) == 1, run.stderr
