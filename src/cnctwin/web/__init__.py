"""cnctwin in the browser: the live dashboard of a running twin (:mod:`cnctwin.web.server`,
:mod:`cnctwin.web.feed`) and the 3D stock view (:mod:`cnctwin.web.stock`).

Nothing here is imported by the rest of cnctwin unless a command is given ``--web``: the web
server (FastAPI, uvicorn) loads only then. See docs/dashboard.md.
"""

from typing import TYPE_CHECKING

from cnctwin import _lazy

if TYPE_CHECKING:
    from cnctwin.web.runs import RunBrowser, runs_app
    from cnctwin.web.server import LiveDashboard, check_host, listen_socket

# FastAPI and uvicorn load with these: imported on first use.
_LAZY = {
    "LiveDashboard": "server",
    "RunBrowser": "runs",
    "check_host": "server",
    "listen_socket": "server",
    "runs_app": "runs",
}

__all__ = ["LiveDashboard", "RunBrowser", "check_host", "listen_socket", "runs_app"]

__getattr__, __dir__ = _lazy.exports(__name__, _LAZY)
