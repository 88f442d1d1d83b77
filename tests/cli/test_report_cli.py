"""``--report OUT.html``: a path where no report can be written ends in one line, exit 2,
before the command does its work; a good path gets the report."""

from __future__ import annotations

from pathlib import Path

import pytest

from cnctwin.cli import run as cli_run

REPO = Path(__file__).resolve().parents[2]
PACKAGED = REPO / "src" / "cnctwin" / "examples"
STABILITY = REPO / "examples" / "stability" / "insperger_slot.toml"

#: Each command with --report, before the path.
COMMANDS = {
    "simulate": ["simulate", str(PACKAGED / "demo.ngc"), "-c", str(PACKAGED / "demo.toml")],
    "study dexel": ["study", "dexel", "--quick", "--out", "{tmp}/study"],
    "stability lobes": ["stability", "lobes", "--config", str(STABILITY)],
    "stability roadmap": [
        "stability",
        "roadmap",
        str(PACKAGED / "demo.ngc"),
        "-c",
        str(PACKAGED / "demo.toml"),
        "--stability",
        str(STABILITY),
    ],  # fmt: skip
    "wear ekf": ["wear", "ekf", "--synthetic"],
}


def _bad_paths(tmp: Path) -> dict[str, tuple[Path, str]]:
    (tmp / "a_file").write_text("x")
    return {
        "a folder": (tmp, "is a folder"),
        "no such folder": (tmp / "missing" / "r.html", "does not exist"),
        "below a file": (tmp / "a_file" / "r.html", "does not exist"),
        "a read-only place": (Path("/proc/cnctwin-report.html"), "cannot write there"),
    }


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize(
    "case", ["a folder", "no such folder", "below a file", "a read-only place"]
)
def test_unwritable_report_is_one_line(command, case, tmp_path, capsys) -> None:
    path, message = _bad_paths(tmp_path)[case]
    args = [a.replace("{tmp}", str(tmp_path)) for a in COMMANDS[command]]
    assert cli_run([*args, "--report", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"--report {path}" in err and message in err and err.count("\n") == 1, err
    assert not (tmp_path / "study").exists()  # refused before the study ran


def test_report_is_written_and_no_probe_is_left(tmp_path) -> None:
    page = tmp_path / "lobes.html"
    args = ["stability", "lobes", "--config", str(STABILITY), "--method", "zoa", "--points", "20"]
    assert cli_run([*args, "--report", str(page)]) == 0
    assert page.read_text(encoding="utf-8").startswith("<!DOCTYPE html>")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["lobes.html"]
    # An existing file is overwritten.
    page.write_text("old")
    assert cli_run([*args, "--report", str(page)]) == 0
    assert "Plotly.newPlot" in page.read_text(encoding="utf-8")
