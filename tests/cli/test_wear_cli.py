"""``cnctwin wear simulate-lathe``: JSON keys and units, table, plot, bad options."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from cnctwin.cli.wear import app
from cnctwin.wear import run_test

REQUIRED = [
    "parts",
    "parts_before_trusted",
    "max_abs_deviation_um",
    "out_of_tolerance",
    "heritage_used",
]


def invoke(*argv: str) -> tuple[int, str]:
    result = CliRunner().invoke(app, list(argv))
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise result.exception
    return result.exit_code, result.output


def test_json_is_one_object_in_micrometres() -> None:
    code, out = invoke("simulate-lathe", "--test", "2", "--seed", "7", "--json")
    assert code == 0
    assert out.count("\n") == 1
    report = json.loads(out)
    assert set(REQUIRED) <= set(report)
    run = run_test(2, 7)
    assert report["parts"] == 30
    assert report["heritage_used"] is True
    assert report["parts_before_trusted"] == run.parts_before_trusted
    assert report["max_abs_deviation_um"] == pytest.approx(run.max_abs_deviation * 1e6, abs=1e-3)
    assert report["out_of_tolerance"] == 0
    assert report["tolerance_um"] == [-50.0, 50.0]
    assert report["target_mm"] == 13.45
    # The offset in force for part 1 is the heritage's first correction, -5 um.
    assert report["offset_um"][0] == -5.0
    assert len(report["deviation_um"]) == len(report["trusted"]) == 30


def test_parts_and_seed_change_the_run() -> None:
    _, out = invoke("simulate-lathe", "--test", "1", "--parts", "12", "--json")
    short = json.loads(out)
    assert short["parts"] == 12 and len(short["correction_um"]) == 12
    assert short["heritage_used"] is False and short["heritage_slope_um_per_part"] is None
    _, other = invoke("simulate-lathe", "--test", "1", "--parts", "12", "--seed", "1", "--json")
    assert json.loads(other)["deviation_um"] != short["deviation_um"]


def test_table_and_plot(tmp_path: Path) -> None:
    png = tmp_path / "test5.png"
    code, out = invoke("simulate-lathe", "--test", "5", "--plot", str(png))
    assert code == 0
    assert "Test 5, seed 0" in out and "parts out of tolerance" in out
    assert f"plot written to {png}" in out.replace("\n", "")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert png.stat().st_size > 20_000


@pytest.mark.parametrize(
    "argv",
    [
        ["simulate-lathe", "--test", "7"],
        ["simulate-lathe", "--test", "1", "--parts", "0"],
        ["simulate-lathe", "--test", "1", "--seed", "-3"],
        ["simulate-lathe"],
    ],
)
def test_bad_options_are_usage_errors(argv: list[str]) -> None:
    code, _ = invoke(*argv)
    assert code == 2


def test_a_tool_mounted_twice_is_exit_2_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from cnctwin.cli.app import run

    mount = ["wear", "mount", "--db", str(tmp_path / "w.db"), "--tool", "T7", "--target-mm", "20"]
    assert run(mount) == 0
    capsys.readouterr()
    assert run(mount) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "internal error" not in err
    assert "'T7'" in err and "already mounted" in err
