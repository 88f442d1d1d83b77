"""The run browser in headless Chromium: open a recorded run, zoom a signal, overlay a run,
export it; what the page plots is checked against the values recorded (tests/web/runs_data.py).
"""

import csv
import io
import threading
import time
import zipfile

import numpy as np
import pytest
import uvicorn
from runs_data import DT_S, N1, SPIKE, expected_force, record
from screenshots import keep

from cnctwin.web.runs import RunBrowser, runs_app


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    path = tmp_path_factory.mktemp("runs") / "runs.sqlite"
    record(path)
    runs = RunBrowser(path)
    config = uvicorn.Config(runs_app(runs), host="127.0.0.1", port=0, log_level="warning")
    served = uvicorn.Server(config)
    thread = threading.Thread(target=served.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 20
    while not served.started:
        assert thread.is_alive() and time.monotonic() < deadline, "server did not start"
        time.sleep(0.02)
    port = served.servers[0].sockets[0].getsockname()[1]
    yield f"http://127.0.0.1:{port}"
    served.should_exit = True
    thread.join(10)
    runs.close()


def plotted(page, trace: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The (t, y) the page handed to plotly for one trace (NaN for a gap)."""
    x, y = page.evaluate(
        f"[Array.from(document.getElementById('plot').data[{trace}].x),"
        f" Array.from(document.getElementById('plot').data[{trace}].y)]"
    )
    return np.array(x, dtype=float), np.array([np.nan if v is None else v for v in y])


def loads(page, n: int) -> None:
    page.wait_for_function(f"document.getElementById('plot').dataset.loads === '{n}'")


def test_open_a_recorded_run_and_zoom(page, server) -> None:
    page.goto(f"{server}/runs")
    page.wait_for_selector("#runs tbody tr[data-run='1']")
    rows = page.locator("#runs tbody tr").all_inner_texts()
    assert any("pocket.nc" in row and "finished" in row for row in rows)
    assert any("slot.nc" in row and "mill-2" in row and "stopped" in row for row in rows)
    page.click("#runs tbody tr[data-run='1']")
    plot = page.locator("#plot")
    loads(page, 1)
    assert plot.get_attribute("data-samples") == str(N1)
    assert plot.get_attribute("data-raw") == "false"
    width = page.evaluate("document.getElementById('plot').clientWidth")
    assert int(plot.get_attribute("data-points")) <= 2 * width
    assert page.locator("#plot .main-svg").count() > 0
    assert "force above the band" in page.inner_text("#events")
    title = page.inner_text("#title")
    assert title.startswith("run 1: pocket.nc on opc.tcp://127.0.0.1:4840, finished"), title
    # The whole run: every point drawn is a recorded sample, and the spike survives.
    recorded = expected_force()
    t, y = plotted(page)
    index = np.rint(t / DT_S).astype(int)
    np.testing.assert_array_equal(np.nan_to_num(y, nan=-1), np.nan_to_num(recorded[index], nan=-1))
    assert np.nanmax(y) == 900.0 and t[np.nanargmax(y)] == SPIKE * DT_S
    assert np.nanmin(y) == np.nanmin(recorded)
    keep(page.screenshot(), "runs-browser.png")
    # Zoom with the mouse: drag across 10 % of the plot area; the window's samples come back.
    area = page.locator("#plot .nsewdrag").bounding_box()
    y_mid = area["y"] + area["height"] / 2
    page.mouse.move(area["x"] + 0.40 * area["width"], y_mid)
    page.mouse.down()
    page.mouse.move(area["x"] + 0.45 * area["width"], y_mid, steps=5)
    page.mouse.move(area["x"] + 0.50 * area["width"], y_mid, steps=5)
    page.mouse.up()
    loads(page, 2)
    t0, t1 = float(plot.get_attribute("data-t0")), float(plot.get_attribute("data-t1"))
    assert 0.35 * (N1 * DT_S) < t0 < t1 < 0.55 * (N1 * DT_S)
    t, y = plotted(page)
    inside = recorded[int(np.ceil(t0 / DT_S - 1e-9)) : int(np.floor(t1 / DT_S + 1e-9)) + 1]
    assert int(plot.get_attribute("data-samples")) == inside.size
    assert np.nanmax(y) == np.nanmax(inside) and np.nanmin(y) == np.nanmin(inside)
    # Zoom to 2 s: the server sends that window's samples, every one of them.
    page.evaluate("Runs.zoom(100.0, 102.0)")
    loads(page, 3)
    assert plot.get_attribute("data-raw") == "true"
    assert plot.get_attribute("data-samples") == str(int(2.0 / DT_S) + 1)
    assert float(plot.get_attribute("data-t0")) == 100.0
    t, y = plotted(page)
    np.testing.assert_allclose(t, np.arange(8000, 8161) * DT_S)
    np.testing.assert_array_equal(y, recorded[8000:8161])
    # Overlay run 2 on the same signal.
    page.select_option("#overlay", "2")
    page.wait_for_function("document.getElementById('plot').dataset.traces === '2'")
    assert page.locator("#plot .legend").count() == 1
    assert plotted(page, 1)[1].size == 0  # run 2 lasted 5 s: nothing of it after 100 s
    page.select_option("#overlay", "")
    page.wait_for_function("document.getElementById('plot').dataset.traces === '1'")
    page.evaluate("Runs.zoom(0.0, 4.0)")
    page.select_option("#overlay", "2")
    page.wait_for_function("document.getElementById('plot').dataset.traces === '2'")
    _, other = plotted(page, 1)
    assert other.tolist() == [50.0 + i for i in range(321)]  # 0..4 s of run 2, as recorded
    # Export: the download is the historian's CSV of run 1.
    assert page.get_attribute("#export-csv", "href") == "api/runs/1/export?format=csv"
    with page.expect_download() as download:
        page.click("#export-csv")
    archive = zipfile.ZipFile(io.BytesIO(open(download.value.path(), "rb").read()))
    rows = list(csv.DictReader(io.StringIO(archive.read("run1.csv").decode())))
    assert len(rows) == N1
    exported = np.array([float(r["force_x_n"]) if r["force_x_n"] else np.nan for r in rows])
    np.testing.assert_allclose(exported, recorded, rtol=1e-9, equal_nan=True)


def test_the_run_is_drawn_before_plotly_js_arrives(page, server) -> None:
    """The first view of a run is the page's own canvas plot: with plotly.js held back it
    still shows the whole run, the spike included, at the spike's time and height."""
    page.route("**/plotly.min.js", lambda route: route.abort())
    page.goto(f"{server}/runs#run=1&signal=measured:force_x_n")
    page.wait_for_function("document.getElementById('plot').dataset.quick")
    page.wait_for_function("document.getElementById('view-error').textContent !== ''")
    assert "plotly.js did not load" in page.inner_text("#view-error")
    assert page.locator("#plot .main-svg").count() == 0 and page.is_visible("#quick canvas")
    width = page.evaluate("document.getElementById('plot').clientWidth")
    assert 0 < int(page.get_attribute("#plot", "data-quick")) <= 2 * width
    # The plot area's pixels: the line's colour in the column of the spike's time reaches
    # the top of the plot (900 N is the run's maximum); no other column comes near it.
    columns = page.evaluate(
        """() => {
          const c = document.querySelector('#quick canvas'), r = window.devicePixelRatio || 1;
          const ctx = c.getContext('2d');
          const img = ctx.getImageData(0, 0, c.width, c.height);
          const tops = [];
          for (let x = 0; x < c.width; x++) {
            let top = -1;
            for (let y = 0; y < c.height; y++) {
              const i = (y * c.width + x) * 4;
              if (img.data[i + 2] > 150 && img.data[i] < 100) { top = y; break; }
            }
            tops.push(top);
          }
          return {tops, ratio: r, width: c.width};
        }"""
    )
    tops = np.array(columns["tops"], dtype=float)
    drawn = tops >= 0
    assert drawn.sum() > 0.8 * (columns["width"] - 80 * columns["ratio"])  # a line across
    highest = int(np.argmin(np.where(drawn, tops, np.inf)))
    # Margins of lineplot.js: 60 px left, 20 px right; the x axis spans the run.
    left, right = 60 * columns["ratio"], columns["width"] - 20 * columns["ratio"]
    t_spike = (highest - left) / (right - left) * (N1 - 1) * DT_S
    assert abs(t_spike - SPIKE * DT_S) < 2.0 * (N1 * DT_S) / (right - left)
    others = np.where(drawn, tops, np.inf)
    others[max(0, highest - 3) : highest + 4] = np.inf
    assert others.min() > tops[highest] + 0.5 * (np.nanmax(tops[drawn]) - tops[highest])
