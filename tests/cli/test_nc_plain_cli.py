"""Plain ``nc inspect``/``nc trace`` invocations run without typer, with typer's results.

:mod:`cnctwin.cli.nc_argv` reads them; anything it does not take goes to typer. These tests
compare the two paths on the same command lines, check that the reader leaves everything
else to typer, that its options are those typer declares, and that the plain path imports
neither typer nor pydantic (nor numpy for a short program).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from cnctwin.cli import run
from cnctwin.cli.app import load_command
from cnctwin.cli.nc_argv import plain_nc_command
from cnctwin.cli.nc_work import GUARD_LIMITS
from cnctwin.examples import example_file

PROGRAM = str(example_file("demo.ngc"))
CONFIG = str(example_file("demo.toml"))


def _both(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, args: list[str]
) -> tuple[tuple[int, str, str], tuple[int, str, str]]:
    """(exit code, stdout, stderr) of ``args`` read plainly, then through typer."""
    assert plain_nc_command(args) is not None, args
    plain = (run(args), *capsys.readouterr())
    with monkeypatch.context() as patched:
        patched.setattr("cnctwin.cli.nc_argv.plain_nc_command", lambda _: None)
        typed = (run(args), *capsys.readouterr())
    return plain, typed


@pytest.mark.parametrize(
    "args",
    [
        ["nc", "inspect", "--json", PROGRAM],
        ["nc", "inspect", PROGRAM],
        [PROGRAM, "--json", "--config", CONFIG],
        ["--json", f"--config={CONFIG}", "--max-segments", "100000", PROGRAM],
        ["-c", CONFIG, "--max-bytes=5000000", "--max-repeated-lines", "0", PROGRAM],
        ["--max-segments", "3", PROGRAM],
        ["--max-bytes", "10", "--json", PROGRAM],
        ["--json", "/no/such/program.ngc"],
        ["--json", "--config", "/no/such/config.toml", PROGRAM],
    ],
)
def test_inspect_read_plainly_ends_as_under_typer(
    args: list[str], capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    line = args if args[:1] == ["nc"] else ["nc", "inspect", *args]
    plain, typed = _both(capsys, monkeypatch, line)
    assert plain == typed


@pytest.mark.parametrize(
    "args",
    [
        [PROGRAM],
        ["--frame", "machine", "-c", CONFIG, PROGRAM],
        [PROGRAM, "--frame=program", "--max-segments", "5"],
    ],
)
def test_trace_read_plainly_ends_as_under_typer(
    args: list[str], capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    plain, typed = _both(capsys, monkeypatch, ["nc", "trace", *args])
    assert plain == typed
    assert plain[0] != 0 or "STRAIGHT_TRAVERSE(" in plain[1]


def test_debug_is_read_plainly_and_shows_the_traceback(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    args = ["--debug", "nc", "inspect", "--json", "/no/such/program.ngc"]
    plain, typed = _both(capsys, monkeypatch, args)
    assert plain[0] == typed[0] == 2
    # The frames differ (typer's are not there); the error's line is the same.
    assert plain[2].startswith("Traceback (most recent call last):")
    assert plain[2].splitlines()[-1] == typed[2].splitlines()[-1]


@pytest.mark.parametrize(
    "args",
    [
        ["nc", "inspect", "--help"],
        ["nc", "inspect"],
        ["nc", "inspect", PROGRAM, PROGRAM],
        ["nc", "inspect", "--json", "--json", PROGRAM],
        ["nc", "inspect", "--json=1", PROGRAM],
        ["nc", "inspect", "--plot", "out.png", PROGRAM],
        ["nc", "inspect", "--frame", "machine", PROGRAM],
        ["nc", "inspect", "--", PROGRAM],
        ["nc", "inspect", "-"],
        ["nc", "inspect", ""],
        ["nc", "inspect", "-c", CONFIG, "--config", CONFIG, PROGRAM],
        ["nc", "inspect", f"-c{CONFIG}", PROGRAM],
        ["nc", "inspect", f"-c={CONFIG}", PROGRAM],
        ["nc", "inspect", "--config", "", PROGRAM],
        ["nc", "inspect", "--config", "--json", PROGRAM],
        ["nc", "inspect", PROGRAM, "--config"],
        ["nc", "inspect", "--max-segments", "0", PROGRAM],
        ["nc", "inspect", "--max-segments", "007", PROGRAM],
        ["nc", "inspect", "--max-segments", "1.0", PROGRAM],
        ["nc", "inspect", "--max-segments", "+3", PROGRAM],
        ["nc", "inspect", "--max-segments", "-1", PROGRAM],
        ["nc", "inspect", "--max-segments", str(GUARD_LIMITS["--max-segments"][2] + 1), PROGRAM],
        ["nc", "inspect", "--max-repeated-lines", "", PROGRAM],
        ["nc", "trace", "--json", PROGRAM],
        ["nc", "trace", "--frame", "Machine", PROGRAM],
        ["nc", "trace", "--frame", "", PROGRAM],
        ["nc", "--debug", "inspect", PROGRAM],
        ["--debug", "--debug", "nc", "inspect", PROGRAM],
        ["--version", "nc", "inspect", PROGRAM],
        ["nc", "plot", PROGRAM],
        ["simulate", PROGRAM],
        [],
    ],
)
def test_what_typer_would_refuse_or_read_otherwise_is_left_to_it(args: list[str]) -> None:
    assert plain_nc_command(args) is None


def test_a_file_that_cannot_be_read_is_left_to_typer(tmp_path: Path) -> None:
    secret = tmp_path / "secret.ngc"
    secret.write_text("G0 X1\n")
    secret.chmod(0)
    try:
        if os.access(secret, os.R_OK):
            pytest.skip("this user reads any file (root)")
        assert plain_nc_command(["nc", "inspect", str(secret)]) is None
        assert plain_nc_command(["nc", "inspect", "-c", str(secret), PROGRAM]) is None
    finally:
        secret.chmod(0o600)


def test_shell_completion_is_left_to_typer(monkeypatch: pytest.MonkeyPatch) -> None:
    assert plain_nc_command(["nc", "inspect", PROGRAM]) is not None
    monkeypatch.setenv("_CNCTWIN_COMPLETE", "bash_complete")
    assert plain_nc_command(["nc", "inspect", PROGRAM]) is None


def test_the_plain_reader_knows_the_options_typer_declares() -> None:
    from cnctwin.cli import nc_argv

    group = load_command("nc")
    for name in ("inspect", "trace"):
        params = {p.opts[0]: p for p in group.commands[name].params if p.opts[0].startswith("-")}
        known = {
            *nc_argv._FLAGS[name],
            *nc_argv._CHOICES[name],
            *set(nc_argv._PATHS.values()),
            *nc_argv._COUNTS,
        }
        # --plot is the one option left to typer (it draws with matplotlib anyway).
        assert set(params) - known == ({"--plot"} if name == "inspect" else set())
        assert known <= set(params)
        assert params["--config"].opts == [
            option for option, long in nc_argv._PATHS.items() if long == "--config"
        ]
        for option in nc_argv._FLAGS[name]:
            assert params[option].is_flag
        for option, values in nc_argv._CHOICES[name].items():
            assert tuple(params[option].type_descriptor.choices) == values
        for option in nc_argv._COUNTS:
            info = params[option].type_descriptor.parameter_info
            default, least, greatest = GUARD_LIMITS[option]
            assert (params[option].default, info.min, info.max) == (default, least, greatest)


_PROBE = """
import json, sys
from cnctwin.cli import run
code = run(sys.argv[1:])
print(json.dumps([code, sorted(sys.modules)]))
"""


@pytest.mark.parametrize("command", [["inspect", "--json"], ["inspect"], ["trace"]])
def test_plain_nc_commands_import_neither_typer_nor_pydantic(
    command: list[str], tmp_path: Path
) -> None:
    # A fresh interpreter: this test process has imported everything already.
    program = tmp_path / "short.ngc"
    program.write_text("G0 X0 Y0\nG1 X1 Y2 F100\nG2 X3 Y2 I1 J0\nM2\n")
    done = subprocess.run(
        [sys.executable, "-c", _PROBE, "nc", *command, str(program)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    code, modules = json.loads(done.stdout.splitlines()[-1])
    assert code == 0, done.stderr
    heavy = {"typer", "click", "pydantic", "pydantic_core", "numpy", "scipy", "cnctwin.config"}
    loaded = {name for name in modules if name in heavy or name.rpartition(".")[0] in heavy}
    assert not loaded, sorted(loaded)


@pytest.mark.parametrize("typer_reads_it", [False, True])
def test_a_closed_output_pipe_ends_with_1_and_no_message(
    typer_reads_it: bool, tmp_path: Path
) -> None:
    # `cnctwin nc trace PROGRAM | head -1`: typer's way (exit 1, nothing on stderr) both ways.
    program = tmp_path / "long.ngc"
    program.write_text("".join(f"G1 X{i % 7} Y{i % 5} F100\n" for i in range(20_000)))
    config = [f"-c{CONFIG}"] if typer_reads_it else []  # "-cFILE": left to typer
    assert (plain_nc_command(["nc", "trace", *config, str(program)]) is None) is typer_reads_it
    done = subprocess.Popen(
        [sys.executable, "-m", "cnctwin", "nc", "trace", *config, str(program)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    assert done.stdout is not None and done.stderr is not None
    assert done.stdout.readline()
    done.stdout.close()
    assert (done.wait(timeout=120), done.stderr.read()) == (1, b"")


def test_importing_the_typer_root_module_keeps_the_root_exported() -> None:
    # Python binds a submodule on its package: cnctwin.cli.app must stay the typer root.
    probe = (
        "import typer, cnctwin.cli.app, cnctwin.cli.run, cnctwin.cli as cli\n"
        "print(isinstance(cli.app, typer.Typer), callable(cli.run) and cli.run is cli.main"
        " .__globals__['run'])"
    )
    done = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=120
    )
    assert done.stdout.split() == ["True", "True"], done.stderr


def test_a_trace_prints_every_line_before_an_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The trace is written some lines at a time: those before a bad line still come out,
    then the one-line error, exit 2 (a run of 300 moves read in bulk, then single lines)."""
    moves = "".join(f"G1 X{i * 0.5:.1f} Y{i % 7}\n" for i in range(300))
    program = tmp_path / "bad.ngc"
    program.write_text(f"G21 G90 G94 F500\n{moves}G0 Z5\nG1 X1 F-5\nM2\n")
    assert run(["nc", "trace", str(program)]) == 2
    out, err = capsys.readouterr()
    lines = out.splitlines()
    assert len(lines) == 301
    assert lines[0] == "2 STRAIGHT_FEED(0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000)"
    assert lines[-1] == "302 STRAIGHT_TRAVERSE(149.5000, 5.0000, 5.0000, 0.0000, 0.0000, 0.0000)"
    assert err.count("\n") == 1 and "bad.ngc:303: feed rate F-5" in err, err
