"""Benchmark: time to open a 1-hour recorded run in the run browser (target: under 1 s).

Records one run through :class:`cnctwin.store.Historian` (an SQLite file) at the twin's rate:
one instant per 12.5 ms cycle for ``--minutes`` (default 60: 288,000 instants) of the 27
canonical measured signals (:data:`cnctwin.thread.SIGNALS`, time aside) and, per instant,
8 predicted values (force with its band, torque, power, wear: what the twin's recorder adds).
Closing the run stores its overview (:meth:`Historian.overview`; the time to record includes
it). Then, each time with a fresh run browser (:class:`cnctwin.web.runs.RunBrowser`: nothing
held in memory), served by uvicorn on 127.0.0.1:

* API: the three requests the page makes to open the run and draw its first plot
  (``/api/runs``, ``/api/runs/1``, ``/api/runs/1/signal`` of ``force_x_n`` over the whole run at
  1,000 buckets) over HTTP, from the first request to the last byte of the plot's points,
  each request's share, and the CPU time this process (server and client) spent on them,
  which a loaded machine inflates less than the wall time; then the same plot of a second
  signal and a zoom to 10 s in the middle.
* Browser: headless Chromium (Debian's ``/usr/bin/chromium``, driven by Playwright) loads
  ``/runs#run=1&signal=measured:force_x_n`` in a fresh context (empty cache). Timed from
  ``page.goto`` to the run's plot shown (the page's canvas plot of the whole run, drawn
  before plotly.js is loaded), and on to the plot zoomable (plotly.js loaded, compiled and
  drawn); the page's own clock gives the plot shown, the page loaded
  (``domContentLoadedEventEnd``), plotly.js fetched and run (its ``load`` event: parsed,
  compiled and evaluated), each since the navigation started, and the run opened until
  zoomable, since the page's script started opening it.

* Older database: the same API requests once more after the overview tables are dropped (as
  in a database written before they existed), so the first open computes and stores them.

Usage::

    python benchmarks/bench_run_browser.py [--minutes 60] [--repeat 5] [--no-browser]

``--quick`` (CI) records 5 minutes and times the API once, without the browser.
"""

from __future__ import annotations

import argparse
import os
import platform
import sqlite3
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

import httpx
import numpy as np
import uvicorn

from cnctwin.store import Historian
from cnctwin.thread import SIGNALS
from cnctwin.web import RunBrowser, runs_app

#: The twin's default cycle, s.
CYCLE_S = 0.0125
#: Predicted values recorded per instant.
PREDICTED = (
    "force_x_n", "force_y_n", "force_lower_n", "force_upper_n", "spindle_torque_nm",
    "spindle_power_w", "wear_vb_mm", "wear_sd_mm",
)  # fmt: skip
#: Chromium of Debian's package.
CHROMIUM = os.environ.get("CNCTWIN_CHROMIUM", "/usr/bin/chromium")


def record(path: Path, minutes: float) -> tuple[int, float]:
    """Record the run; its number of instants and the seconds recording took."""
    n = round(minutes * 60.0 / CYCLE_S)
    names = [s for s in SIGNALS if s != "t_s"]
    rng = np.random.default_rng(7)
    t = np.arange(n) * CYCLE_S
    # Each signal a slow sine with noise; force_x_n with cutting spikes now and then.
    values = 100.0 * np.sin(t[:, None] * rng.uniform(0.01, 1.0, len(names)))
    values += rng.normal(0.0, 5.0, values.shape)
    fx = names.index("force_x_n")
    values[rng.choice(n, 20, replace=False), fx] += 900.0
    predicted = values[:, [fx] * len(PREDICTED)] * 0.9
    started = time.perf_counter()
    with Historian.open(path) as h:
        run = h.start_run({"program": "bench-1h.nc", "machine": "bench"})
        for i in range(n):
            h.record_samples(run, float(t[i]), dict(zip(names, values[i].tolist(), strict=True)))
            h.record_prediction(
                run, float(t[i]), dict(zip(PREDICTED, predicted[i].tolist(), strict=True))
            )
        h.end_run(run, "finished", {"cycles": n})
        h.flush(timeout_s=3600.0)
    return n, time.perf_counter() - started


def serve(db: Path) -> tuple[str, Callable[[], None]]:
    """A fresh run browser of ``db`` on a free port; its address and a function to stop it."""
    browser = RunBrowser(db)
    config = uvicorn.Config(runs_app(browser), host="127.0.0.1", port=0, log_level="warning")
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    while not server.started:
        time.sleep(0.01)
    port = server.servers[0].sockets[0].getsockname()[1]

    def stop() -> None:
        server.should_exit = True
        thread.join(10)
        browser.close()

    return f"http://127.0.0.1:{port}", stop


def api_once(db: Path, n: int) -> dict[str, float]:
    """Seconds of the opening requests, the second signal and a 10 s zoom (fresh server)."""
    url, stop = serve(db)
    try:
        middle = round(n * CYCLE_S / 2.0)
        with httpx.Client(base_url=url, timeout=60.0) as client:
            clock = time.perf_counter
            cpu, start = time.process_time(), clock()
            assert client.get("/api/runs").status_code == 200
            listed = clock()
            assert client.get("/api/runs/1").status_code == 200
            detailed = clock()
            whole = client.get(
                "/api/runs/1/signal", params={"name": "force_x_n", "buckets": 1000}
            ).json()
            first, cpu = clock() - start, time.process_time() - cpu
            assert whole["samples"] == n and len(whole["t"]) <= 2000
            parts = {"list_s": listed - start, "run_s": detailed - listed}
            parts["signal_s"] = first - parts["list_s"] - parts["run_s"]
            start = clock()
            client.get("/api/runs/1/signal", params={"name": "spindle_rpm", "buckets": 1000})
            second = clock() - start
            start = clock()
            zoom = client.get(
                "/api/runs/1/signal",
                params={"name": "force_x_n", "buckets": 1000, "t0": middle, "t1": middle + 10.0},
            ).json()
            zoomed = clock() - start
            assert zoom["raw"] and zoom["samples"] == 801
    finally:
        stop()
    return {
        "first_plot_s": first,
        **parts,
        "first_plot_cpu_s": cpu,
        "second_signal_s": second,
        "zoom_s": zoomed,
    }


def browser_once(db: Path, chromium: object) -> dict[str, float]:
    """Seconds from ``page.goto`` to the run's plot drawn (fresh server, fresh page)."""
    url, stop = serve(db)
    try:
        context = chromium.new_context(viewport={"width": 1280, "height": 900})  # type: ignore[attr-defined]
        page = context.new_page()
        start = time.perf_counter()
        page.goto(f"{url}/runs#run=1&signal=measured:force_x_n")
        page.wait_for_function("document.getElementById('plot').dataset.quick", timeout=60_000)
        shown = time.perf_counter() - start
        page.wait_for_function(
            "document.getElementById('plot').dataset.loads === '1'", timeout=60_000
        )
        drawn = time.perf_counter() - start
        opened_ms = float(page.get_attribute("#plot", "data-opened-ms") or "nan")
        first_ms = float(page.get_attribute("#plot", "data-first-drawn-ms") or "nan")
        loaded_ms = page.evaluate(
            "performance.getEntriesByType('navigation')[0].domContentLoadedEventEnd"
        )
        ready_ms = float(page.get_attribute("#plot", "data-plotly-ready-ms") or "nan")
        plotly_ms = page.evaluate(
            "performance.getEntriesByType('resource').filter((r) =>"
            " r.name.endsWith('plotly.min.js')).map((r) => r.responseEnd)[0]"
        )
        context.close()
    finally:
        stop()
    return {
        "page_to_plot_shown_s": shown,
        "plot_shown_in_page_s": first_ms / 1e3,
        "page_loaded_s": loaded_ms / 1e3,
        "page_to_zoomable_s": drawn,
        "plotly_js_fetched_s": plotly_ms / 1e3,
        "plotly_js_run_s": ready_ms / 1e3,
        "open_run_in_page_s": opened_ms / 1e3,
    }


def summary(rows: list[dict[str, float]]) -> dict[str, tuple[float, float, float]]:
    """Per key: median, min, max."""
    return {
        k: (
            float(np.median([r[k] for r in rows])),
            min(r[k] for r in rows),
            max(r[k] for r in rows),
        )
        for k in rows[0]
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=60.0, help="Length of the run, min.")
    parser.add_argument("--repeat", type=int, default=5, help="Fresh servers per measurement.")
    parser.add_argument("--no-browser", action="store_true", help="API timings only.")
    parser.add_argument(
        "--quick", action="store_true", help="CI: a 5-minute run, one fresh server, API only"
    )
    args = parser.parse_args()
    if args.quick:
        args.minutes, args.repeat, args.no_browser = 5.0, 1, True
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
          f"load {os.getloadavg()[0]:.2f}, Python {platform.python_version()}")  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="cnctwin-bench-") as folder:
        db = Path(folder) / "runs.sqlite"
        n, seconds = record(db, args.minutes)
        size_mb = db.stat().st_size / 1e6
        print(f"recorded {n:,} instants x {len(SIGNALS) - 1} measured + {len(PREDICTED)} "
              f"predicted values in {seconds:.1f} s ({size_mb:.0f} MB SQLite)")  # fmt: skip
        api = summary([api_once(db, n) for _ in range(args.repeat)])
        for key, (median, low, high) in api.items():
            print(f"API {key:<22} median {median * 1e3:7.0f} ms  (min {low * 1e3:.0f}, "
                  f"max {high * 1e3:.0f}; {args.repeat} fresh servers)")  # fmt: skip
        if not args.no_browser:
            from playwright.sync_api import sync_playwright

            with sync_playwright() as pw:
                chromium = pw.chromium.launch(
                    executable_path=CHROMIUM, headless=True, args=["--no-sandbox"]
                )
                browser_once(db, chromium)  # the browser's own start-up, not counted
                rows = [browser_once(db, chromium) for _ in range(args.repeat)]
                chromium.close()
            for key, (median, low, high) in summary(rows).items():
                print(f"Chromium {key:<22} median {median * 1e3:7.0f} ms  (min "
                      f"{low * 1e3:.0f}, max {high * 1e3:.0f})")  # fmt: skip
        with sqlite3.connect(db) as conn:
            conn.execute("DROP TABLE hist_overview")
            conn.execute("DROP TABLE hist_run_layouts")
        older = api_once(db, n)
        first, second = older["first_plot_s"] * 1e3, older["second_signal_s"] * 1e3
        print(f"API, database without overviews: first plot {first:.0f} ms (computes and "
              f"stores the overview), a second signal {second:.0f} ms, "
              f"zoom {older['zoom_s'] * 1e3:.0f} ms")  # fmt: skip
        print(f"load at the end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
