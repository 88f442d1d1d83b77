"""Configuration: loading, defaults, one-line errors naming the key, the interpreter's set-up."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from cnctwin.config import MachiningConfig, ToolConfig, load_config
from cnctwin.errors import ConfigError
from cnctwin.nc.setup import NCSetup, ToolEntry

FULL = """
tool_table = "tables/mill.tbl"
tool_table_units = "inch"

[machine]
name = "VF-2"
kind = "mill"
rapid_mm_min = 25400.0
max_spindle_rpm = 8100.0
g28_home_mm = [0.0, 0.0, 0.0]
g30_home_mm = [-100.0, -50.0, -10.0]

[machine.axes.x]
min_mm = -762.0
max_mm = 0.0
max_velocity_mm_min = 25400.0
max_accel_mm_s2 = 5000.0

[machine.axes.z]
min_mm = -508.0
max_mm = 0.0

[machine.work_offsets]
g54 = [-400.0, -250.0, -300.0]
"g59.3" = [1.0, 2.0, 3.0]

[[tools]]
number = 1
kind = "ball"
diameter_mm = 6.0
flutes = 2
helix_deg = 30.0
flute_length_mm = 12.0
length_mm = 80.0

[[tools]]
number = 4
kind = "bull"
diameter_mm = 12.0
corner_radius_mm = 1.0
flutes = 4
length_mm = 95.5

[stock]
kind = "box"
min_mm = [-400.0, -250.0, -330.0]
max_mm = [-300.0, -150.0, -300.0]

[material]
name = "aluminium 7075-T6"
density_kg_m3 = 2810.0
hardness_hb = 150.0
"""


def write(folder: Path, text: str, name: str = "twin.toml") -> Path:
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


@pytest.fixture
def full_config(tmp_path: Path) -> Path:
    write(tmp_path, "T4 P4 Z1.0 D0.5 ;replaced by [[tools]]\nT5 P5 Z2.0 D0.25\n", "tables/mill.tbl")
    return write(tmp_path, FULL)


def load_error(tmp_path: Path, text: str) -> str:
    path = write(tmp_path, text)
    with pytest.raises(ConfigError) as caught:
        load_config(path)
    message = str(caught.value)
    assert "\n" not in message
    assert message.startswith(f"{path}: ")
    return message.removeprefix(f"{path}: ")


def test_full_config_round_trip(full_config: Path) -> None:
    config = load_config(full_config)
    assert config.machine.name == "VF-2"
    assert config.machine.axes.x.min_mm == -762.0
    assert config.machine.axes.y.max_mm == 500.0  # default
    assert config.tools[0].corner_radius_mm == 3.0  # a ball's is half the diameter
    assert config.tools[1].corner_radius_mm == 1.0
    assert config.stock.max_mm == (-300.0, -150.0, -300.0)
    assert config.material.hardness_hb == 150.0
    assert MachiningConfig.model_validate(config.model_dump(by_alias=True)) == config


def test_nc_setup_merges_table_and_tools(full_config: Path) -> None:
    setup = load_config(full_config).nc_setup()
    assert setup == NCSetup(
        tools={
            1: ToolEntry(number=1, length_mm=80.0, diameter_mm=6.0),
            4: ToolEntry(number=4, length_mm=95.5, diameter_mm=12.0),
            5: ToolEntry(number=5, length_mm=2.0 * 25.4, diameter_mm=0.25 * 25.4),
        },
        lathe=False,
        work_offsets_mm={1: (-400.0, -250.0, -300.0), 9: (1.0, 2.0, 3.0)},
        g28_home_mm=(0.0, 0.0, 0.0),
        g30_home_mm=(-100.0, -50.0, -10.0),
        max_spindle_rpm=8100.0,
    )


def test_empty_file_is_the_defaults(tmp_path: Path) -> None:
    config = load_config(write(tmp_path, ""))
    assert config == MachiningConfig()
    assert config.machine.kind == "mill"
    assert config.nc_setup() == NCSetup()


def test_lathe_kind_sets_the_lathe_flag(tmp_path: Path) -> None:
    text = '[machine]\nkind = "lathe"\n[[tools]]\nnumber = 1\ndiameter_mm = 0.8\norientation = 3\n'
    setup = load_config(write(tmp_path, text)).nc_setup()
    assert setup.lathe is True
    assert setup.tools[1].orientation == 3


def test_relative_tool_table_is_relative_to_the_config_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    write(tmp_path / "cell", "T2 P2 Z12.5 D3\n", "tools.tbl")
    path = write(tmp_path / "cell", 'tool_table = "tools.tbl"\n')
    monkeypatch.chdir(tmp_path)  # not the config's folder
    config = load_config(path)
    assert config.tool_table == (tmp_path / "cell" / "tools.tbl").resolve()
    assert config.nc_setup().tools == {2: ToolEntry(number=2, length_mm=12.5, diameter_mm=3.0)}


def test_missing_tool_table_names_the_key(tmp_path: Path) -> None:
    message = load_error(tmp_path, 'tool_table = "nowhere.tbl"\n')
    assert message.startswith(f"tool_table: no such file {tmp_path / 'nowhere.tbl'}")
    assert message.endswith("; got 'nowhere.tbl'")


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (
            "[machine.axes.x]\nmaxmm = 3.0\n",
            "machine.axes.x.maxmm: unknown key; valid keys: min_mm, max_mm, "
            "max_velocity_mm_min, max_accel_mm_s2",
        ),
        (
            "[machin]\nname = 'x'\n",
            "machin: unknown key; valid keys: machine, tools, tool_table, tool_table_units, "
            "stock, material, simulation",
        ),
        (
            "[machine.work_offsets]\ng60 = [0, 0, 0]\n",
            "machine.work_offsets.g60: unknown key; valid keys: g54, g55, g56, g57, g58, g59, "
            "g59.1, g59.2, g59.3",
        ),
        (
            "[[tools]]\nnumber = 1\ndiameter_mm = 3\n"
            "[[tools]]\nnumber = 2\ndiameter_mm = 3\ncolour = 1\n",
            "tools[1].colour: unknown key; valid keys: number, kind, diameter_mm, "
            "corner_radius_mm, tip_diameter_mm, flutes, helix_deg, flute_length_mm, "
            "tip_angle_deg, web_mm, pitch_mm, length_mm, x_offset_mm, orientation",
        ),
    ],
)
def test_unknown_keys_are_named_with_their_path(tmp_path: Path, text: str, expected: str) -> None:
    assert load_error(tmp_path, text) == expected


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (
            "[machine.axes.x]\nmin_mm = -10.0\nmax_mm = -20.0\n",
            "machine.axes.x.max_mm: must be greater than min_mm (-10.0); got -20.0",
        ),
        (
            "[machine]\nrapid_mm_min = 0\n",
            "machine.rapid_mm_min: must be >= 1 and <= 1000000; got 0",
        ),
        ("[machine]\nkind = 'drill'\n", "machine.kind: must be 'mill' or 'lathe'; got 'drill'"),
        (
            "[machine]\nrapid_mm_min = nan\n",
            "machine.rapid_mm_min: must be a finite number; got nan",
        ),
        ("[machine]\ng28_home_mm = [1, 2]\n", "machine.g28_home_mm[2]: item is missing"),
        (
            "[machine.axes.y]\nmax_accel_mm_s2 = -1\n",
            "machine.axes.y.max_accel_mm_s2: must be >= 1 and <= 1000000; got -1",
        ),
        ("[[tools]]\nnumber = 1\n", "tools[0].diameter_mm: required key is missing"),
        (
            "[[tools]]\nnumber = 1\ndiameter_mm = 10\nkind = 'ball'\ncorner_radius_mm = 2\n",
            "tools[0].corner_radius_mm: must be diameter_mm/2 (5.0) for kind 'ball'; got 2",
        ),
        (
            "[[tools]]\nnumber = 1\ndiameter_mm = 10\nkind = 'bull'\n",
            "tools[0].corner_radius_mm: must be given for kind 'bull', greater than 0 and less "
            "than diameter_mm/2 (5.0)",
        ),
        (
            "[[tools]]\nnumber = 1\ndiameter_mm = 10\ncorner_radius_mm = 1\n",
            "tools[0].corner_radius_mm: must be 0 for kind 'flat' (use kind 'bull' for a corner "
            "radius); got 1",
        ),
        (
            "[[tools]]\nnumber = 1\ndiameter_mm = 10\nhelix_deg = 90\n",
            "tools[0].helix_deg: must be >= 0 and <= 89; got 90",
        ),
        (
            "[[tools]]\nnumber = 3\ndiameter_mm = 1\n[[tools]]\nnumber = 3\ndiameter_mm = 2\n",
            "tools: tool number 3 is given twice, in tools[0] and tools[1]",
        ),
        (
            "[stock]\nmin_mm = [0, 0, 0]\nmax_mm = [10, 10, -5]\n",
            "stock.max_mm: z must be greater than min_mm's z (0.0)",
        ),
        (
            "[[tools]]\nnumber = 1\ndiameter_mm = 1\norientation = 10\n",
            "tools[0].orientation: must be >= 0 and <= 9; got 10",
        ),
        (
            "[machine]\nmax_spindle_rpm = 0\n",
            "machine.max_spindle_rpm: must be >= 1 and <= 200000; got 0",
        ),
        ("tool_table_units = 'cm'\n", "tool_table_units: must be 'mm' or 'inch'; got 'cm'"),
        (
            "[material]\ndensity_kg_m3 = 'heavy'\n",
            "material.density_kg_m3: must be a valid number, "
            "unable to parse string as a number; got 'heavy'",
        ),
    ],
)
def test_bad_values_name_key_bound_and_value(tmp_path: Path, text: str, expected: str) -> None:
    assert load_error(tmp_path, text) == expected


def test_several_problems_are_counted_on_one_line(tmp_path: Path) -> None:
    message = load_error(tmp_path, "[machine]\nrapid_mm_min = -1\nkind = 'x'\nfoo = 1\n")
    assert re.fullmatch(r"machine\.kind: .* \(and 2 more problems\)", message)


def test_toml_syntax_error_is_one_line(tmp_path: Path) -> None:
    message = load_error(tmp_path, "[machine\nname = 1\n")
    assert message.startswith("invalid TOML: ")
    assert "line 1" in message


def test_unreadable_files(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"none\.toml: cannot read configuration: No such file"):
        load_config(tmp_path / "none.toml")
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"name = '\xff'\n")
    with pytest.raises(ConfigError, match=r"binary\.toml: not UTF-8 text \(byte 8\)"):
        load_config(binary)


def test_models_built_in_code_are_validated_too() -> None:
    with pytest.raises(ValueError, match="greater than or equal to 0.01"):
        ToolConfig(number=1, diameter_mm=-1.0)
    tool = ToolConfig(number=2, kind="ball", diameter_mm=8.0)
    assert math.isclose(tool.corner_radius_mm or 0.0, 4.0)
    assert tool.tool_entry() == ToolEntry(number=2, diameter_mm=8.0)


@pytest.mark.parametrize(
    ("kind", "key", "value", "allowed"),
    [
        ("flat", "pitch_mm", 1.0, "'tap'"),
        ("bull", "web_mm", 1.0, "'drill'"),
        ("ball", "tip_angle_deg", 90.0, "'conical', 'snub' or 'drill'"),
    ],
)
def test_a_key_of_another_tool_kind_is_named_with_the_kinds_it_belongs_to(
    kind: str, key: str, value: float, allowed: str
) -> None:
    extra = {"corner_radius_mm": 1.0} if kind == "bull" else {}
    with pytest.raises(ValueError) as caught:
        ToolConfig.model_validate(
            {"number": 1, "kind": kind, "diameter_mm": 10.0, key: value, **extra}
        )
    assert f"is only for kind {allowed}; remove it for kind '{kind}'" in str(caught.value)
