"""The twin's configuration file: one TOML for machining, connection, machine, rules and twin."""

from __future__ import annotations

from pathlib import Path

import pytest

from cnctwin.config import MachiningConfig, load_config
from cnctwin.errors import ConfigError
from cnctwin.twin.config import RunConfig, load_run_config
from cnctwin.twin.pipeline import signal_names
from cnctwin.virtual.config import HoleFault


def test_demo_file_holds_every_table(demo_config: RunConfig) -> None:
    c = demo_config
    assert isinstance(c, MachiningConfig)  # the machining root, extended
    assert c.tools[0].diameter_mm == 6.0 and c.material.name == "AA6060-T6"
    assert c.connection.transport == "opcua"
    assert c.virtual is not None and c.virtual.program is not None
    assert c.virtual.program.name == "demo_twin.ngc" and c.virtual.program.is_file()
    assert any(isinstance(f, HoleFault) for f in c.virtual.faults)
    assert c.control.enabled and [r.name for r in c.rules][:2] == [
        "force_out_of_band",
        "form_error",
    ]
    assert c.twin.cycle_s == 0.0125 and c.twin.form_error.tolerance_um == 40.0
    assert set(c.twin.filters) == {"force_x_n", "force_y_n", "spindle_power_w"}


def test_load_config_with_a_model_and_without(tmp_path: Path) -> None:
    path = tmp_path / "t.toml"
    path.write_text("[twin]\ncycle_s = 0.01\n[control]\nenabled = true\n")
    assert load_config(path, model=RunConfig).twin.cycle_s == 0.01
    with pytest.raises(ConfigError, match=r"twin: unknown key; valid keys: machine, tools"):
        load_config(path)  # the machining root alone does not know the runtime's tables


def test_empty_file_is_a_valid_twin_with_control_off(tmp_path: Path) -> None:
    path = tmp_path / "empty.toml"
    path.write_text("")
    c = load_run_config(path)
    assert c.control.enabled is False and c.rules == [] and c.virtual is None
    assert c.twin.cycle_s == 0.0125


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[twin]\ncycle = 1\n", "twin.cycle: unknown key"),
        ("[twin.force_band]\nk = -1\n", "twin.force_band.k: must be > 0 and <= 100; got -1"),
        ('[twin.filters.force_x_n]\nkind = "median"\n', "twin.filters.force_x_n.kind"),
        ('[twin]\nprogram = "missing.ngc"\n', "no such file"),
        (
            '[[rules]]\nname = "a"\ncondition = "x > 1"\naction = "stop"\n'
            '[[rules]]\nname = "a"\ncondition = "x > 2"\naction = "stop"\n',
            "rule name 'a' is given twice",
        ),
    ],
)
def test_bad_values_are_one_line_errors(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_run_config(path)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_rules_may_read_every_name_the_twin_provides(demo_config: RunConfig) -> None:
    names = set(signal_names(demo_config))
    assert {"force_out_of_band", "form_error_um", "feed_override_pct"} <= names
    assert {"filtered_force_x_n", "spindle_power_w_rms"} <= names
