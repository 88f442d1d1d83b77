"""The command line: exit codes, one-line errors, --json, --plot, trace, demo."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from cnctwin.cli import run
from cnctwin.examples import example_file

PROGRAM = str(example_file("demo.ngc"))
CONFIG = str(example_file("demo.toml"))
INSPECT_KEYS = [
    "lines",
    "motion_blocks",
    "feed_length_mm",
    "rapid_length_mm",
    "machining_time_s",
    "rapid_time_s",
    "dwell_time_s",
    "total_time_s",
    "bounds_mm",
    "tools",
    "units",
    "warnings",
    "file",
]


def cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = run(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_inspect_json_is_one_object_with_the_keys(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = cli(capsys, "nc", "inspect", PROGRAM, "--config", CONFIG, "--json")
    assert (code, err) == (0, "")
    assert out.count("\n") == 1
    report = json.loads(out)
    assert list(report) == INSPECT_KEYS
    assert report["units"] == "mm"
    assert report["tools"] == [1, 2]
    assert report["file"] == PROGRAM
    # Four 17 mm drilling strokes from R2 to Z-15 reach 15 mm below the stock top (G54 Z-300).
    assert report["bounds_mm"]["min"][2] == pytest.approx(-315.0)
    assert report["dwell_time_s"] == pytest.approx(0.5)
    assert report["total_time_s"] == pytest.approx(
        report["machining_time_s"] + report["rapid_time_s"] + report["dwell_time_s"]
    )


def test_inspect_table_and_plot(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    png = tmp_path / "path.png"
    code, out, err = cli(capsys, "nc", "inspect", PROGRAM, "--config", CONFIG, "--plot", str(png))
    assert (code, err) == (0, "")
    assert "machining time" in out
    assert "T1, T2" in out
    assert png.read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
    assert png.stat().st_size > 10_000


def test_inspect_without_config_uses_defaults(capsys, tmp_path: Path) -> None:
    program = tmp_path / "p.ngc"
    program.write_text("G20 G90\nG0 X1 Y1\nG1 X2 F10\nG1 X3\nM2\n")
    code, out, err = cli(capsys, "nc", "inspect", str(program), "--json")
    report = json.loads(out)
    assert (code, err) == (0, "")
    assert report["units"] == "inch"
    assert report["feed_length_mm"] == pytest.approx(2 * 25.4)
    assert report["rapid_time_s"] == pytest.approx(60 * 25.4 * 2**0.5 / 10_000)  # default rapid


def test_nc_error_is_one_line_with_file_and_line(capsys, tmp_path: Path) -> None:
    program = tmp_path / "bad.ngc"
    program.write_text("G21\nG0 X1\nG12 I5\n")
    code, out, err = cli(capsys, "nc", "inspect", str(program))
    assert code == 2
    assert out == ""
    assert err.count("\n") == 1
    assert err.startswith(f"{program}:3: ")


def test_missing_program_is_one_line(capsys, tmp_path: Path) -> None:
    missing = tmp_path / "none.ngc"
    code, _, err = cli(capsys, "nc", "trace", str(missing))
    assert code == 2
    assert err == f"{missing}: No such file or directory\n"


def test_bad_config_key_is_one_line(capsys, tmp_path: Path) -> None:
    config = tmp_path / "bad.toml"
    config.write_text("[machine]\nrapid = 5\n")
    code, _, err = cli(capsys, "nc", "inspect", PROGRAM, "--config", str(config), "--json")
    assert code == 2
    assert err.startswith(f"{config}: machine.rapid: unknown key; valid keys: name, kind,")
    assert err.count("\n") == 1


def test_internal_error_hints_at_debug(capsys, monkeypatch: pytest.MonkeyPatch) -> None:
    def broken(*args: object, **kwargs: object) -> None:
        raise RuntimeError("boom")

    monkeypatch.setattr("cnctwin.cli.nc_work.summarize", broken)
    code, _, err = cli(capsys, "nc", "inspect", PROGRAM)
    assert code == 1
    assert err == "internal error: RuntimeError: boom (re-run with --debug for the traceback)\n"
    code, _, err = cli(capsys, "--debug", "nc", "inspect", PROGRAM)
    assert code == 1
    assert err.startswith("Traceback (most recent call last):")
    assert err.endswith(
        "internal error: RuntimeError: boom (re-run with --debug for the traceback)\n"
    )


def test_trace_prints_canonical_calls(capsys) -> None:
    code, out, err = cli(capsys, "nc", "trace", PROGRAM, "--config", CONFIG)
    lines = out.splitlines()
    assert (code, err) == (0, "")
    assert any(" ARC_FEED(" in line for line in lines)
    assert any(" DWELL(0.5" in line for line in lines)
    assert all(line.split(" ", 1)[0].isdigit() for line in lines)


def test_demo_is_the_live_twin(capsys) -> None:
    # the whole demo run is in test_demo_cli.py; here: it is the twin, with its options
    code, out, err = cli(capsys, "demo", "--help")
    assert (code, err) == (0, "")
    for option in ("--duration", "--speed", "--db", "--json", "--transport"):
        assert option in out


def test_version_and_usage_errors(capsys) -> None:
    code, out, _ = cli(capsys, "--version")
    assert code == 0
    assert re.fullmatch(r"cnctwin \S+ \(NC interpreter: (compiled|pure Python)\)\n", out), out
    code, _, err = cli(capsys, "nc", "inspect")
    assert code == 2
    assert "Missing argument" in err


def _console_script() -> list[str]:
    script = Path(sys.executable).with_name("cnctwin")
    return [str(script)] if script.exists() else [sys.executable, "-m", "cnctwin"]


@pytest.mark.parametrize("launcher", ["script", "module"])
def test_installed_command_exit_codes(launcher: str, tmp_path: Path) -> None:
    command = _console_script() if launcher == "script" else [sys.executable, "-m", "cnctwin"]
    ok = subprocess.run(
        [*command, "nc", "inspect", PROGRAM, "--json"],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert (ok.returncode, ok.stderr) == (0, "")
    assert list(json.loads(ok.stdout)) == INSPECT_KEYS
    bad = subprocess.run(
        [*command, "nc", "inspect", str(tmp_path / "none.ngc")],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert bad.returncode == 2
    assert bad.stdout == ""
    assert bad.stderr == f"{tmp_path / 'none.ngc'}: No such file or directory\n"


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["nc", "inspect", "--bogus", "x"], "No such option: --bogus (see --help)"),
        (["nc", "inspect"], "Missing argument 'program'. (see --help)"),
        (
            ["wear", "simulate-lathe", "--test", "9"],
            "Invalid value for '--test': Input should be less than or equal to 6 (see --help)",
        ),
    ],
)
def test_usage_errors_are_one_line(args: list[str], message: str) -> None:
    done = subprocess.run(
        [sys.executable, "-m", "cnctwin", *args], capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 2
    assert done.stderr == message + "\n"


@pytest.mark.parametrize(("error", "shown"), [(KeyboardInterrupt, False), (ValueError, True)])
def test_ctrl_c_python_cannot_raise_is_not_printed_as_a_traceback(
    error: type[BaseException], shown: bool, capsys: pytest.CaptureFixture[str]
) -> None:
    # Ctrl-C inside a C callback (numba compiling) reaches sys.unraisablehook; the command
    # still ends with 130, so the console script's hook keeps the traceback off stderr
    import sys

    from cnctwin.cli._entry import _unraisable

    class Raises:
        def __del__(self) -> None:
            raise error("in a callback")

    previous, sys.unraisablehook = sys.unraisablehook, _unraisable
    try:
        thing = Raises()
        del thing
    finally:
        sys.unraisablehook = previous
    assert ("Exception ignored" in capsys.readouterr().err) is shown
