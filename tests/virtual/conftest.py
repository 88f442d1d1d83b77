"""Fixtures of the virtual machine's tests (helpers are in vm_helpers.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from vm_helpers import QUIET, MakeVM, physics

from cnctwin.config import MachiningConfig
from cnctwin.virtual import VirtualMachine, VirtualMachineConfig


@pytest.fixture
def make_vm(tmp_path: Path) -> MakeVM:
    """``make_vm(program_text, physics_config=None, **virtual_keys)``: a quiet virtual machine
    running the text (on :func:`vm_helpers.physics` unless ``physics_config`` is given)."""

    def make(
        text: str, physics_config: MachiningConfig | None = None, **keys: Any
    ) -> VirtualMachine:
        program = tmp_path / "program.ngc"
        program.write_text(text)
        keys.setdefault("noise", QUIET)
        config = VirtualMachineConfig(program=program, **keys)
        return VirtualMachine(config, physics_config or physics())

    return make
