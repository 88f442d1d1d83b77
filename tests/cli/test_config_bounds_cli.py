"""The commands refuse out-of-range configurations and options with one line and exit 2.

The command-line side of tests/config/test_bounds.py (issue 11): the values that once crashed
or hung the simulation (a tool with ``flute_length_mm = 1e308``, tiny cycle times, a huge
stock, tiny and huge dexel densities) and out-of-range physics options.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from cnctwin.cli.app import run

CONFIG = """
[[tools]]
number = 1
diameter_mm = 6.0
flute_length_mm = 15.0
flutes = 2

[stock]
min_mm = [0.0, 0.0, -5.0]
max_mm = [20.0, 10.0, 0.0]

[material]
name = "AA6060-T6"

[simulation]
density_per_mm = 2.0
"""

PROGRAM = "G21 G90 G94\nT1 M6\nS8000 M3\nG0 X-5 Y5 Z2\nG1 Z-1 F300\nG1 X25 F900\nM30\n"
SLOT = Path(__file__).resolve().parents[2] / "examples" / "stability" / "insperger_slot.toml"


@pytest.fixture
def program(tmp_path: Path) -> Path:
    path = tmp_path / "p.ngc"
    path.write_text(PROGRAM)
    return path


def _run(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str]:
    capsys.readouterr()
    code = run(list(args))
    return code, capsys.readouterr().err


@pytest.mark.parametrize(
    ("extra", "change", "message"),
    [
        (["--cycle-ms", "0.0001"], ("", ""), "--cycle-ms 0.0001: give 0.1 <= cycle <= 1000 ms"),
        (["--density", "0.0001"], ("", ""), "--density 0.0001: give 0.1 <= density <= 100"),
        (["--density", "nan"], ("", ""), "--density nan"),
        ([], ("max_mm = [20.0, 10.0, 0.0]", "max_mm = [1e5, 1e5, 1e5]"), "rays"),
        ([], ("flute_length_mm = 15.0", "flute_length_mm = 1e308"), "<= 2000"),
    ],
)
@pytest.mark.parametrize("command", ["simulate", "signals"])
def test_commands_refuse_with_exit_2(
    tmp_path: Path,
    program: Path,
    capsys: pytest.CaptureFixture[str],
    command: str,
    extra: list[str],
    change: tuple[str, str],
    message: str,
) -> None:
    config = tmp_path / "c.toml"
    config.write_text(CONFIG.replace(*change) if change[0] else CONFIG)
    code, err = _run(capsys, command, str(program), "--config", str(config), "--json", *extra)
    assert code == 2
    assert message in err and len(err.strip().splitlines()) == 1


def test_a_long_fluted_tool_in_code_cuts_as_the_config_would(
    tmp_path: Path, program: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # The segfault's path end to end, at the longest valid fluted length.
    config = tmp_path / "c.toml"
    config.write_text(CONFIG.replace("flute_length_mm = 15.0", "flute_length_mm = 2000.0"))
    capsys.readouterr()
    assert run(["simulate", str(program), "--config", str(config), "--json"]) == 0
    assert math.isfinite(float(capsys.readouterr().out.split('"removed_volume_mm3": ')[1][:8]))


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            "forces --diameter-mm 10 --teeth 1000000000 --helix-deg 30 --ae-mm 5 --ap-mm 2 "
            "--fz-mm 0.1 --rpm 8000 --material AA6060-T6",
            "--teeth 1000000000; give an integer from 1 to 100",
        ),
        (
            "forces --diameter-mm 10 --teeth 3 --helix-deg 30 --ae-mm 5 --ap-mm 2 "
            "--fz-mm 0.1 --rpm 1e308 --material AA6060-T6",
            "--rpm 1e+308: give a value > 0 and <= 200000 rpm",
        ),
        (
            f"vibration simulate --config {SLOT} --rpm 1e-300 --depth-mm 1 --feed-mm 0.05",
            "--rpm 1e-300: give a value > 1 and <= 200000 rpm",
        ),
        (
            f"vibration simulate --config {SLOT} --rpm 9000 --depth-mm 1e308 --feed-mm 0.05",
            "--depth-mm 1e+308: give a value > 0 and <= 1000 mm",
        ),
    ],
)
def test_physics_options_are_bounded(
    capsys: pytest.CaptureFixture[str], args: str, message: str
) -> None:
    code, err = _run(capsys, *args.split(), "--json")
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1


def test_a_speed_list_is_bounded(capsys: pytest.CaptureFixture[str]) -> None:
    code, err = _run(capsys, "stability", "lobes", "--config", str(SLOT), "--rpm", "1e308,5")
    assert code == 2 and "each > 0 and <= 200000" in err


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--window-s", "1e308"], "--window-s 1e+308: give a value > 0 and <= 3600 s"),
        (["--rpm", "1e308"], "--rpm 1e+308: give a value > 1 and <= 200000 rpm"),
        (["--teeth", "1000000000"], "--teeth 1000000000; give an integer from 1 to 100"),
    ],
)
def test_chatter_detection_options_are_bounded(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], message: str
) -> None:
    signal = tmp_path / "s.csv"
    t = np.arange(0.0, 0.2, 1e-4)
    np.savetxt(signal, np.column_stack((t, np.sin(600 * np.pi * t))), delimiter=",",
               header="t_s,force_n", comments="")  # fmt: skip
    options = {"--rpm": "9000", "--teeth": "2"}
    for name, value in zip(extra[::2], extra[1::2], strict=True):
        options[name] = value
    args = [item for pair in options.items() for item in pair]
    code, err = _run(capsys, "chatter", "detect", str(signal), *args, "--json")
    assert code == 2 and message in err
