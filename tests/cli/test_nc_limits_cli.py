"""``cnctwin nc inspect`` and ``nc trace`` on hostile files: exit 2 and one line, strict JSON.

The command-line side of tests/nc/test_limits.py: binary files, files over the size limit,
devices and FIFOs, programs the interpreter refuses, and the ``--json`` output.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import pytest

from cnctwin.cli.app import run


def inspect(tmp_path: Path, capsys: pytest.CaptureFixture[str], data: bytes, *args: str):
    program = tmp_path / "p.ngc"
    program.write_bytes(data)
    code = run(["nc", "inspect", str(program), "--json", *args])
    out, err = capsys.readouterr()
    return code, out, err


def strict_json(text: str) -> object:
    def refuse(constant: str) -> object:
        raise AssertionError(f"{constant} is not JSON")

    return json.loads(text, parse_constant=refuse)


@pytest.mark.parametrize(
    ("data", "needle"),
    [
        (b"G0 X1\n" + b"\0" * 100, "NUL byte at byte offset 6"),
        (b"\x7fELF\x02\x01\x01\0\0\0", "binary file"),
    ],
)
def test_binary_files_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], data: bytes, needle: str
) -> None:
    code, out, err = inspect(tmp_path, capsys, data)
    assert code == 2 and out == ""
    assert needle in err and err.count("\n") == 1


def test_a_file_over_the_size_limit_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, _, err = inspect(tmp_path, capsys, b"G0 X1\n" * 100, "--max-bytes", "500")
    assert code == 2 and "the file has 600 bytes; at most 500" in err


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="no /dev/zero")
def test_dev_zero_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    assert run(["nc", "inspect", "/dev/zero"]) == 2
    assert "not a regular file" in capsys.readouterr().err


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_fifo_is_refused_without_waiting_for_a_writer(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fifo = tmp_path / "pipe.ngc"
    os.mkfifo(fifo)
    assert run(["nc", "trace", str(fifo)]) == 2
    assert "not a regular file" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("program", "needle"),
    [
        (b"G21 G90\nG0 X" + b"9" * 400 + b"\n", "p.ngc:2: number"),
        (b"G21 G90 F100\nG0 X0 Y0\nG2 X10 Y0 R1e300\n", "p.ngc:3:"),
        (b"G21 G90 F100 S1000 M3\nG83 X0 Y0 Z-100000 R1 Q0.0001\n", "pecks"),
        (b"o1 repeat [1000000000]\nG0 X1\no1 endrepeat\n", "repeat count 1e+09"),
        (b"G0 X[10**400]\n", "overflows"),
    ],
)
def test_cli_reports_bad_programs_in_one_line_with_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], program: bytes, needle: str
) -> None:
    code, out, err = inspect(tmp_path, capsys, program)
    assert code == 2 and out == ""
    assert needle in err and err.count("\n") == 1 and "Traceback" not in err


def test_cli_max_segments_option(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = b"G21\n" + b"G0 X1\nG0 X2\n" * 10
    code, out, _ = inspect(tmp_path, capsys, data, "--max-segments", "20")
    assert code == 0 and strict_json(out)["motion_blocks"] == 20  # type: ignore[index]
    code, _, err = inspect(tmp_path, capsys, data, "--max-segments", "19")
    assert code == 2 and "p.ngc:21: the program produces more than 19" in err


def test_inspect_json_is_strict_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = inspect(tmp_path, capsys, b"G21 G90 F100\r\nG1 X10 Y10\rG0 Z5\nM2\n")
    assert code == 0
    report = strict_json(out)
    assert report["lines"] == 4  # type: ignore[index]
    assert report["feed_length_mm"] == pytest.approx(math.hypot(10.0, 10.0))  # type: ignore[index]
