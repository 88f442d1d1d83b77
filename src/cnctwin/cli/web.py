"""``cnctwin web --db HISTORIAN``: the run browser for recorded runs (docs/dashboard.md)."""

from __future__ import annotations

import secrets
from typing import Annotated

import typer

from cnctwin.cli._options import HistorianDb, check_count

__all__ = ["WEB_PORT", "web"]

#: Default port of the run browser (the live dashboard's is 8765).
WEB_PORT = 8766


def web(
    db: HistorianDb = None,
    host: Annotated[str, typer.Option("--host", help="Address to listen on.")] = "127.0.0.1",
    port: Annotated[int, typer.Option("--port", help="Port (0: a free one).")] = WEB_PORT,
    insecure: Annotated[
        bool,
        typer.Option(
            "--insecure",
            help="Allow a non-loopback --host (plain HTTP, trusted network; every page then "
            "needs the printed token).",
        ),
    ] = False,
) -> None:
    """Serve the run browser: list recorded runs, open one, zoom any signal, overlay, export."""
    import uvicorn

    from cnctwin.virtual import is_loopback
    from cnctwin.web import RunBrowser, check_host, listen_socket, runs_app

    check_count("--port", port, 0, 65535)
    check_host(host, insecure)
    token = None if is_loopback(host) else secrets.token_urlsafe(18)
    browser = RunBrowser(db)
    try:
        sock = listen_socket(host, port)
        shown = f"[{host}]" if ":" in host else host
        address = f"http://{shown}:{sock.getsockname()[1]}/runs"
        typer.echo(f"run browser of {browser.location} at {address}"
                   + (f"?token={token}" if token else "") + " (Ctrl-C to stop)")  # fmt: skip
        config = uvicorn.Config(runs_app(browser, token), log_level="warning", access_log=False)
        uvicorn.Server(config).run(sockets=[sock])
    finally:
        browser.close()
