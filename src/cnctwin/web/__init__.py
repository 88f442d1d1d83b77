"""cnctwin in the browser: the live dashboard of a running twin (:mod:`cnctwin.web.server`,
:mod:`cnctwin.web.feed`) and the 3D stock view (:mod:`cnctwin.web.stock`).

Nothing here is imported by the rest of cnctwin unless a command is given ``--web``: the web
server (FastAPI, uvicorn) loads only then. See docs/dashboard.md.
"""

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from cnctwin.web.runs import RunBrowser, runs_app
    from cnctwin.web.server import LiveDashboard, check_host, listen_socket

# FastAPI and uvicorn load with these: imported on first use.
_LAZY = {
    "LiveDashboard": "cnctwin.web.server",
    "RunBrowser": "cnctwin.web.runs",
    "check_host": "cnctwin.web.server",
    "listen_socket": "cnctwin.web.server",
    "runs_app": "cnctwin.web.runs",
}

__all__ = ["LiveDashboard", "RunBrowser", "check_host", "listen_socket", "runs_app"]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
