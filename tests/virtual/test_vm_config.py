"""The ``[virtual]`` table: validation, relative paths, faults."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest
from pydantic import ValidationError
from vm_helpers import physics

from cnctwin.virtual import (
    ChatterFault,
    HoleFault,
    ToolBreakageFault,
    VirtualMachine,
    VirtualMachineConfig,
    WearFault,
)

TOML = """
[virtual]
program = "parts/slot.ngc"
tick_ms = 2.5
speed = 4.0
seed = 7

[virtual.noise]
force_n = 3.0

[[virtual.faults]]
kind = "hole"
shape = "cylinder"
center_mm = [30.0, 10.0]
radius_mm = 6.0
z_mm = [-10.0, 0.0]

[[virtual.faults]]
kind = "breakage"
at_line = 7

[[virtual.faults]]
kind = "wear"
growth_per_min = 0.2

[[virtual.faults]]
kind = "chatter"
at_s = 3.0
frequency_hz = 900.0
"""


def _load(tmp_path: Path, text: str) -> VirtualMachineConfig:
    data = tomllib.loads(text)
    return VirtualMachineConfig.model_validate(data["virtual"], context={"base_dir": tmp_path})


def test_toml_table(tmp_path: Path) -> None:
    (tmp_path / "parts").mkdir()
    (tmp_path / "parts" / "slot.ngc").write_text("G21 G90\nG1 X10 F600\nM30\n")
    config = _load(tmp_path, TOML)
    assert config.program == (tmp_path / "parts" / "slot.ngc").resolve()
    assert config.tick_s == pytest.approx(0.0025)
    assert config.noise.force_n == 3.0
    assert config.noise.current_a > 0.0  # other families keep their defaults
    kinds = [type(f) for f in config.faults]
    assert kinds == [HoleFault, ToolBreakageFault, WearFault, ChatterFault]
    vm = VirtualMachine(config, physics())
    vm.step(config.tick_s)
    assert vm.snapshot()["t_s"] == pytest.approx(0.0025)


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("[virtual]\nprogram = 'missing.ngc'\n", ["no such file", "missing.ngc"]),
        ("[virtual]\ntick_ms = 0.1\n", ["tick_ms"]),
        ("[virtual]\nspeed = 0\n", ["speed"]),
        ("[virtual]\nturbo = true\n", ["turbo"]),
        ("[[virtual.faults]]\nkind = 'meteor'\n", ["meteor"]),
        ("[[virtual.faults]]\nkind = 'breakage'\n", ["exactly one of at_s"]),
        ("[[virtual.faults]]\nkind = 'hole'\nmin_mm = [0, 0, 0]\n", ["min_mm and max_mm"]),
        (
            "[[virtual.faults]]\nkind = 'hole'\nmin_mm = [0, 0, 0]\nmax_mm = [1, 0, 1]\n",
            ["max_mm's y"],
        ),
        ("[[virtual.faults]]\nkind = 'hole'\nshape = 'cylinder'\n", ["center_mm"]),
    ],
)
def test_invalid_tables(tmp_path: Path, text: str, words: list[str]) -> None:
    with pytest.raises(ValidationError) as info:
        _load(tmp_path, text)
    message = str(info.value)
    for word in words:
        assert word in message


def test_missing_material_is_a_config_error() -> None:
    from cnctwin.config import MaterialConfig
    from cnctwin.errors import ConfigError

    bad = physics().model_copy(update={"material": MaterialConfig(name="unobtainium")})
    with pytest.raises(ConfigError, match="material.name"):
        VirtualMachine(VirtualMachineConfig(), bad)
