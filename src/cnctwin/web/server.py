"""The live dashboard: a FastAPI app served by uvicorn in the twin's process.

:class:`LiveDashboard` runs the web server on a thread of its own with its own event loop, so
the twin's cycle never waits for it: the runtime hands each finished cycle to
:meth:`LiveDashboard.observe` (a bounded, drop-oldest hand-over, :mod:`cnctwin.web.feed`),
and the server turns what arrived into one JSON message about ten times a second, sent to
every open page as server-sent events. A browser that does not keep up is dropped.

Control from the page (stop, feed override) exists only when the twin's ``[control]`` is
enabled, and needs the access token printed at start (``Authorization: Bearer TOKEN``). The
command becomes a :class:`~cnctwin.control.rules.Decision` of the rule ``dashboard`` and goes
the way of every rule's decision (:meth:`cnctwin.twin.actions.ActionStage.submit`): the
safety filter, the write, the read-back, the historian's decision record; the timeline shows
it with the client's address. The server listens on 127.0.0.1 by default; another address is
refused unless ``insecure`` is given (plain HTTP), and then every request needs the token.

Browser code comes from files of this package (``static/``) and from the installed plotly
package (``plotly.min.js``); nothing is fetched from the internet.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import math
import secrets
import signal
import socket
import sys
import threading
import time
from collections import deque
from collections.abc import AsyncIterator
from importlib.resources import files
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fastapi import Depends, FastAPI, HTTPException, Request
from fastapi.responses import (
    FileResponse,
    HTMLResponse,
    JSONResponse,
    Response,
    StreamingResponse,
)

from cnctwin import finite_json
from cnctwin.errors import ConfigError
from cnctwin.virtual import is_loopback
from cnctwin.web.feed import (
    Hub,
    LiveFeed,
    decision_item,
    event_item,
    run_state_name,
    series_of,
)

if TYPE_CHECKING:
    from cnctwin.twin import CycleState, RunSummary, Twin

__all__ = [
    "COMMANDS",
    "LiveDashboard",
    "check_host",
    "plotly_js",
    "static_file",
]

#: Commands the page may send: name -> (rule action, lowest value, highest value, unit).
#: The bounds are the signal's (:data:`cnctwin.thread.signals.COMMANDS`); the safety filter
#: applies the narrower ``[control]`` bounds.
COMMANDS: dict[str, tuple[str, float, float, str]] = {
    "stop": ("stop", 1.0, 1.0, ""),
    "feed_override": ("feed_override", 0.0, 150.0, "%"),
}

#: The rule name of a command from the page (the timeline's and the historian's "who").
DASHBOARD_RULE = "dashboard"

#: Cookie that carries the token for a non-loopback dashboard's pages.
TOKEN_COOKIE = "cnctwin_token"

#: Cells a side of the live 3D view's height map (:func:`cnctwin.web.stock.height_map`).
STOCK_CELLS = 60

#: The interpreter's thread switch interval while the dashboard serves, s (see ``start``).
SWITCH_INTERVAL_S = 0.0005

#: Lines of the program text the page gets (a longer program is cut there).
MAX_PROGRAM_LINES = 20_000


def check_host(host: str, insecure: bool) -> None:
    """Refuse a non-loopback ``host`` unless ``insecure`` (the rule of ``virtual serve``).

    Raises
    ------
    ConfigError
        One line that says what to do.
    """
    if insecure or is_loopback(host):
        return
    raise ConfigError(
        f"--host {host!r}: refusing to serve the dashboard on a non-loopback address over plain "
        "HTTP (its access token would cross the network unencrypted); listen on 127.0.0.1, or "
        "pass --insecure on a network you control (every page then needs the token)"
    )


def static_file(name: str) -> bytes:
    """A file of the package's ``static/`` folder (the pages, their scripts and styles)."""
    return (files("cnctwin.web") / "static" / name).read_bytes()


def plotly_js() -> Path:
    """The installed plotly package's bundled ``plotly.min.js``."""
    import plotly

    return Path(plotly.__file__).parent / "package_data" / "plotly.min.js"


class LiveDashboard:
    """The live page of one twin run, served while the twin cycles.

    Parameters
    ----------
    host, port
        Where to listen (``port`` 0: a free port).
    control_enabled
        The twin's ``[control] enabled``: without it the page offers no control and the
        server refuses every command.
    insecure
        Allow a non-loopback ``host`` (then every request needs the token).
    title
        Shown on the page (the machine's name).
    program
        The NC program the machine runs (its lines are shown by number), or ``None``.
    token
        The access token; ``None`` draws a random one (:func:`secrets.token_urlsafe`).
    rate_hz
        Messages per second to each page.
    stock_hz
        Updates per second of the 3D stock.
    history_s
        Seconds of plot history a page gets when it opens.

    Raises
    ------
    ConfigError
        For a non-loopback ``host`` without ``insecure``, or a port that cannot be bound.
    """

    def __init__(
        self,
        *,
        host: str = "127.0.0.1",
        port: int = 0,
        control_enabled: bool = False,
        insecure: bool = False,
        title: str = "cnctwin",
        program: Path | None = None,
        token: str | None = None,
        rate_hz: float = 10.0,
        stock_hz: float = 2.0,
        history_s: float = 60.0,
    ) -> None:
        check_host(host, insecure)
        if not 0 <= port <= 65535:
            raise ConfigError(f"--port {port}; give 0 (a free port) to 65535")
        self.host = host
        self.control_enabled = control_enabled
        self.token_for_view = not is_loopback(host)
        self.title = title
        self.token = token or secrets.token_urlsafe(18)
        self.rate_hz = rate_hz
        self.stock_hz = stock_hz
        self.feed = LiveFeed()
        self.hub = Hub()
        self.program_lines = _program_lines(program)
        self.program_name = program.name if program is not None else ""
        self.twin: Twin | None = None
        self.summary: RunSummary | None = None
        self.t0_s = time.monotonic()
        self.messages = 0
        self._series: deque[dict[str, list[float | None]]] = deque(
            maxlen=max(int(history_s * rate_hz), 1)
        )
        self._timeline: deque[dict[str, Any]] = deque(maxlen=500)
        self._stock: dict[str, Any] | None = None
        self._stock_due_s = 0.0
        self._sock = listen_socket(host, port)
        self.port: int = self._sock.getsockname()[1]
        self._server: Any = None
        self._thread: threading.Thread | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._switch_s: float | None = None

    # ------------------------------------------------------------------ the twin's side
    @property
    def url(self) -> str:
        """The page's address (without the token)."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/"

    def attach(self, twin: Twin) -> None:
        """Watch this twin (its runtime's timing, its stock, its action stage)."""
        self.t0_s = time.monotonic()
        self.twin = twin

    def observe(self, state: CycleState) -> None:
        """Hand a finished cycle over (the runtime's ``on_cycle``; never blocks)."""
        self.feed.put(state)

    def finish(self, summary: RunSummary) -> None:
        """The run ended: the page shows the summary."""
        self.summary = summary

    # ------------------------------------------------------------------ serving
    def start(self) -> None:
        """Serve on a thread of its own; return once the server listens.

        Raises
        ------
        cnctwin.errors.CnctwinError
            If the server does not start within 10 s.
        """
        import uvicorn

        from cnctwin.errors import CnctwinError

        # The server's thread and the twin's share the interpreter lock: a thread that wants
        # it back (the twin after each read of the machine) waits until the holder's switch
        # interval ends, 5 ms by default. A short interval keeps that wait well under the
        # twin's cycle while the server turns a cycle into JSON (benchmarks/bench_dashboard.py).
        self._switch_s = sys.getswitchinterval()
        sys.setswitchinterval(min(self._switch_s, SWITCH_INTERVAL_S))

        config = uvicorn.Config(
            self.app(), log_level="warning", access_log=False, lifespan="on", loop="asyncio"
        )
        self._server = uvicorn.Server(config)
        self._thread = threading.Thread(
            target=self._server.run,
            kwargs={"sockets": [self._sock]},
            name="cnctwin-web",
            daemon=True,
        )
        self._thread.start()
        deadline = time.monotonic() + 10.0
        while not self._server.started:
            if not self._thread.is_alive() or time.monotonic() > deadline:
                raise CnctwinError(f"the dashboard did not start on {self.url}")
            time.sleep(0.01)

    def close(self) -> None:
        """Stop serving (open pages see the stream end)."""
        if self._server is not None:
            self._server.should_exit = True
            loop = self._loop
            if loop is not None:
                for sub in list(self.hub.subscribers):
                    loop.call_soon_threadsafe(self.hub.unsubscribe, sub)
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        if self._switch_s is not None:
            sys.setswitchinterval(self._switch_s)
            self._switch_s = None
        self._sock.close()

    def __enter__(self) -> LiveDashboard:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def wait_for_page(self, timeout_s: float) -> bool:
        """Wait until a page has opened the stream, at most ``timeout_s`` s; whether one did."""
        deadline = time.monotonic() + timeout_s
        while self.hub.opened == 0:
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.05)
        return True

    def wait_until_interrupted(self) -> None:
        """Keep serving until Ctrl-C or SIGTERM (after the run: the page stays readable)."""
        done = threading.Event()
        previous = signal.signal(signal.SIGTERM, lambda *_: done.set())
        try:
            while not done.wait(0.5):
                pass
        except KeyboardInterrupt:
            pass
        finally:
            signal.signal(signal.SIGTERM, previous)

    # ------------------------------------------------------------------ messages
    def tick(self, stock: bool = True) -> dict[str, Any]:
        """Take what the twin handed over since the last tick: one ``update`` message (with
        the 3D stock when ``stock`` and it is due)."""
        cycles, items = self.feed.take()
        series = series_of(cycles)
        self._series.append(series)
        timeline = [self._item(item) for item in items]
        self._timeline.extend(timeline)
        message: dict[str, Any] = {
            "type": "update",
            "series": series,
            "timeline": timeline,
            "snapshot": self.snapshot(),
        }
        now = time.monotonic()
        if stock and self.stock_hz > 0 and now >= self._stock_due_s:
            self._stock_due_s = now + 1.0 / self.stock_hz
            stock = self.stock()
            if stock is not None:
                message["stock"] = stock
        self.messages += 1
        return message

    def hello(self) -> dict[str, Any]:
        """The first message of a page: what the dashboard is, the history, the latest state."""
        series: dict[str, list[float | None]] = {}
        for block in self._series:
            for name, values in block.items():
                series.setdefault(name, []).extend(values)
        return {
            "type": "hello",
            "info": {
                "title": self.title,
                "control_enabled": self.control_enabled,
                "commands": {
                    name: {"low": low, "high": high, "unit": unit}
                    for name, (_, low, high, unit) in COMMANDS.items()
                },
                "program_name": self.program_name,
                "program": self.program_lines,
                "rate_hz": self.rate_hz,
            },
            "series": series,
            "timeline": list(self._timeline),
            "snapshot": self.snapshot(),
            "stock": self._stock,
        }

    def snapshot(self) -> dict[str, Any]:
        """The latest cycle's values, the connection and the cycle timing."""
        state = self.feed.latest
        twin = self.twin
        out: dict[str, Any] = {
            "time_s": time.monotonic() - self.t0_s,
            "feed_dropped": self.feed.dropped,
            "pages": len(self.hub.subscribers),
            "pages_dropped": self.hub.dropped,
            "ended": None if self.summary is None else self.summary.ended,
        }
        if twin is not None:
            runtime = twin.runtime
            times = runtime.cycle_times
            out.update(
                connected=runtime.connected,
                cycles=runtime.cycles,
                overruns=runtime.overruns,
                cycle_p50_ms=times.recent_percentile_ms(50),
                cycle_p99_ms=times.recent_percentile_ms(99),
                cycle_s=runtime.cycle_s,
                stop_outcome=twin.actions.stop_outcome,
            )
        if state is None:
            return out
        measured = state.measured
        line = state.line
        out.update(
            cycle=state.index,
            reading=state.connected,
            stale=state.stale,
            sample_age_s=state.sample_age_s,
            rejected=dict(state.rejected),
            run_state=run_state_name(measured.get("run_state")),
            line=line,
            block=self.program_lines[line - 1] if 0 < line <= len(self.program_lines) else "",
            tool=state.tool,
            position_mm=None
            if state.position_mm is None
            else [float(v) for v in state.position_mm],
            measured=dict(measured),
            predicted=dict(state.predicted),
        )
        return out

    def stock(self) -> dict[str, Any] | None:
        """The 3D view's data (:func:`cnctwin.web.stock.stock_view`): the twin's stock as a
        height map and the tool at its latest position, or ``None`` before the twin is built.

        The stock is read while the twin may be cutting it (no lock, so the twin never waits):
        a view can show a cut half applied, corrected by the next one.
        """
        twin = self.twin
        if twin is None:
            return None
        from cnctwin.web.stock import stock_view

        state = self.feed.latest
        physics = twin.physics
        position = None if state is None else state.position_mm
        cutter = None if state is None else physics.cutters.get(state.tool)
        self._stock = stock_view(physics.stock, position, cutter, max_cells=STOCK_CELLS)
        return self._stock

    def _item(self, item: Any) -> dict[str, Any]:
        from cnctwin.twin import TwinEvent

        if isinstance(item, TwinEvent):
            return event_item(item, self.t0_s)
        return decision_item(item, self.t0_s)

    # ------------------------------------------------------------------ control
    def command(self, name: str, value: float | None, client: str) -> dict[str, Any]:
        """Queue an operator's command for the twin's next cycle (token already checked).

        Returns
        -------
        dict
            The decision as queued.

        Raises
        ------
        PermissionError
            Control is off.
        ValueError
            An unknown command, or a value out of range.
        RuntimeError
            No twin yet, or the machine is not connected.
        """
        from cnctwin.control import Decision

        if not self.control_enabled:
            raise PermissionError("control is off: the twin's [control] enabled = false")
        if name not in COMMANDS:
            raise ValueError(f"command {name!r}; valid: {', '.join(COMMANDS)}")
        action, low, high, unit = COMMANDS[name]
        if name == "stop":
            value = 1.0
        if value is None or not math.isfinite(value) or not low <= value <= high:
            raise ValueError(f"{name} value {value!r}; valid: {low:g} to {high:g} {unit}".strip())
        twin = self.twin
        if twin is None or not twin.runtime.connected:
            raise RuntimeError("the twin is not connected to the machine; nothing was sent")
        what = "stop" if name == "stop" else f"feed override {value:g} %"
        decision = Decision(
            time.monotonic(),
            DASHBOARD_RULE,
            action,
            value,
            f"operator on the dashboard ({client}): {what}",
        )
        twin.actions.submit(decision)
        return {"who": DASHBOARD_RULE, "what": action, "value": value, "reason": decision.reason}

    # ------------------------------------------------------------------ the app
    def app(self) -> FastAPI:
        """The FastAPI application: the page, its files, the stream, the control."""

        @contextlib.asynccontextmanager
        async def lifespan(_app: FastAPI) -> AsyncIterator[None]:
            self._loop = asyncio.get_running_loop()
            pump = asyncio.create_task(self._pump())
            try:
                yield
            finally:
                pump.cancel()
                for sub in list(self.hub.subscribers):
                    self.hub.unsubscribe(sub)

        app = FastAPI(
            title="cnctwin live", lifespan=lifespan, docs_url=None, redoc_url=None, openapi_url=None
        )

        def viewer(request: Request) -> None:
            if self.token_for_view and not self._authorized(request, cookie=True):
                raise HTTPException(
                    401,
                    "this dashboard needs its access token: open the address printed at "
                    "start (…/?token=TOKEN)",
                )

        view = [Depends(viewer)]

        @app.get("/", dependencies=view)
        def page(request: Request) -> Response:
            response = HTMLResponse(static_file("live.html"), headers={"Cache-Control": "no-store"})
            given = request.query_params.get("token")
            if self.token_for_view and given and secrets.compare_digest(given, self.token):
                response.set_cookie(TOKEN_COOKIE, given, httponly=True, samesite="strict")
            return response

        @app.get("/favicon.ico")
        def favicon() -> Response:
            return Response(status_code=204)

        @app.get("/static/plotly.min.js", dependencies=view)
        def plotly() -> Response:
            return FileResponse(plotly_js(), media_type="text/javascript")

        @app.get("/static/{name}", dependencies=view)
        def static(name: str) -> Response:
            types = {".js": "text/javascript", ".css": "text/css", ".html": "text/html"}
            kind = types.get(Path(name).suffix)
            if kind is None or "/" in name or name.startswith("."):
                raise HTTPException(404, f"no file {name!r}")
            try:
                return Response(static_file(name), media_type=kind)
            except FileNotFoundError:
                raise HTTPException(404, f"no file {name!r}") from None

        @app.get("/api/snapshot", dependencies=view)
        def snapshot() -> Response:
            return Response(finite_json.dumps(self.hello()), media_type="application/json")

        @app.get("/api/stream", dependencies=view)
        async def stream(request: Request) -> StreamingResponse:
            sub = self.hub.subscribe()
            hello = finite_json.dumps(self.hello())

            async def events() -> AsyncIterator[str]:
                try:
                    yield f"retry: 1000\ndata: {hello}\n\n"
                    while True:
                        message = await self.hub.next_message(sub, 5.0)
                        if message is None:
                            if sub.closed:
                                return
                            yield ": keep-alive\n\n"
                            continue
                        yield f"data: {message}\n\n"
                finally:
                    self.hub.unsubscribe(sub)

            return StreamingResponse(
                events(),
                media_type="text/event-stream",
                headers={"Cache-Control": "no-store", "X-Accel-Buffering": "no"},
            )

        @app.post("/api/control")
        async def control(request: Request) -> JSONResponse:
            if not self.control_enabled:
                return JSONResponse(
                    {"error": "control is off: the twin's [control] enabled = false"}, 403
                )
            if not self._authorized(request, cookie=False):
                return JSONResponse(
                    {
                        "error": "a command needs the access token printed at start "
                        "(Authorization: Bearer TOKEN)"
                    },
                    401,
                )
            try:
                body = await request.json()
                name = str(body["command"])
                raw = body.get("value")
                value = None if raw is None else float(raw)
            except (ValueError, KeyError, TypeError, AttributeError):
                return JSONResponse(
                    {
                        "error": 'body: give JSON {"command": "stop"} or '
                        '{"command": "feed_override", "value": PERCENT}'
                    },
                    422,
                )
            client = request.client.host if request.client is not None else "unknown"
            try:
                queued = self.command(name, value, client)
            except ValueError as err:
                return JSONResponse({"error": str(err)}, 422)
            except RuntimeError as err:
                return JSONResponse({"error": str(err)}, 409)
            return JSONResponse({"queued": queued}, 202)

        return app

    def _authorized(self, request: Request, *, cookie: bool) -> bool:
        given = ""
        header = request.headers.get("authorization", "")
        if header.lower().startswith("bearer "):
            given = header[7:].strip()
        elif cookie:
            given = request.cookies.get(TOKEN_COOKIE) or request.query_params.get("token") or ""
        return bool(given) and secrets.compare_digest(given, self.token)

    async def _pump(self) -> None:
        """Every 1/rate_hz s: one message to every page (the server's loop)."""
        period = 1.0 / self.rate_hz
        deadline = time.monotonic()
        while True:
            deadline += period
            await asyncio.sleep(max(deadline - time.monotonic(), 0.0))
            # nobody watching: the history and the timeline still follow the twin
            watched = bool(self.hub.subscribers)
            message = self.tick(stock=watched)
            if watched:
                self.hub.publish(finite_json.dumps(message))
            deadline = max(deadline, time.monotonic() - period)


def _program_lines(program: Path | None) -> list[str]:
    if program is None:
        return []
    try:
        with open(program, encoding="utf-8", errors="replace") as text:
            return [line.rstrip("\r\n") for line in itertools.islice(text, MAX_PROGRAM_LINES)]
    except OSError:
        return []


def listen_socket(host: str, port: int) -> socket.socket:
    """A listening TCP socket on ``host:port`` (port 0: a free one), inheritable by a server.

    Raises
    ------
    ConfigError
        One line naming the port and the reason when the address cannot be bound.
    """
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
    except OSError as err:
        sock.close()
        raise ConfigError(
            f"--port {port}: cannot listen on {host}:{port}: {err.strerror}"
        ) from None
    sock.listen(64)
    sock.set_inheritable(True)
    return sock
