"""The SQLite historian: exact round trip, ordering, export, WAL, SIGKILL survival, errors."""

from __future__ import annotations

import csv
import math
import os
import signal
import sqlite3
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from historian_cases import assert_bits_equal, check_roundtrip, record_everything

from cnctwin.errors import ConfigError, DataError
from cnctwin.store import Historian, HistorianConfig, default_database_path


@pytest.fixture
def db(tmp_path: Path) -> Path:
    return tmp_path / "historian.sqlite"


def test_round_trip_is_exact(db: Path) -> None:
    with Historian.open(db, batch_size=50) as h:
        rec = record_everything(h)
        check_roundtrip(h, rec)
        h.end_run(rec.run_id, "finished", {"cycles": 600, "stop_reaction_ms": 3.5})
        summary = h.runs()[0]
    assert summary.status == "finished" and summary.summary == {
        "cycles": 600,
        "stop_reaction_ms": 3.5,
    }
    assert summary.ended_at is not None and summary.ended_at >= summary.started_at
    # A new process reading the closed file sees the same.
    with Historian.open(db, create=False) as h:
        check_roundtrip(h, rec)


def test_file_is_in_wal_mode(db: Path) -> None:
    with Historian.open(db) as h:
        h.start_run({})
    conn = sqlite3.connect(db)
    assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    conn.close()


def test_batches_keep_the_order_of_several_threads(db: Path) -> None:
    """Four threads record interleaved over many batches; each thread's records come back
    complete and in its order."""
    with Historian.open(db, batch_size=7, flush_interval_s=0.05) as h:
        run = h.start_run({})

        def worker(w: int) -> None:
            for i in range(500):
                h.record_samples(run, w * 1000 + i, {"worker": w, "i": i})
                if i % 100 == 99:
                    time.sleep(0.06)  # let the writer commit mid-stream

        threads = [threading.Thread(target=worker, args=(w,)) for w in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        h.flush()
        got = h.samples(run)
        assert h.stats().batches > 3
    assert len(got["i"]) == 2000
    for w in range(4):
        mine = got["worker"] == w
        assert np.array_equal(got["i"][mine], np.arange(500))
        assert np.array_equal(got["time_s"][mine], w * 1000 + np.arange(500))


def test_writer_commits_without_flush(db: Path) -> None:
    """Within a few intervals the records are in the file for any other reader."""
    with Historian.open(db, flush_interval_s=0.1) as h:
        run = h.start_run({})
        for i in range(100):
            h.record_samples(run, i, {"a": i})
        reader = sqlite3.connect(db)
        # 0.1 s intervals: the records are there within a few; 60 s only ends a writer that
        # never commits (the loop leaves as soon as all 100 are in)
        deadline = time.monotonic() + 60.0
        n = 0
        while time.monotonic() < deadline and n < 100:
            time.sleep(0.05)
            n = reader.execute("SELECT COUNT(*) FROM hist_frames").fetchone()[0]
        reader.close()
    assert n == 100


def _read_csv(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def test_export_csv_and_parquet_read_back_equal(db: Path, tmp_path: Path) -> None:
    with Historian.open(db) as h:
        rec = record_everything(h, n=300)
        h.end_run(rec.run_id)
        csv_files = h.export(rec.run_id, tmp_path / "run.csv")
        pq_files = h.export(rec.run_id, tmp_path / "run.parquet")
    assert [p.name for p in csv_files] == [
        "run.csv",
        "run.predictions.csv",
        "run.events.csv",
        "run.decisions.csv",
    ]
    for predicted, index in ((False, 0), (True, 1)):
        want = rec.columns(predicted)
        present = {
            name: np.array([name in f for f in rec.frames[predicted]]) for name in list(want)[1:]
        }
        # CSV: float() of each cell gives the value back; an empty cell is "not recorded".
        rows = _read_csv(csv_files[index])
        assert list(rows[0]) == list(want)
        for name, values in want.items():
            cells = [row[name] for row in rows]
            if name != "time_s":
                assert [c != "" for c in cells] == list(present[name])
            got = np.array([float(c) if c else np.nan for c in cells])
            assert_bits_equal(got, values, f"csv {name}")
        # Parquet: nulls where not recorded, exact floats elsewhere.
        table = pq.read_table(pq_files[index])
        assert table.column_names == list(want)
        for name, values in want.items():
            column = table.column(name)
            if name != "time_s":
                assert list(column.is_valid().to_pylist()) == list(present[name])
            got = column.to_numpy(zero_copy_only=False).astype(np.float64)
            got = np.where(column.is_valid().to_numpy(zero_copy_only=False), got, np.nan)
            assert_bits_equal(got, values, f"parquet {name}")
    events = pq.read_table(pq_files[2]).to_pylist()
    assert [(e["seq"], e["t_s"], e["kind"], e["message"]) for e in events] == [
        (e.seq, e.t_s, e.kind, e.message) for e in rec.events
    ]
    decisions = _read_csv(csv_files[3])
    assert [float(d["value"]) for d in decisions] == [d.value for d in rec.decisions]
    assert [d["readback"] for d in decisions][0] == ""  # not read back
    assert b"cnctwin.run" in pq.read_schema(pq_files[0]).metadata


_CHILD = textwrap.dedent(
    """
    import sys, time
    from cnctwin.store import Historian
    h = Historian.open(sys.argv[1], flush_interval_s=0.25)
    run = h.start_run({"program": "kill-test"})
    t0 = time.monotonic()
    k = 0
    while True:
        t = time.monotonic() - t0
        h.record_samples(run, t, {"k": k, "x_mm": k * 0.5, "force_x_n": -k / 3})
        print(k, repr(t), flush=True)
        k += 1
        time.sleep(0.002)
    """
)


def test_sigkill_leaves_a_sound_file_missing_at_most_one_second(db: Path) -> None:
    """A child records samples at about 400/s and reports each; SIGKILL it mid-run."""
    child = subprocess.Popen(
        [sys.executable, "-c", _CHILD, str(db)], stdout=subprocess.PIPE, text=True
    )
    reported: list[tuple[int, float]] = []
    try:
        assert child.stdout is not None
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline:
            line = child.stdout.readline()
            if not line:
                break
            k, t = line.split()
            reported.append((int(k), float(t)))
            if reported[-1][1] > 1.7:
                break
        os.kill(child.pid, signal.SIGKILL)
        rest, _ = child.communicate(timeout=10.0)
    finally:
        if child.poll() is None:
            child.kill()
    for line in rest.splitlines():
        parts = line.split()
        if len(parts) == 2:  # the last line may have been cut by the kill
            reported.append((int(parts[0]), float(parts[1])))
    assert child.returncode == -signal.SIGKILL
    last_t = reported[-1][1]
    assert last_t > 1.7, "the child did not run long enough"

    conn = sqlite3.connect(db)
    assert conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    conn.close()
    with Historian.open(db, create=False) as h:
        (run,) = h.runs()
        assert run.status == "running"  # interrupted, never ended
        got = h.samples(run.run_id)
    n = len(got["k"])
    # What is there is exactly what the child recorded, from the first sample on, gap-free.
    assert np.array_equal(got["k"], np.arange(n))
    assert np.array_equal(got["x_mm"], np.arange(n) * 0.5)
    assert np.array_equal(got["force_x_n"], -np.arange(n) / 3)
    times = dict(reported)
    assert all(got["time_s"][i] == times[i] for i in range(0, n, 50))
    # ... and it reaches to within one second of the last sample reported before the kill.
    assert got["time_s"][-1] >= last_t - 1.0, (got["time_s"][-1], last_t)


def test_a_full_queue_drops_and_counts_instead_of_blocking(db: Path) -> None:
    """Another process holds the file's write lock: the writer waits, the queue fills and the
    caller is never blocked; once the lock goes everything queued is written."""
    with Historian.open(db, max_pending=100, flush_interval_s=0.05) as h:
        run = h.start_run({})
        blocker = sqlite3.connect(db, isolation_level=None)
        blocker.execute("BEGIN IMMEDIATE")
        time.sleep(0.2)  # the writer's next wake-up finds the lock
        start = time.perf_counter()
        for i in range(300):
            h.record_samples(run, i, {"a": i})
        elapsed = time.perf_counter() - start
        blocker.execute("ROLLBACK")
        blocker.close()
        with pytest.raises(DataError, match="were dropped"):
            h.flush()
        stats = h.stats()
        got = h.samples(run)["a"]
    # nothing waited for the lock: 300 calls take about 1 ms, while a caller that waited would
    # wait for good (the lock goes only after the loop); 30 s is far beyond any machine's load
    assert elapsed < 30.0
    assert stats.dropped >= 200 and stats.dropped + len(got) == 300
    assert np.array_equal(got, np.arange(len(got)))


def test_bad_input_is_one_clear_error(db: Path, tmp_path: Path) -> None:
    with Historian.open(db) as h:
        run = h.start_run({})
        with pytest.raises(DataError, match="'force_x_n' has value 'high'"):
            h.record_samples(run, 0.0, {"x_mm": 1.0, "force_x_n": "high"})  # type: ignore[dict-item]
        with pytest.raises(DataError, match="finite"):
            h.record_samples(run, math.nan, {"x_mm": 1.0})
        with pytest.raises(DataError, match="reserved"):
            h.record_samples(run, 0.0, {"time_s": 1.0})
        with pytest.raises(DataError, match="finite"):
            h.record_decision(run, 0.0, "r", "feed_override_pct", math.inf, "why", True)
        with pytest.raises(DataError, match="JSON"):
            h.record_event(run, 0.0, "k", "m", {"bad": {(1, 2): "tuple key"}})
        with pytest.raises(DataError, match=r"run 99 is not in the historian .*ids 1\.\.1"):
            h.run(99)
        with pytest.raises(DataError, match="no samples named 'nope'"):
            h.samples(run, ["nope"])
        with pytest.raises(DataError, match="export format 'txt'"):
            h.export(run, tmp_path / "out.txt")
    with pytest.raises(DataError, match="is closed"):
        h.record_samples(run, 0.0, {"a": 1.0})
    with pytest.raises(ConfigError, match="scheme 'mysql'"):
        Historian.open("mysql://localhost/db")
    with pytest.raises(DataError, match="no historian database"):
        Historian.open(tmp_path / "absent.sqlite", create=False)
    junk = tmp_path / "junk.sqlite"
    junk.write_bytes(b"this is not a database" * 100)
    with pytest.raises(DataError, match="junk.sqlite"):
        Historian.open(junk)


def test_values_none_and_numeric_types_are_floats(db: Path) -> None:
    with Historian.open(db) as h:
        run = h.start_run({})
        h.record_samples(run, 0.0, {"a": 1, "b": True, "c": None, "d": np.float32(0.5)})  # type: ignore[dict-item]
        got = h.samples(run)
    assert [got[k][0] for k in "abd"] == [1.0, 1.0, 0.5] and math.isnan(got["c"][0])


def test_config_and_default_path(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    if sys.platform.startswith("linux"):
        monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
        assert default_database_path() == tmp_path / "xdg" / "cnctwin" / "historian.sqlite"
    with pytest.raises(ValueError, match="less than or equal to 1"):
        HistorianConfig(flush_interval_s=2.0)
    with pytest.raises(ConfigError, match="flush_interval_s = 5"):
        Historian.open(tmp_path / "h.sqlite", flush_interval_s=5)
    with pytest.raises(ValueError, match="Extra inputs"):
        HistorianConfig.model_validate({"path": "x"})
    config = HistorianConfig(url=str(tmp_path / "cfg.sqlite"), batch_size=10)
    with Historian.from_config(config) as h:
        assert h.location == str(tmp_path / "cfg.sqlite")
        run = h.start_run({"config": tmp_path})  # a Path is stored as its text
        assert h.run(run).summary.meta == {"config": str(tmp_path)}
