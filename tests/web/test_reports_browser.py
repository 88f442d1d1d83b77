"""An HTML report (``--report OUT.html``) opens from disk in headless Chromium, offline.

Every request the page makes is recorded and refused unless it reads the file itself, so a
report that needed the network would show a blank plot and fail here.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from screenshots import distinct_colours, keep

REPO = Path(__file__).resolve().parents[2]
PACKAGED = REPO / "src" / "cnctwin" / "examples"
STABILITY = REPO / "examples" / "stability"

#: name -> the command's arguments before ``--report``.
REPORTS = {
    "lobes": ["stability", "lobes", "--config", str(STABILITY / "insperger_slot.toml"),
              "--method", "zoa"],
    "simulate": ["simulate", str(PACKAGED / "demo.ngc"), "-c", str(PACKAGED / "demo.toml"),
                 "--density", "2", "--cycle-ms", "50"],
    "wear": ["wear", "ekf", "--synthetic"],
}  # fmt: skip


@pytest.mark.parametrize("name", sorted(REPORTS))
def test_report_renders_offline(page, tmp_path, name) -> None:
    path = tmp_path / f"{name}.html"
    done = subprocess.run(
        [sys.executable, "-m", "cnctwin", *REPORTS[name], "--report", str(path)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    requests: list[str] = []

    def refuse_network(route) -> None:
        requests.append(route.request.url)
        if route.request.url == path.as_uri():
            route.continue_()
        else:
            route.abort()

    page.context.route("**/*", refuse_network)
    page.goto(path.as_uri())
    page.wait_for_selector("#figure-1 .main-svg")
    page.wait_for_selector("#figure-1 .scatterlayer .trace, #figure-1 .gl-container canvas")
    page.wait_for_timeout(300)
    assert requests == [path.as_uri()]  # nothing but the file itself
    shot = page.locator("#figure-1").screenshot()
    assert distinct_colours(shot) > 50  # axes, ticks, curves: not a blank box
    assert page.locator("#figure-1 .xaxislayer-above text").count() > 2  # tick labels
    assert page.evaluate("document.getElementById('figure-1').data.length") >= 1
    keep(shot, f"report-{name}.png")
