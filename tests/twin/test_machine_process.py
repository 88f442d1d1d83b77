"""The virtual machine's child process: Ctrl-C while it starts ends the start as Ctrl-C does."""

from __future__ import annotations

import signal
from pathlib import Path

import pytest

from cnctwin.twin import RunConfig
from cnctwin.twin.host import MachineProcess


def test_ctrl_c_that_ends_the_starting_child_is_a_keyboard_interrupt(
    demo_config: RunConfig, tmp_path: Path
) -> None:
    # Ctrl-C at a terminal reaches the whole process group; the parent's own interrupt can be
    # swallowed while numba compiles (a ctypes callback), so the child's end must tell
    machine = MachineProcess(demo_config, "opcua", log=tmp_path / "machine.log")
    machine.spawn()
    child = machine._process
    assert child is not None
    child.send_signal(signal.SIGINT)  # before it can answer: it is still importing
    with pytest.raises(KeyboardInterrupt):
        machine.wait_ready()
    assert child.poll() is not None


def test_a_child_that_dies_otherwise_is_a_one_line_error(
    demo_config: RunConfig, tmp_path: Path
) -> None:
    from cnctwin.errors import CnctwinError

    machine = MachineProcess(demo_config, "opcua", log=tmp_path / "machine.log")
    machine.spawn()
    assert machine._process is not None
    machine._process.send_signal(signal.SIGTERM)
    with pytest.raises(CnctwinError, match="did not start"):
        machine.wait_ready()
