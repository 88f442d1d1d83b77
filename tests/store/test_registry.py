"""The SQLite twin registry: state survives restarts, bad input is refused and not stored."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from cnctwin.errors import DataError
from cnctwin.store import TwinRegistry
from cnctwin.wear.compensation import ManufacturingParameters

UM = 1e-6
PARAMS = ManufacturingParameters("C45", "CNMG 120408", 200.0 / 60.0, 0.2e-3, 1.0e-3)
TARGET = 13.45e-3


def _run_tool(registry: TwinRegistry, tool: str, drift_um: float, parts: int) -> list[float]:
    """Make parts with a drift of ``drift_um`` per part, applying every correction given."""
    offset = registry.tools("L1")[-1].twin.offset
    true_deviations = []
    for part in range(1, parts + 1):
        deviation = drift_um * UM * part + offset  # what the lathe makes with the offset
        obs = registry.record("L1", tool, TARGET + deviation)
        offset = obs.offset
        true_deviations.append(deviation)
    return true_deviations


def test_heritage_survives_a_restart(tmp_path: Path) -> None:
    db = tmp_path / "twins.db"
    with TwinRegistry(db) as registry:
        registry.mount(
            "L1", "T1", target_m=TARGET, tolerance_m=(-50 * UM, 50 * UM), parameters=PARAMS
        )
        _run_tool(registry, "T1", 3.0, 20)
        retired = registry.retire("L1", "T1")
        assert retired.twin.slope == pytest.approx(3.0 * UM, rel=1e-9)  # no scatter: exact
    # A new process: the retired twin's drift is inherited from the file.
    with TwinRegistry(db) as registry:
        record = registry.mount(
            "L1", "T2", target_m=TARGET, tolerance_m=(-50 * UM, 50 * UM), parameters=PARAMS
        )
        assert record.twin.heritage is not None and record.twin.heritage.tool_id == "T1"
        assert record.twin.offset == pytest.approx(-3.0 * UM)  # corrected before part 1
        deviations = _run_tool(registry, "T2", 3.0, 10)
        assert max(abs(d) for d in deviations) < 1e-12  # heritage keeps every part on target
        history = registry.history("L1")
        assert [r.tool_id for r in history] == ["T1"] * 20 + ["T2"] * 10
        assert [t.state for t in registry.tools("L1")] == ["retired", "active"]


def test_bad_measurements_are_refused_and_not_stored(tmp_path: Path) -> None:
    with TwinRegistry(tmp_path / "twins.db") as registry:
        registry.mount("L1", "T1", target_m=TARGET, tolerance_m=(-20 * UM, 20 * UM))
        with pytest.raises(DataError, match="absurd"):
            registry.record("L1", "T1", TARGET + 2e-3)
        with pytest.raises(DataError, match="not a finite"):
            registry.record("L1", "T1", float("nan"))
        with pytest.raises(DataError, match="not mounted"):
            registry.record("L1", "T9", TARGET)
        assert registry.history("L1") == []
        assert registry.tools("L1")[0].twin.count == 0
        with pytest.raises(DataError, match="low < high"):
            registry.mount("L1", "T2", target_m=TARGET, tolerance_m=(5 * UM, -5 * UM))


def test_a_file_that_is_not_a_registry_is_a_clear_error(tmp_path: Path) -> None:
    junk = tmp_path / "junk.db"
    junk.write_bytes(b"not sqlite at all" * 100)
    with pytest.raises(DataError, match="not a cnctwin registry"):
        TwinRegistry(junk)


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "cnctwin", "wear", *args],
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_compensate_from_the_command_line(tmp_path: Path) -> None:
    db = str(tmp_path / "twins.db")
    mounted = _cli("mount", "--db", db, "--tool", "T1", "--target-mm", "13.45", "--json")
    assert mounted.returncode == 0, mounted.stderr
    offset_um = 0.0
    for part in range(1, 9):
        measured_mm = 13.45 + (2.0 * part + offset_um) * 1e-3
        done = _cli(
            "compensate",
            "--db",
            db,
            "--tool",
            "T1",
            "--measurement",
            f"{measured_mm:.6f}",
            "--json",
        )
        assert done.returncode == 0, done.stderr
        report = json.loads(done.stdout)
        offset_um = report["offset_um"]
    assert report["part"] == 8 and report["slope_um_per_part"] == pytest.approx(2.0, abs=1e-3)
    bad = _cli("compensate", "--db", db, "--tool", "T1", "--measurement", "13,45")
    assert bad.returncode == 2
    assert bad.stderr.strip() == "measurement '13,45' is not a number; give the dimension in mm"
    history = json.loads(_cli("history", "--db", db, "--json").stdout)
    assert len(history["parts"]) == 8 and history["tools"][0]["tool"] == "T1"
