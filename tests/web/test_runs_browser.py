"""The run browser in headless Chromium: open a recorded run, zoom a signal, overlay a run."""

import threading
import time

import pytest
import uvicorn
from runs_data import DT_S, N1, record

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


def test_open_a_recorded_run_and_zoom(page, server) -> None:
    page.goto(f"{server}/runs")
    page.wait_for_selector("#runs tbody tr[data-run='1']")
    rows = page.locator("#runs tbody tr").all_inner_texts()
    assert any("pocket.nc" in row and "finished" in row for row in rows)
    assert any("slot.nc" in row and "mill-2" in row and "stopped" in row for row in rows)
    page.click("#runs tbody tr[data-run='1']")
    plot = page.locator("#plot")
    page.wait_for_function("document.getElementById('plot').dataset.loads === '1'")
    assert plot.get_attribute("data-samples") == str(N1)
    assert plot.get_attribute("data-raw") == "false"
    assert int(plot.get_attribute("data-points")) <= 2 * page.evaluate(
        "document.getElementById('plot').clientWidth"
    )
    assert page.locator("#plot .main-svg").count() > 0
    assert "force above the band" in page.inner_text("#events")
    # Zoom to 2 s: the server sends that window's samples, every one of them.
    page.evaluate("Runs.zoom(100.0, 102.0)")
    page.wait_for_function("document.getElementById('plot').dataset.loads === '2'")
    assert plot.get_attribute("data-raw") == "true"
    assert plot.get_attribute("data-samples") == str(int(2.0 / DT_S) + 1)
    assert float(plot.get_attribute("data-t0")) == 100.0
    # Overlay run 2 on the same signal.
    page.select_option("#overlay", "2")
    page.wait_for_function("document.getElementById('plot').dataset.traces === '2'")
    assert page.locator("#plot .legend").count() == 1
    href = page.get_attribute("#export-csv", "href")
    assert href == "api/runs/1/export?format=csv"
