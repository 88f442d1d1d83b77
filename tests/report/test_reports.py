"""The HTML reports of the five commands hold what they claim, and load nothing from a network.

Each command runs as a user runs it (``python -m cnctwin ... --json --report OUT.html``); the
page's plotly figures are read back (tests/report/plotly_html.py) and compared with the
command's own outputs (its ``--json``, ``--out`` files) and with something independent of the
code under test: a closed form, the program's geometry, a recomputation here.
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from plotly_html import array, fetched, figures, read, result

REPO = Path(__file__).resolve().parents[2]
PACKAGED = REPO / "src" / "cnctwin" / "examples"
STABILITY = REPO / "examples" / "stability"


def cnctwin(*args: str | Path) -> dict[str, Any]:
    """Run the CLI in a fresh interpreter; its ``--json`` object."""
    done = subprocess.run(
        [sys.executable, "-m", "cnctwin", *map(str, args), "--json"],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def csv_columns(path: Path) -> dict[str, np.ndarray]:
    with path.open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    return {key: np.array([float(r[key]) for r in rows]) for key in rows[0]}


def self_contained(text: str, printed: dict[str, Any]) -> None:
    """Nothing to fetch, plotly.js inline, the printed result embedded whole."""
    assert fetched(text) == []
    assert "Plotly.newPlot" in text and len(text) > 3_000_000  # plotly.js itself is ~4.6 MB
    assert result(text) == printed


@pytest.fixture(scope="module")
def simulated(tmp_path_factory) -> tuple[dict[str, Any], str, Path]:
    # 10 ms steps over the 63.6 s program: 6,360 steps, more than the plot's 2 x 2000 points.
    out = tmp_path_factory.mktemp("simulate")
    printed = cnctwin(
        "simulate", PACKAGED / "demo.ngc", "-c", PACKAGED / "demo.toml", "--density", "2",
        "--cycle-ms", "10", "--out", out, "--report", out / "sim.html",
    )  # fmt: skip
    return printed, read(out / "sim.html"), out


def test_simulation_report_plots_every_steps_envelope(simulated) -> None:
    printed, text, out = simulated
    self_contained(text, printed)
    steps = csv_columns(out / "engagement.csv")
    assert steps["t_s"].size == printed["steps"] > 4000
    plots = figures(text)
    panels = plots["figure-1"]["data"]
    t_all = steps["t_s"]
    edges = np.linspace(t_all[0], t_all[-1], 2001)
    for trace, column in zip(panels, ("ae_mm", "ap_mm", "mrr_mm3_s", "feed_mm_min"), strict=True):
        x, y = array(trace["x"]), array(trace["y"])
        assert x.size <= 4000 and np.all(np.diff(x) >= 0)
        values = steps[column]
        # Every point is a step of engagement.csv (written there to 6 digits).
        index = np.searchsorted(t_all, x - 1e-9)
        np.testing.assert_allclose(t_all[index], x, rtol=1e-5)
        np.testing.assert_allclose(values[index], y, rtol=1e-5, atol=1e-9)
        # Per plot column (2000 equal time buckets) the plotted extremes are the steps'.
        bucket_all = np.minimum(np.searchsorted(edges, t_all, side="right") - 1, 1999)
        bucket = np.minimum(np.searchsorted(edges, x, side="right") - 1, 1999)
        for b in np.unique(bucket_all)[::37]:
            mine, shown = values[bucket_all == b], y[bucket == b]
            assert shown.max() == pytest.approx(mine.max(), rel=1e-5, abs=1e-9), (column, b)
            assert shown.min() == pytest.approx(mine.min(), rel=1e-5, abs=1e-9), (column, b)
    assert array(panels[0]["y"]).max() == pytest.approx(printed["max_ae_mm"], rel=1e-5)


def test_simulation_report_stock_is_the_programs_pocket(simulated) -> None:
    _, text, _ = simulated
    surface = figures(text)["figure-2"]["data"][0]
    x, y, z = array(surface["x"]), array(surface["y"]), array(surface["z"])
    # demo.toml: the block spans x 150..230, y 100..160, top z -300 (machine coordinates);
    # demo.ngc: a 3 mm deep pocket around X40 Y30 of the stock's top left corner.
    assert 150 <= x.min() and x.max() <= 230 and 100 <= y.min() and y.max() <= 160
    assert np.nanmax(z) == pytest.approx(-300.0, abs=1e-3)
    centre = z[np.argmin(np.abs(y - 130.0)), np.argmin(np.abs(x - 190.0))]
    assert centre == pytest.approx(-303.0, abs=0.05)


def test_lobes_report_minimum_is_the_closed_form(tmp_path) -> None:
    page = tmp_path / "lobes.html"
    printed = cnctwin(
        "stability", "lobes", "--config", STABILITY / "insperger_slot.toml", "--method", "zoa",
        "--rpm-range", "5000:25000:400", "--report", page,
    )  # fmt: skip
    text = read(page)
    self_contained(text, printed)
    traces = figures(text)["figure-1"]["data"]
    curve = next(t for t in traces if t.get("name") == "critical depth [mm]")
    rpm, depth = array(curve["x"]), array(curve["y"])
    order = np.argsort(printed["spindle_rpm"])
    np.testing.assert_array_equal(rpm, np.array(printed["spindle_rpm"])[order])
    np.testing.assert_allclose(depth, np.array(printed["critical_depth_mm"])[order], rtol=1e-12)
    chatter = next(t for t in traces if t.get("name") == "chatter frequency [Hz]")
    np.testing.assert_allclose(
        array(chatter["y"]), np.array(printed["chatter_frequency_hz"])[order], rtol=1e-12
    )
    # Independent: a_lim = -1 / (2 Ks Re[G]min) (Altintas & Budak 1995, zero-order solution)
    # with the FRF of the file's one mode sampled here (k in N/m, zeta), and Ks = N Krc / 4:
    # the averaged force factor of a slot (ae/D = 1) on a tool flexible in x alone.
    k, zeta = 1340049.648, 0.011
    r = np.linspace(0.5, 1.5, 2_000_001)  # frequency / natural frequency
    re_g_min = (1.0 / (k * (1 - r**2 + 2j * zeta * r))).real.min()  # m/N
    ks = 2 * 200e6 / 4  # N/m^2: two teeth, Krc 200 N/mm^2
    a_lim_mm = -1.0 / (2 * ks * re_g_min) * 1e3
    assert a_lim_mm == pytest.approx(0.29805, rel=1e-4)
    assert depth.min() == pytest.approx(a_lim_mm, rel=0.01) and depth.min() >= a_lim_mm * 0.9999
    shapes = figures(text)["figure-1"]["layout"]["shapes"]
    assert any(s["y0"] == pytest.approx(a_lim_mm, rel=1e-5) for s in shapes)  # the ZOA line


def test_roadmap_report_plots_the_segments_and_their_lobes(tmp_path) -> None:
    page = tmp_path / "road.html"
    printed = cnctwin(
        "stability", "roadmap", PACKAGED / "demo.ngc", "-c", PACKAGED / "demo.toml",
        "--stability", STABILITY / "insperger_slot.toml", "--method", "zoa",
        "--rpm-range", "5000:10000:51", "--density", "1", "--report", page,
    )  # fmt: skip
    text = read(page)
    self_contained(text, printed)
    plots = figures(text)
    road, lobes = plots["figure-1"]["data"], plots["figure-2"]["data"]
    segments = [s for s in printed["segments"] if s["programmed_critical_depth_mm"] is not None]
    programmed = [t for t in road if t.get("legendgroup") == "p"]
    assert len(programmed) == len(segments) > 0
    for trace, seg in zip(programmed, segments, strict=True):
        assert array(trace["x"]).tolist() == [seg["start_s_mm"], seg["end_s_mm"]]
        assert array(trace["y"]).tolist() == [seg["programmed_rpm"]] * 2
    curves = {t["name"].split(":")[0]: array(t["y"]) for t in lobes if t["mode"] == "lines"}
    grid = np.linspace(5000, 10000, 51)
    for label, depth in curves.items():
        engagement = printed["engagements"][int(label[1:])]
        assert np.nanmin(depth) == pytest.approx(engagement["min_critical_depth_mm"], rel=1e-9)
    assert all(np.array_equal(array(t["x"]), grid) for t in lobes if t["mode"] == "lines")
    # The red cells: speeds whose critical depth is below margin x depth, recomputed here
    # from the plotted lobes and each segment's depth.
    heat = [t for t in road if t["type"] == "heatmap"]
    assert len(heat) == len(segments)
    for cells, seg in zip(heat, segments, strict=True):
        unstable = curves[cells["name"]] < printed["margin"] * seg["ap_mm"]
        np.testing.assert_array_equal(array(cells["z"])[:, 0], unstable.astype(float))
        np.testing.assert_array_equal(array(cells["y"]), grid)


def test_wear_report_plots_the_estimate_band_and_stages(tmp_path) -> None:
    page, estimate = tmp_path / "wear.html", tmp_path / "estimate.csv"
    printed = cnctwin(
        "wear", "ekf", "--synthetic", "--seed", "3", "--stages-mm", "0.05", "0.2", "0.55",
        "--out", estimate, "--report", page,
    )  # fmt: skip
    text = read(page)
    self_contained(text, printed)
    figure = figures(text)["figure-1"]
    traces = {t["name"]: t for t in figure["data"]}
    rows = csv_columns(estimate)
    t = array(traces["EKF estimate"]["x"])
    vb = array(traces["EKF estimate"]["y"])
    np.testing.assert_allclose(t, rows["time_s"], rtol=1e-5)
    np.testing.assert_allclose(vb, rows["vb_mm"], rtol=1e-5, atol=1e-9)
    band = array(traces["estimate +- 2 sd"]["y"])
    n = t.size
    np.testing.assert_allclose(band[:n], rows["vb_mm"] + 2 * rows["sd_mm"], rtol=1e-4, atol=2e-6)
    np.testing.assert_allclose(
        band[n:][::-1], rows["vb_mm"] - 2 * rows["sd_mm"], rtol=1e-4, atol=2e-6
    )
    # The error against the true wear, recomputed from the two plotted curves.
    truth = array(traces["true wear"]["y"])
    assert np.mean(np.abs(vb - truth)) == pytest.approx(printed["mean_abs_error_mm"], rel=1e-9)
    shapes = figure["layout"]["shapes"]
    levels = sorted(s["y0"] for s in shapes if s["y0"] == s["y1"])
    assert levels == [0.05, 0.2, 0.55]  # the stages given
    events = sorted(s["x0"] for s in shapes if s["x0"] == s["x1"])
    assert events == sorted(e["time_s"] for e in printed["stage_events"]) and events


def test_dexel_study_report_maps_are_the_runs_and_eq3(tmp_path) -> None:
    page, out = tmp_path / "study.html", tmp_path / "study"
    printed = cnctwin("study", "dexel", "--out", out, "--quick", "--workers", "2", "--report", page)
    text = read(page)
    self_contained(text, printed)
    plots = figures(text)
    runs = list(csv.DictReader((out / "results.csv").open()))
    densities = sorted({float(r["density_per_mm"]) for r in runs})
    cycles = sorted({float(r["cycle_s"]) for r in runs})

    # Heide 2025, Eq. 2-3 from results.csv: per setting the mean |delta ae| and feed deviation
    # over its feeds, the sum of its CPU times; min-max normalised (flat below the resolution).
    def metric(name: str, reduce) -> np.ndarray:
        return np.array(
            [
                [
                    reduce([float(r[name]) for r in runs
                            if float(r["density_per_mm"]) == d and float(r["cycle_s"]) == c])
                    for c in cycles
                ]
                for d in densities
            ]
        )  # fmt: skip

    def normalised(a: np.ndarray, resolution: float) -> np.ndarray:
        span = a.max() - a.min()
        return np.zeros_like(a) if span <= resolution else (a - a.min()) / span

    ae, vf = metric("delta_ae_mm", np.mean), metric("feed_deviation_pct", np.mean)
    cpu = metric("cpu_s", np.sum)
    expected = 0.4 * normalised(ae, 1e-6) + 0.4 * normalised(vf, 1e-6) + 0.2 * normalised(cpu, 0)
    score = plots["figure-1"]["data"][0]
    assert score["y"] == [f"{d:g}" for d in densities]
    assert score["x"] == [f"{c * 1e3:g}" for c in cycles]
    np.testing.assert_allclose(array(score["z"]), expected, atol=2e-4)
    best = np.unravel_index(np.argmin(expected), expected.shape)
    assert (densities[best[0]], cycles[best[1]] * 1e3) == pytest.approx(
        (printed["score_optimum"]["density_per_mm"], printed["score_optimum"]["cycle_ms"])
    )
    # Per feed, the |delta ae| map's cells are the runs of results.csv (in um).
    feed = float(runs[0]["feed_mm_min"])
    ae_map = next(
        f["data"][0] for f in plots.values() if f["layout"]["title"]["text"].startswith(
            f"mean |delta ae|, vf = {feed:g}"
        )
    )  # fmt: skip
    for i, d in enumerate(densities):
        for j, c in enumerate(cycles):
            run = next(
                r for r in runs if (float(r["density_per_mm"]), float(r["cycle_s"]),
                                    float(r["feed_mm_min"])) == (d, c, feed)
            )  # fmt: skip
            value_um = float(run["delta_ae_mm"]) * 1e3
            assert float(ae_map["text"][i][j]) == pytest.approx(value_um, rel=5e-3)  # 3 digits
            # Colour: log10 of the value, floored at the 1e-3 um resolution.
            colour = 10 ** array(ae_map["z"])[i, j]
            assert colour == pytest.approx(max(value_um, 1e-3), rel=1e-5)
