"""``cnctwin wear compensate --write-offset``: the part is recorded, the write obeys [control]."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from cnctwin.cli.app import run


def test_the_cli_records_the_part_and_blocks_the_write_with_control_disabled(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = str(tmp_path / "shop.db")
    shipped = Path(__file__).resolve().parents[2] / "examples/wear/lathe_offset.toml"
    assert run(["wear", "mount", "--db", db, "--tool", "T1", "--target-mm", "20"]) == 0
    argv = ["wear", "compensate", "--db", db, "--tool", "T1", "--measurement", "20.004"]
    assert run([*argv, "--write-offset", str(shipped)]) == 2  # no --machine-tool
    capsys.readouterr()
    assert run([*argv, "--write-offset", str(shipped), "--machine-tool", "1", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["part"] == 1
    assert report["offset_write"]["outcome"] == "blocked"
    assert "control disabled" in report["offset_write"]["note"]
