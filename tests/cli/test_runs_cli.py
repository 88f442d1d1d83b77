"""``cnctwin runs list|show|export``: what the historian holds, as tables, JSON and files;
one-line errors with exit 2."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from cnctwin.cli import run
from cnctwin.store import Historian


def cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = run(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def db(tmp_path: Path) -> Path:
    """A historian with two runs: a finished one with an event and a decision, and an
    interrupted one."""
    path = tmp_path / "h.sqlite"
    with Historian.open(path) as h:
        first = h.start_run({"program": "pocket.nc", "endpoint": "opc.tcp://127.0.0.1:4840"})
        for i in range(80):
            h.record_samples(first, i * 0.0125, {"x_mm": i * 0.1, "force_x_n": -3.0 * i})
            h.record_prediction(first, i * 0.0125, {"force_x_n": -3.0 * i + 0.5})
        h.record_event(first, 0.5, "anomaly", "force below the band", {"force_n": 12.0})
        h.record_decision(first, 0.5, "hole", "stop", 1.0, "force 12 N < 80 N", True, 1.0)
        h.end_run(first, "stopped", {"stop_reaction_ms": 4.2})
        second = h.start_run({"program": "slot.nc"})
        h.record_samples(second, 0.0, {"x_mm": 1.0})
    return path


def test_list_json(capsys: pytest.CaptureFixture[str], db: Path) -> None:
    code, out, _ = cli(capsys, "runs", "list", "--db", str(db), "--json")
    assert code == 0 and out.count("\n") == 1
    report = json.loads(out)
    assert report["database"] == str(db)
    first, second = report["runs"]
    assert (first["run_id"], first["status"], second["status"]) == (1, "stopped", "running")
    assert first["values"] == 160 and first["predicted_values"] == 80
    assert (first["events"], first["decisions"]) == (1, 1)
    assert first["meta"]["program"] == "pocket.nc"
    assert first["summary"] == {"stop_reaction_ms": 4.2}
    assert second["values"] == 1 and second["ended_at"] is None


def test_list_and_show_tables(capsys: pytest.CaptureFixture[str], db: Path) -> None:
    code, out, _ = cli(capsys, "runs", "list", "--db", str(db))
    assert code == 0 and "pocket.nc" in out and "slot.nc" in out and "running" in out
    code, out, _ = cli(capsys, "runs", "show", "1", "--db", str(db))
    assert code == 0
    assert "force below the band" in out and "hole" in out and "x_mm, force_x_n" in out


def test_show_tables_a_stages_sections(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """A run summary's ``stage_results`` with sections (the roughness stage's) is a table."""
    path = tmp_path / "s.sqlite"
    sections = [
        {"line": 17, "tool": 1, "samples": 167, "ra_mean_um": None, "kin_rz_max_um": 0.70481},
        {"line": 23, "tool": 1, "samples": 125, "ra_mean_um": 1.2345, "kin_rz_max_um": 1.2535},
    ]
    empty = {"line": 29, "tool": 1, "samples": 9, "ra_mean_um": None, "kin_rz_max_um": None}
    with Historian.open(path) as h:
        run_id = h.start_run({"program": "slots.ngc"})
        results = {"roughness": {"sections": sections}, "other": {"sections": [empty]}}
        h.end_run(run_id, "finished", {"stage_results": results})
    code, out, _ = cli(capsys, "runs", "show", "1", "--db", str(path))
    assert code == 0 and "roughness by program section" in out
    assert "summary.stage_results" not in out and "kin rz max um" in out
    # a column without a value is left out
    assert "other by program section" in out and "kin rz" not in out.split("other by")[1]
    rows = [line for line in out.splitlines() if "│ 17" in line or "│ 23" in line]
    assert [[cell.strip() for cell in row.split("│")[1:-1]] for row in rows] == [
        ["17", "1", "167", "-", "0.7048"],
        ["23", "1", "125", "1.234", "1.254"],
    ]


def test_show_json(capsys: pytest.CaptureFixture[str], db: Path) -> None:
    code, out, _ = cli(capsys, "runs", "show", "1", "--db", str(db), "--json")
    assert code == 0
    detail = json.loads(out)
    assert detail["signals"] == ["x_mm", "force_x_n"] and detail["predicted"] == ["force_x_n"]
    (event,) = detail["event_log"]
    assert event["message"] == "force below the band" and event["data"] == {"force_n": 12.0}
    (decision,) = detail["decision_log"]
    assert decision["action"] == "stop" and decision["readback"] == 1.0
    assert decision["accepted"] is True


def test_export_files(capsys: pytest.CaptureFixture[str], db: Path, tmp_path: Path) -> None:
    code, out, _ = cli(capsys, "runs", "export", "1", str(tmp_path / "r.parquet"), "--db", str(db))
    assert code == 0
    assert out.split() == [
        str(tmp_path / f"r{infix}.parquet")
        for infix in ("", ".predictions", ".events", ".decisions")
    ]
    table = pq.read_table(tmp_path / "r.parquet")
    assert table.column_names == ["time_s", "x_mm", "force_x_n"]
    assert np.array_equal(table.column("force_x_n").to_numpy(), -3.0 * np.arange(80))
    code, out, _ = cli(capsys, "runs", "export", "1", str(tmp_path / "r.csv"), "--db", str(db))
    assert code == 0
    lines = (tmp_path / "r.csv").read_text().splitlines()
    assert lines[0] == '"time_s","x_mm","force_x_n"' and len(lines) == 81
    assert lines[2] == "0.0125,0.1,-3"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["runs", "show", "9"], "run 9 is not in the historian"),
        (["runs", "export", "9", "x.csv"], "run 9 is not in the historian"),
        (["runs", "export", "1", "x.xlsx"], "export format 'xlsx' is not supported"),
        (["runs", "show", "one"], "Invalid value for 'run_id'"),
    ],
)
def test_bad_input_is_one_line(
    capsys: pytest.CaptureFixture[str], db: Path, argv: list[str], message: str
) -> None:
    code, out, err = cli(capsys, *argv, "--db", str(db))
    assert code == 2 and out == ""
    assert message in err and err.count("\n") == 1


def test_bad_database_is_one_line(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    junk = tmp_path / "junk.db"
    junk.write_text("not sqlite\n" * 200)
    for db, message in [
        (str(tmp_path / "absent.sqlite"), "no historian database at"),
        (str(junk), "not a readable SQLite database"),
        ("mysql://host/db", "scheme 'mysql' is not supported"),
        ("postgresql://postgres@127.0.0.1:1/none", "cannot connect to PostgreSQL"),
    ]:
        code, out, err = cli(capsys, "runs", "list", "--db", db)
        assert code == 2 and message in err and err.count("\n") == 1, (db, err)
    assert not (tmp_path / "absent.sqlite").exists()  # a read-only command creates nothing
