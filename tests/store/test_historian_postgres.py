"""The PostgreSQL historian against the real server (127.0.0.1:5432, user postgres, db test).

Each test works in a schema of its own (chosen with libpq's ``options`` in the URL) and drops
it afterwards, so parallel runs do not collide.
"""

from __future__ import annotations

import uuid
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from historian_cases import assert_bits_equal, check_roundtrip, record_everything
from skips import require_service

from cnctwin.errors import DataError
from cnctwin.store import Historian

HOST, PORT = "127.0.0.1", 5432
SERVER = f"postgresql://postgres@{HOST}:{PORT}/test"


@pytest.fixture
def url() -> Iterator[str]:
    require_service(HOST, PORT, "PostgreSQL")
    psycopg = pytest.importorskip("psycopg")
    schema = f"hist_test_{uuid.uuid4().hex[:12]}"
    with psycopg.connect(SERVER, autocommit=True, connect_timeout=5) as conn:
        conn.execute(f"CREATE SCHEMA {schema}")
    try:
        yield f"{SERVER}?options=-csearch_path%3D{schema}&application_name={schema}"
    finally:
        with psycopg.connect(SERVER, autocommit=True, connect_timeout=5) as conn:
            conn.execute(f"DROP SCHEMA {schema} CASCADE")


def test_round_trip_is_exact(url: str) -> None:
    with Historian.open(url, batch_size=50) as h:
        assert h.location == url
        rec = record_everything(h)
        check_roundtrip(h, rec)
        h.end_run(rec.run_id, "stopped", {"reason": "hole in the blank"})
    with Historian.open(url, create=False) as h:
        check_roundtrip(h, rec)
        (run,) = h.runs()
        assert run.status == "stopped" and run.summary == {"reason": "hole in the blank"}


def test_tables_live_in_the_chosen_schema(url: str) -> None:
    import psycopg

    with Historian.open(url) as h:
        h.start_run({})
    schema = url.split("%3D", 1)[1].split("&", 1)[0]
    with psycopg.connect(SERVER, connect_timeout=5) as conn:
        tables = {
            r[0]
            for r in conn.execute(
                "SELECT table_name FROM information_schema.tables WHERE table_schema = %s",
                (schema,),
            )
        }
    assert {"hist_runs", "hist_layouts", "hist_frames", "hist_events", "hist_decisions"} <= tables


def test_export_from_postgres(url: str, tmp_path: Path) -> None:
    with Historian.open(url) as h:
        rec = record_everything(h, n=200)
        files = h.export(rec.run_id, tmp_path / "pg.parquet")
    table = pq.read_table(files[0])
    want = rec.columns(False)
    assert table.column_names == list(want)
    got = np.array(table.column("time_s").to_pylist())
    assert_bits_equal(got, want["time_s"], "time_s")


def test_reconnects_after_the_server_drops_the_connections(url: str) -> None:
    """The server terminates the historian's sessions mid-run (as in a restart): the writer
    keeps its batch, reconnects and commits it; queries reconnect too. Nothing is lost."""
    import psycopg

    application = url.rsplit("application_name=", 1)[1]
    with Historian.open(url, flush_interval_s=0.05) as h:
        run = h.start_run({})
        for i in range(100):
            h.record_samples(run, i, {"a": i})
        h.flush()
        with psycopg.connect(SERVER, autocommit=True, connect_timeout=5) as admin:
            killed = admin.execute(
                "SELECT pg_terminate_backend(pid) FROM pg_stat_activity "
                "WHERE application_name = %s",
                (application,),
            ).fetchall()
        assert len(killed) == 2  # the writer's session and the queries' session
        for i in range(100, 200):
            h.record_samples(run, i, {"a": i})
        h.flush()
        assert h.stats().last_error is not None  # the writer did see the loss
        assert np.array_equal(h.samples(run)["a"], np.arange(200))


def test_unreachable_server_is_one_line() -> None:
    with pytest.raises(DataError, match=r"cannot connect to PostgreSQL at postgresql://u:\*\*\*@"):
        Historian.open("postgresql://u:secret@127.0.0.1:1/none")


def test_a_closed_runs_overview_and_windows(url: str) -> None:
    """The overview is stored in PostgreSQL as in SQLite: its envelope against a brute-force
    min/max of the recorded values, and a window of samples against the values in it."""
    t = np.arange(5000) * 0.0125
    y = np.sin(t * 3.0) * 100.0
    y[1234] = 900.0
    with Historian.open(url) as h:
        run = h.start_run({})
        for ti, yi in zip(t, y, strict=True):
            h.record_samples(run, float(ti), {"force_x_n": float(yi)})
        h.end_run(run, "finished")
    with Historian.open(url, create=False) as h:
        assert {r[0] for r in h._read("SELECT name FROM hist_overview")} == {"", "force_x_n"}
        envelope = h.overview(run).envelope("force_x_n", 100)
        window = h.samples(run, t0=10.0, t1=11.0)
    group = np.minimum(np.searchsorted(envelope.edges, t, side="right") - 1, 99)
    shown = np.minimum(np.searchsorted(envelope.edges, envelope.t, side="right") - 1, 99)
    for b in range(100):
        assert envelope.y[shown == b].max() == y[group == b].max()
        assert envelope.y[shown == b].min() == y[group == b].min()
    assert 900.0 in envelope.y
    np.testing.assert_array_equal(window["force_x_n"], y[800:881])
