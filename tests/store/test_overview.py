"""A closed run's overview (Historian.overview) against a brute-force min/max over the raw
frames, decoded here straight from the SQLite file with struct (not through the historian)."""

from __future__ import annotations

import json
import math
import sqlite3
import struct

import numpy as np
import pytest

from cnctwin.errors import DataError
from cnctwin.store import OVERVIEW_BUCKETS, Historian

N = 30_000


def raw_frames(path, run_id: int, kind: int) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Times and per-signal values of a run's frames, decoded byte by byte (NaN: absent)."""
    with sqlite3.connect(path) as conn:
        layouts = {i: json.loads(n) for i, n in conn.execute("SELECT id, names FROM hist_layouts")}
        rows = conn.execute(
            "SELECT t_s, layout_id, vals FROM hist_frames WHERE run_id = ? AND kind = ? "
            "ORDER BY seq",
            (run_id, kind),
        ).fetchall()
    names = {n for layout in layouts.values() for n in layout}
    values = {n: np.full(len(rows), np.nan) for n in names}
    for i, (_, layout, blob) in enumerate(rows):
        for name, value in zip(
            layouts[layout], struct.unpack(f"<{len(blob) // 8}d", blob), strict=True
        ):
            values[name][i] = value
    return np.array([r[0] for r in rows]), values


def brute_force(t, y, edges):
    """Per bucket [edges[k], edges[k+1]) (the last one closed): (min, max) of the finite
    values with the time of the first min and the last max, or a NaN at the bucket's first
    instant when it has no finite value."""
    points = []
    for k in range(edges.size - 1):
        last = k == edges.size - 2
        inside = (t >= edges[k]) & ((t <= edges[k + 1]) if last else (t < edges[k + 1]))
        tt, yy = t[inside], y[inside]
        if tt.size == 0:
            continue
        if np.isnan(yy).all():
            points.append((tt[0], math.nan))
            continue
        low, high = np.nanmin(yy), np.nanmax(yy)
        i, j = np.flatnonzero(yy == low)[0], np.flatnonzero(yy == high)[-1]
        points += [(tt[i], yy[i])] if i == j else sorted([(tt[i], yy[i]), (tt[j], yy[j])])
    return points


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    path = tmp_path_factory.mktemp("overview") / "runs.sqlite"
    rng = np.random.default_rng(11)
    # Irregular steps (pauses leave buckets empty), values rounded so extremes tie, NaN
    # instants and a stretch with no finite value, spikes one instant wide, and a signal
    # that appears half-way (a second layout).
    t = np.cumsum(rng.choice([0.0125, 0.5, 7.0], N, p=[0.97, 0.025, 0.005]))
    force = np.round(rng.normal(100.0, 10.0, N))
    force[rng.random(N) < 0.03] = np.nan
    force[9_000:9_400] = np.nan
    force[[1_234, 20_001]] = [5_000.0, -3_000.0]
    power = rng.normal(0.0, 1.0, N)
    with Historian.open(path) as h:
        run = h.start_run({"program": "overview.nc"})
        for i in range(N):
            values = {"force_x_n": float(force[i])}
            if i >= N // 2:
                values["spindle_power_w"] = float(power[i])
            h.record_samples(run, float(t[i]), values)
            if i % 3 == 0:
                h.record_prediction(run, float(t[i]), {"force_x_n": float(force[i]) * 0.9})
        h.end_run(run, "finished")
        live = h.start_run({"program": "live.nc"})
        h.record_samples(live, 0.0, {"force_x_n": 1.0})
        h.flush()
    return path, run, live


@pytest.mark.parametrize("buckets", [1, 7, 500, 1000, 1920, OVERVIEW_BUCKETS])
@pytest.mark.parametrize(
    ("kind", "name"), [(0, "force_x_n"), (0, "spindle_power_w"), (1, "force_x_n")]
)
def test_overview_is_the_min_max_of_the_raw_frames(recorded, buckets, kind, name) -> None:
    path, run, _ = recorded
    t, values = raw_frames(path, run, kind)
    with Historian.open(path, create=False) as h:
        overview = h.overview(run, [name], predicted=bool(kind))
    assert overview is not None and list(overview.signals) == [name]
    assert (overview.t_first, overview.t_last, overview.frames) == (t[0], t[-1], t.size)
    envelope = overview.envelope(name, buckets)
    assert envelope.edges[0] == t[0] and envelope.edges[-1] == t[-1]
    equal = np.linspace(t[0], t[-1], buckets + 1)
    assert np.abs(envelope.edges - equal).max() <= (t[-1] - t[0]) / OVERVIEW_BUCKETS * 1.000001
    expected = brute_force(t, values[name], envelope.edges)
    assert len(envelope.t) == len(expected) <= 2 * buckets
    np.testing.assert_array_equal(envelope.t, [p[0] for p in expected])
    np.testing.assert_array_equal(envelope.y, [p[1] for p in expected])
    if kind == 0 and name == "force_x_n":
        assert 5_000.0 in envelope.y and -3_000.0 in envelope.y  # the one-instant spikes


def test_a_database_without_overviews_gets_one_on_first_use(recorded, tmp_path) -> None:
    path, run, _ = recorded
    old = tmp_path / "old.sqlite"
    with sqlite3.connect(path) as src, sqlite3.connect(old) as dst:
        src.backup(dst)
        dst.execute("DROP TABLE hist_overview")  # as written before the tables existed
        dst.execute("DROP TABLE hist_run_layouts")
    with Historian.open(old, create=False) as h:
        counted = h.runs(), h.run(run)  # from the frames' index
        computed = h.overview(run)
        assert (h.runs(), h.run(run)) == counted  # now from hist_run_layouts
    with sqlite3.connect(old) as conn:
        stored = conn.execute("SELECT COUNT(*) FROM hist_overview WHERE run_id = ?", (run,))
        assert stored.fetchone()[0] == 3  # header, force_x_n, spindle_power_w
        layouts = conn.execute("SELECT COUNT(*) FROM hist_run_layouts WHERE run_id = ?", (run,))
        assert layouts.fetchone()[0] == 3  # measured: two layouts; predicted: one
    with Historian.open(path, create=False) as h:
        assert (h.runs(), h.run(run)) == counted
        original = h.overview(run)
    assert computed is not None and original is not None
    for name in ("force_x_n", "spindle_power_w"):
        for field, array in original.signals[name].items():
            np.testing.assert_array_equal(computed.signals[name][field], array)


def test_a_running_run_has_none_and_names_are_checked(recorded) -> None:
    path, run, live = recorded
    with Historian.open(path, create=False) as h:
        assert h.overview(live) is None
        with pytest.raises(DataError, match="no samples named 'torque'.*recorded: force_x_n"):
            h.overview(run, ["torque"])
        with pytest.raises(DataError, match="run 99 is not in the historian"):
            h.overview(99)


def test_a_window_of_samples_is_the_raw_frames_in_it(recorded) -> None:
    path, run, live = recorded
    t, values = raw_frames(path, run, 0)
    rng = np.random.default_rng(5)
    # Windows inside, across pauses, at the ends, past the ends, on an instant, empty.
    windows = [tuple(np.sort(rng.uniform(t[0] - 50.0, t[-1] + 50.0, 2))) for _ in range(20)]
    windows += [(t[0], t[0]), (t[-1], t[-1] + 1.0), (t[100], t[100]), (-10.0, -5.0)]
    windows += [(t[17_000], t[17_000] + 0.05), (t[0], t[-1]), (None, t[50]), (t[-50], None)]
    with Historian.open(path, create=False) as h:
        for t0, t1 in windows:
            got = h.samples(run, ["force_x_n", "spindle_power_w"], t0=t0, t1=t1)
            inside = (t >= (-np.inf if t0 is None else t0)) & (t <= (np.inf if t1 is None else t1))
            np.testing.assert_array_equal(got["time_s"], t[inside])
            for name in ("force_x_n", "spindle_power_w"):
                np.testing.assert_array_equal(got[name], values[name][inside])
        # A short window's frames are found among a few fine buckets' (not the whole run's).
        overview = h.overview(run)
        lo, hi = overview.seq_range(t[17_000], t[17_000] + 0.05)
        assert 0 <= hi - lo < 0.01 * (overview.seq_hi[-1] - overview.seq_lo[0])
        # A run being recorded has no overview: its window is found by time alone.
        assert h.samples(live, t0=-1.0, t1=1.0)["force_x_n"].tolist() == [1.0]
