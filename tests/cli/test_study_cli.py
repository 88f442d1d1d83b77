"""``cnctwin study dexel --quick`` end to end (the command group as the lead wires it in)."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest
from typer.testing import CliRunner

from cnctwin.cli.study import app
from cnctwin.errors import InputError


def test_quick_study_writes_every_output(tmp_path: Path) -> None:
    out = tmp_path / "study"
    done = CliRunner().invoke(
        app, ["dexel", "--out", str(out), "--quick", "--workers", "2", "--json"]
    )
    assert done.exit_code == 0, done.output
    summary = json.loads(done.stdout)
    for name in ("results.csv", "summary.json", "report.md"):
        assert (out / name).is_file()
    for name in ("delta_ae", "feed_deviation", "volume_deviation", "runtime", "score"):
        assert (out / f"{name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert json.loads((out / "summary.json").read_text())["optimum"] == summary["optimum"]
    # --quick: 3 densities x 4 cycle times x 2 feeds.
    with (out / "results.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 24 == summary["study"]["runs"]
    assert {float(r["density_per_mm"]) for r in rows} == {5.0, 10.0, 20.0}
    # The step is feed x cycle time.
    for r in rows:
        step = float(r["feed_mm_min"]) / 60.0 * float(r["cycle_s"])
        assert float(r["step_mm"]) == pytest.approx(step, rel=1e-5)
    # The optimum is the least score among the settings that meet the constraints, with its
    # six-feed (here two) runs.
    best = summary["optimum"]
    assert len(best["runs"]) == 2
    assert 0.0 <= best["score"] <= 1.0
    assert best["volume_deviation_pct"] <= 1.0 and best["realtime_factor"] >= 1.0
    assert summary["constraints"] == {"max_volume_deviation_pct": 1.0, "min_realtime_factor": 1.0}
    # S weighs the measured CPU time (Heide 2025, Eq. 3), so which setting has the least S moves
    # with the machine's load; what does not move is the material left by the coarsest setting.
    # 5 /mm at 200 ms: steps of 9.6 mm at 2880 mm/min, longer than the engaged chord, so each
    # position takes one circular segment of the 6 mm tool beyond 1.2 mm from its axis,
    # R^2 acos(d/R) - d sqrt(R^2 - d^2) = 7.134 mm^2, of the 1.8 x 9.6 mm^2 a continuous cut
    # takes: 58.7 % left standing. It is excluded, and says so.
    top = summary["score_optimum"]
    assert top["score"] <= best["score"]
    segment = 9 * math.acos(0.4) - 1.2 * math.sqrt(9 - 1.44)
    coarse = [r for r in rows if float(r["density_per_mm"]) == 5.0 and float(r["cycle_s"]) == 0.2]
    fast = max(coarse, key=lambda r: float(r["feed_mm_min"]))
    assert float(fast["feed_mm_min"]) == 2880.0
    # Per run the deviation is signed: less removed than by a continuous cut is negative.
    assert float(fast["volume_deviation_pct"]) == pytest.approx(
        -100 * (1 - segment / 17.28), abs=0.5
    )
    excluded = {(e["density_per_mm"], e["cycle_ms"]): e for e in summary["excluded"]}
    assert "(material left uncut), tolerance 1 %" in excluded[(5.0, 200.0)]["reasons"][0]
    # Progress and the estimated cost go to stderr, never into the JSON on stdout.
    assert "dexel study: 24 runs on 2 process(es)" in done.stderr
    assert "for all runs (the first scaled by" in done.stderr
    assert summary["paper"]["density_per_mm"] == 10.0 and summary["paper"]["runtime_s"] == 41.7
    assert summary["at_paper_optimum"]["cycle_ms"] == pytest.approx(12.5)
    assert summary["t_star_fit"]["points"] == 12
    report = (out / "report.md").read_text()
    assert "Heide 2025 optimum" in report and "T* = rho^2 / t_cycle" in report
    assert report.split("\n")[2].startswith(
        f"Optimum: {best['density_per_mm']:g} /mm, {best['cycle_ms']:g} ms"
    )


def test_bad_workers_is_an_input_error(tmp_path: Path) -> None:
    done = CliRunner().invoke(app, ["dexel", "--out", str(tmp_path), "--quick", "--workers", "0"])
    # app.py turns CnctwinError into one line and exit code 2.
    assert isinstance(done.exception, InputError)
    assert "--workers 0" in str(done.exception)
