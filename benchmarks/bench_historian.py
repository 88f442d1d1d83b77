"""Benchmark: historian ingest (target: at least 100,000 signal values per second).

For SQLite (a temporary file) and PostgreSQL (when reachable; a temporary schema) it records
frames of the 27 canonical signals through :class:`cnctwin.store.Historian` and reports

* the ingest rate, values/s, from the first ``record_samples`` call to the end of ``flush()``
  (everything committed);
* the time one ``record_samples`` call takes (p50, p99, p99.9, max, us) when the caller
  records every 1 ms (12.5x the twin's 12.5 ms cycle) while the writer commits every 0.25 s:
  what the twin cycle pays. (A caller recording flat out, as in the ingest test, also pays
  for the writer's turns on the GIL: a few ms once per batch.)
* for the choice of layout, the raw insert rate of the same values stored long (one row per
  value: run, signal id, seq, value) against one row per instant with a float64 blob.

Usage::

    python benchmarks/bench_historian.py [--quick] [--postgres URL]
"""

from __future__ import annotations

import argparse
import os
import platform
import socket
import sqlite3
import tempfile
import time
import uuid
from pathlib import Path

import numpy as np

from cnctwin.store import Historian
from cnctwin.thread import SIGNALS

SERVER = "postgresql://postgres@127.0.0.1:5432/test"


def _frames(n: int) -> tuple[list[str], np.ndarray]:
    names = list(SIGNALS)
    values = np.random.default_rng(1).normal(size=(n, len(names))) * 100.0
    return names, values


def _historian(url: str, n: int, paced: int) -> dict[str, float]:
    """Ingest ``n`` frames flat out, then time ``paced`` calls made every 1 ms."""
    names, values = _frames(n)
    rows = [dict(zip(names, row.tolist(), strict=True)) for row in values]
    clock = time.perf_counter
    with Historian.open(url) as h:
        run = h.start_run({"program": "bench"})
        start = clock()
        for i, row in enumerate(rows):
            h.record_samples(run, i * 0.0125, row)
        enqueued = clock()
        h.flush(timeout_s=600.0)
        done = clock()
        batches = h.stats().batches
        calls = np.empty(paced)
        next_call = clock()
        for i in range(paced):
            next_call += 1e-3
            time.sleep(max(0.0, next_call - clock()))
            t0 = clock()
            h.record_samples(run, i * 1e-3, rows[i % n])
            calls[i] = clock() - t0
        h.flush(timeout_s=600.0)
        stats = h.stats()
    n_values = n * len(names)
    assert stats.written_values == n_values + paced * len(names) and stats.dropped == 0
    return {
        "values": n_values,
        "rate": n_values / (done - start),
        "enqueue_rate": n_values / (enqueued - start),
        "batches": batches,
        "paced": paced,
        "p50_us": float(np.percentile(calls, 50) * 1e6),
        "p99_us": float(np.percentile(calls, 99) * 1e6),
        "p999_us": float(np.percentile(calls, 99.9) * 1e6),
        "max_us": float(calls.max() * 1e6),
    }


def _paced_baseline(paced: int) -> dict[str, float]:
    """The same 1 ms cadence timing only ``np.fromiter`` of the 27 values (no historian):
    what a call costs on this machine when it runs from a cold cache after a sleep."""
    names, values = _frames(1)
    row = dict(zip(names, values[0].tolist(), strict=True))
    clock = time.perf_counter
    calls = np.empty(paced)
    next_call = clock()
    for i in range(paced):
        next_call += 1e-3
        time.sleep(max(0.0, next_call - clock()))
        t0 = clock()
        np.fromiter(row.values(), dtype="<f8", count=len(row)).tobytes()
        calls[i] = clock() - t0
    return {q: float(np.percentile(calls, p) * 1e6) for q, p in (("p50", 50), ("p99", 99))}


def _raw_sqlite(path: Path, n: int, long: bool) -> float:
    """values/s of a bare executemany in one transaction, long or blob layout."""
    names, values = _frames(n)
    conn = sqlite3.connect(path, isolation_level=None)
    conn.execute("PRAGMA journal_mode=WAL")
    conn.execute("PRAGMA synchronous=NORMAL")
    if long:
        conn.execute(
            "CREATE TABLE v (run_id INTEGER, signal_id INTEGER, seq INTEGER, value REAL, "
            "PRIMARY KEY (run_id, signal_id, seq)) WITHOUT ROWID"
        )
        start = time.perf_counter()
        rows = [(1, j, i, v) for i, row in enumerate(values.tolist()) for j, v in enumerate(row)]
        sql = "INSERT INTO v VALUES (?, ?, ?, ?)"
    else:
        conn.execute(
            "CREATE TABLE f (run_id INTEGER, seq INTEGER, t_s REAL, vals BLOB, "
            "PRIMARY KEY (run_id, seq)) WITHOUT ROWID"
        )
        start = time.perf_counter()
        rows = [(1, i, i * 0.0125, row.astype("<f8").tobytes()) for i, row in enumerate(values)]
        sql = "INSERT INTO f VALUES (?, ?, ?, ?)"
    conn.execute("BEGIN")
    conn.executemany(sql, rows)
    conn.execute("COMMIT")
    rate = values.size / (time.perf_counter() - start)
    conn.close()
    return rate


def _raw_postgres(url: str, n: int) -> float:
    """values/s of a binary COPY of the long layout (one row per value)."""
    import psycopg

    names, values = _frames(n)
    with psycopg.connect(url, autocommit=True) as conn:
        conn.execute(
            "CREATE TABLE v (run_id BIGINT, signal_id INT, seq BIGINT, value FLOAT8, "
            "PRIMARY KEY (run_id, signal_id, seq))"
        )
        start = time.perf_counter()
        with conn.transaction(), conn.cursor() as cur:
            with cur.copy("COPY v FROM STDIN (FORMAT BINARY)") as copy:
                copy.set_types(["bigint", "int4", "bigint", "float8"])
                for i, row in enumerate(values.tolist()):
                    for j, v in enumerate(row):
                        copy.write_row((1, j, i, v))
        return values.size / (time.perf_counter() - start)


def _postgres_reachable() -> bool:
    try:
        with socket.create_connection(("127.0.0.1", 5432), timeout=2.0):
            return True
    except OSError:
        return False


def _report(label: str, r: dict[str, float]) -> None:
    print(
        f"| {label} | {r['values']:,.0f} | {r['rate']:,.0f} | {r['enqueue_rate']:,.0f} | "
        f"{r['batches']:.0f} | {r['paced']:,.0f} | {r['p50_us']:.1f} | {r['p99_us']:.1f} | "
        f"{r['p999_us']:.1f} | {r['max_us']:,.0f} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer frames")
    parser.add_argument("--postgres", default=SERVER, help="server URL (database must exist)")
    args = parser.parse_args()
    n, paced = (4_000, 500) if args.quick else (100_000, 20_000)
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}, SQLite {sqlite3.sqlite_version}; "
        f"{n:,} frames x {len(SIGNALS)} signals"
    )
    print()
    print(
        "| backend | values | ingest values/s (to commit) | enqueue values/s | transactions | "
        "paced calls (1 ms) | record_samples p50 us | p99 us | p99.9 us | max us |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    layouts = {}
    with tempfile.TemporaryDirectory() as tmp:
        _report("SQLite (WAL)", _historian(str(Path(tmp) / "h.sqlite"), n, paced))
        layouts["SQLite, one row per instant (float64 blob)"] = _raw_sqlite(
            Path(tmp) / "blob.sqlite", n, long=False
        )
        layouts["SQLite, one row per value (long)"] = _raw_sqlite(
            Path(tmp) / "long.sqlite", n, long=True
        )
    if _postgres_reachable():
        import psycopg

        schema = f"bench_{uuid.uuid4().hex[:10]}"
        with psycopg.connect(args.postgres, autocommit=True) as conn:
            conn.execute(f"CREATE SCHEMA {schema}")
        url = f"{args.postgres}?options=-csearch_path%3D{schema}"
        try:
            _report("PostgreSQL (COPY)", _historian(url, n, paced))
            layouts["PostgreSQL, one row per value (long, binary COPY)"] = _raw_postgres(url, n)
        finally:
            with psycopg.connect(args.postgres, autocommit=True) as conn:
                conn.execute(f"DROP SCHEMA {schema} CASCADE")
    else:
        print("| PostgreSQL | not reachable at 127.0.0.1:5432 | | | | | | | | |")
    base = _paced_baseline(paced)
    print(
        f"| baseline: encoding alone, same cadence | | | | | {paced:,} | {base['p50']:.1f} | "
        f"{base['p99']:.1f} | | |"
    )
    print()
    print("| layout (bare inserts, one transaction) | values/s |")
    print("|---|---:|")
    for label, rate in layouts.items():
        print(f"| {label} | {rate:,.0f} |")


if __name__ == "__main__":
    main()
