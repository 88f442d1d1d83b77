"""The run browser's API (cnctwin.web.runs) on runs recorded through the historian."""

import csv
import io
import zipfile

import numpy as np
import pytest
from fastapi.testclient import TestClient
from runs_data import DT_S, N1, SPIKE, expected_force, record

from cnctwin.web.runs import RunBrowser, runs_app


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    path = tmp_path_factory.mktemp("runs") / "runs.sqlite"
    record(path)
    return path


@pytest.fixture(scope="module")
def client(db):
    browser = RunBrowser(db)
    with TestClient(runs_app(browser)) as c:
        yield c
    browser.close()


def test_list_names_machine_program_start_duration_outcome(client) -> None:
    runs = client.get("/api/runs").json()["runs"]
    assert [(r["run_id"], r["program"], r["machine"], r["status"]) for r in runs] == [
        (1, "pocket.nc", "opc.tcp://127.0.0.1:4840", "finished"),
        (2, "slot.nc", "mill-2", "stopped"),
    ]
    assert runs[0]["frames"] == N1 and runs[1]["frames"] == 400
    assert all(r["duration_s"] >= 0 and r["started_at"] > 1.7e9 for r in runs)
    assert "text/html" in client.get("/runs").headers["content-type"]


def test_open_run_has_signals_events_decisions(client) -> None:
    run = client.get("/api/runs/1").json()
    assert run["signals"] == ["force_x_n", "spindle_rpm"] and run["predicted"] == ["force_x_n"]
    assert run["event_log"][0]["message"] == "force above the band"
    assert run["decision_log"][0]["reason"] == "force 900 N > 150 N"


def test_whole_run_is_min_max_per_pixel(client) -> None:
    got = client.get("/api/runs/1/signal", params={"name": "force_x_n", "buckets": 500}).json()
    y_all = expected_force()
    t_all = np.arange(N1) * DT_S
    assert got["samples"] == N1 and not got["raw"] and len(got["t"]) <= 1000
    assert (got["t0"], got["t1"]) == (0.0, (N1 - 1) * DT_S)
    t = np.array(got["t"])
    y = np.array([np.nan if v is None else v for v in got["y"]])
    # The buckets split the run into 500 nearly equal spans (the overview's 4096 fine
    # buckets merged), and each bucket's points are its min and max, computed here by brute
    # force from the recorded values.
    edges = np.array(got["edges"])
    assert edges.size == 501 and edges[0] == 0.0 and edges[-1] == got["t1"]
    np.testing.assert_allclose(edges, np.linspace(0.0, got["t1"], 501), atol=got["t1"] / 4096)
    bucket = np.minimum(np.searchsorted(edges, t_all, side="right") - 1, 499)
    got_bucket = np.minimum(np.searchsorted(edges, t, side="right") - 1, 499)
    for b in range(500):
        mine, shown = y_all[bucket == b], y[got_bucket == b]
        if np.isnan(mine).all():
            assert shown.size == 1 and np.isnan(shown[0])
            continue
        assert np.nanmax(shown) == np.nanmax(mine) and np.nanmin(shown) == np.nanmin(mine)
        assert shown.size == (1 if np.nanmax(mine) == np.nanmin(mine) else 2)
    assert y[np.argmax(np.nan_to_num(y))] == 900.0 and t[np.nanargmax(y)] == SPIKE * DT_S
    # every point is a recorded sample
    index = np.rint(t / DT_S).astype(int)
    np.testing.assert_array_equal(np.nan_to_num(y, nan=-1), np.nan_to_num(y_all[index], nan=-1))


def test_zoom_returns_the_samples_of_the_window(client) -> None:
    params = {"name": "force_x_n", "buckets": 800, "t0": 150.0, "t1": 155.0}
    got = client.get("/api/runs/1/signal", params=params).json()
    assert got["raw"] and got["samples"] == 401  # 150.0 .. 155.0 s in 12.5 ms steps
    index = np.arange(12_000, 12_401)
    np.testing.assert_allclose(got["t"], index * DT_S)
    np.testing.assert_array_equal(got["y"], expected_force()[index])
    around_gap = {"name": "force_x_n", "buckets": 800, "t0": 62.0, "t1": 63.0}
    got = client.get("/api/runs/1/signal", params=around_gap).json()
    assert got["raw"] and got["y"][40:50] == [None] * 10  # NaN comes as a gap (null)


def test_predicted_signal_and_overlay_run(client) -> None:
    predicted = client.get(
        "/api/runs/1/signal", params={"name": "force_x_n", "kind": "predicted"}
    ).json()
    assert predicted["samples"] == N1 // 10 and set(predicted["y"]) == {101.0}
    other = client.get("/api/runs/2/signal", params={"name": "force_x_n"}).json()
    assert other["raw"] and other["y"] == [50.0 + i for i in range(400)]


@pytest.mark.parametrize(
    ("url", "params", "status", "message"),
    [
        ("/api/runs/9", {}, 404, "run 9 is not in the historian"),
        ("/api/runs/9/signal", {"name": "force_x_n"}, 404, "run 9 is not in the historian"),
        ("/api/runs/1/signal", {"name": "torque"}, 404, "no measured signal 'torque'"),
        ("/api/runs/1/signal", {"name": "force_x_n", "buckets": 0}, 422, "buckets 0"),
        ("/api/runs/1/signal", {"name": "force_x_n", "kind": "x"}, 422, "kind 'x'"),
        ("/api/runs/1/signal", {"name": "force_x_n", "t0": 5, "t1": 1}, 422, "t0=5.0"),
        ("/api/runs/1/export", {"format": "xls"}, 422, "format 'xls'"),
    ],
)
def test_errors_are_one_line(client, url, params, status, message) -> None:
    response = client.get(url, params=params)
    assert response.status_code == status
    error = response.json()["error"]
    assert message in error and "\n" not in error


def test_export_is_the_historians_csv(client) -> None:
    response = client.get("/api/runs/2/export", params={"format": "csv"})
    assert response.headers["content-type"] == "application/zip"
    archive = zipfile.ZipFile(io.BytesIO(response.content))
    assert sorted(archive.namelist()) == [
        "run2.csv",
        "run2.decisions.csv",
        "run2.events.csv",
        "run2.predictions.csv",
    ]
    rows = list(csv.DictReader(io.StringIO(archive.read("run2.csv").decode())))
    assert [float(r["force_x_n"]) for r in rows] == [50.0 + i for i in range(400)]
    parquet = client.get("/api/runs/2/export", params={"format": "parquet"})
    assert "run2.parquet" in zipfile.ZipFile(io.BytesIO(parquet.content)).namelist()


def test_token_is_needed_when_one_is_set(db) -> None:
    browser = RunBrowser(db)
    with TestClient(runs_app(browser, token="s3cret")) as c:
        for url in ("/runs", "/api/runs", "/api/runs/1/signal?name=force_x_n", "/static/runs.js"):
            assert c.get(url).status_code == 401, url
        assert c.get("/api/runs", headers={"Authorization": "Bearer wrong"}).status_code == 401
        assert c.get("/api/runs", headers={"Authorization": "Bearer s3cret"}).status_code == 200
        page = c.get("/runs?token=s3cret")
        assert page.status_code == 200 and page.cookies.get("cnctwin_token") == "s3cret"
        assert c.get("/api/runs").status_code == 200  # the cookie now carries it
    browser.close()


def test_a_run_being_recorded_is_plotted_from_its_frames(tmp_path) -> None:
    """No overview while a run records: the whole-run plot is cut from its columns, in equal
    buckets, and shows what was recorded up to now."""
    from cnctwin.store import Historian

    path = tmp_path / "live.sqlite"
    y_all = expected_force()[:3000]
    with Historian.open(path) as h:
        run = h.start_run({"program": "live.nc"})
        for i, value in enumerate(y_all):
            h.record_samples(run, i * DT_S, {"force_x_n": float(value)})
        h.flush()
        browser = RunBrowser(path)
        try:
            got = browser.signal(run, "force_x_n", buckets=100)
        finally:
            browser.close()
    assert got["samples"] == 3000 and not got["raw"]
    np.testing.assert_allclose(got["edges"], np.linspace(0.0, 2999 * DT_S, 101))
    t, y = np.array(got["t"]), np.array([np.nan if v is None else v for v in got["y"]])
    bucket = np.minimum((np.arange(3000) / 2999 * 100).astype(int), 99)
    shown = np.minimum(np.searchsorted(got["edges"], t, side="right") - 1, 99)
    for b in range(100):
        assert np.nanmax(y[shown == b]) == np.nanmax(y_all[bucket == b])
        assert np.nanmin(y[shown == b]) == np.nanmin(y_all[bucket == b])
