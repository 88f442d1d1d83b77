"""The run browser: the historian's recorded runs in the browser (``cnctwin web --db``).

The page (``static/runs.html``) lists the runs, opens one, plots any signal over the whole
run and zooms into it, overlays the same signal of a second run (time since each run's
start) and exports a run as CSV or Parquet. The browser never receives a whole record: each
plot request names a time window and a width in pixels, and gets the min and max of each
pixel's bucket (:func:`cnctwin.report.downsample.minmax_buckets`, at most two points per
pixel); zooming asks again for the narrower window, down to the single samples.

A plot of a whole closed run comes from the run's overview (:meth:`Historian.overview`: per
signal the min and max of 4096 time buckets, stored when the run was closed), so opening even
a 1-hour run reads a few hundred kB and decodes no frame; its plot buckets fall on the
overview's bucket edges (``edges`` in the answer). A zoom into a closed run reads only the
frames of its window (:meth:`Historian.samples` with ``t0``/``t1``, which the overview points
to). A run still being recorded has no overview: its columns are read whole and kept in
memory (the last few opened) for :data:`LIVE_CACHE_S`; a 1-hour run at the twin's default
12.5 ms cycle is 288,000 instants, ~65 MB of float64 for its 28 measured signals.

HTTP API (JSON; errors are ``{"error": one line}`` with status 404 or 422):

``GET /api/runs``
    ``{"database", "runs": [{run_id, machine, program, status, started_at, duration_s,
    frames, events, decisions}]}``, oldest first.
``GET /api/runs/{id}``
    The run (``cnctwin runs show --json``) with ``duration_s`` and ``machine``.
``GET /api/runs/{id}/signal?name=N&kind=measured|predicted&t0=S&t1=S&buckets=PX``
    ``{"name", "kind", "t", "y", "samples", "raw", "t0", "t1", "t_first", "t_last",
    "edges"}``: times in s since the run's start, ``null`` in ``y`` for a gap; ``t0``/``t1``
    default to the whole run; ``edges`` the plot buckets' edges, s (``null`` when ``raw``).
``GET /api/runs/{id}/export?format=csv|parquet``
    A zip of the four files of ``cnctwin runs export``.
"""

from __future__ import annotations

import io
import tempfile
import threading
import time
import zipfile
from collections import OrderedDict
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from fastapi import APIRouter, Depends, FastAPI, HTTPException, Query, Request
from fastapi.responses import FileResponse, JSONResponse, RedirectResponse, Response

from cnctwin import finite_json
from cnctwin.errors import CnctwinError, DataError, InputError
from cnctwin.report import MAX_BUCKETS, minmax_buckets
from cnctwin.store import TIME_COLUMN, Historian, RunOverview, RunSummary

__all__ = ["LIVE_CACHE_S", "RunBrowser", "runs_app", "runs_router"]

#: Seconds the columns of a run that is still recording are served before being read again.
LIVE_CACHE_S = 2.0
#: Runs (measured or predicted columns each) kept in memory.
CACHED_COLUMNS = 4
_KINDS = ("measured", "predicted")


def _machine(summary: RunSummary) -> str:
    """What the run's meta says the machine was: ``machine``, else the endpoint."""
    meta = summary.meta
    for key in ("machine", "endpoint", "virtual_machine"):
        if meta.get(key):
            return str(meta[key])
    return ""


def _duration(summary: RunSummary) -> float | None:
    """Wall time of the run, s: to its end, or (still running) to its last instant."""
    if summary.ended_at is not None:
        return summary.ended_at - summary.started_at
    return summary.last_t_s


def _row(summary: RunSummary) -> dict[str, Any]:
    return {
        "run_id": summary.run_id,
        "machine": _machine(summary),
        "program": str(summary.meta.get("program") or ""),
        "status": summary.status,
        "started_at": summary.started_at,
        "duration_s": _duration(summary),
        "frames": summary.frames,
        "events": summary.events,
        "decisions": summary.decisions,
    }


def _answer(
    run_id: int,
    name: str,
    kind: str,
    t: np.ndarray,
    y: np.ndarray,
    samples: int,
    raw: bool,
    window: tuple[float, float],
    span: tuple[float, float],
    edges: np.ndarray | None,
) -> dict[str, Any]:
    """The JSON of ``GET .../signal`` (module notes)."""
    return {
        "run_id": run_id,
        "name": name,
        "kind": kind,
        "t": t.tolist(),
        "y": [None if v != v else v for v in y.tolist()],
        "samples": samples,
        "raw": raw,
        "t0": window[0],
        "t1": window[1],
        "t_first": span[0],
        "t_last": span[1],
        "edges": None if edges is None else edges.tolist(),
    }


def _known(run_id: int, kind: str, name: str, recorded: list[str]) -> None:
    """A DataError unless ``name`` is one of the ``recorded`` signals of the run."""
    if name not in recorded:
        raise DataError(
            f"run {run_id} has no {kind} signal {name!r} (recorded: "
            f"{', '.join(recorded) or 'none'})"
        )


class RunBrowser:
    """The run browser's access to one historian (thread-safe).

    Parameters
    ----------
    url_or_path
        An SQLite file or ``postgresql://`` URL (see :meth:`Historian.open`); never created.

    Raises
    ------
    DataError
        For a missing or unreadable database.
    """

    def __init__(self, url_or_path: str | Path | None) -> None:
        self._meta = Historian.open(url_or_path, create=False)
        # A second connection reads columns, so listing and plotting do not queue
        # behind a long read.
        self._loader = Historian.open(url_or_path, create=False)
        self._cache: OrderedDict[tuple[int, bool], tuple[float, dict[str, np.ndarray]]] = (
            OrderedDict()
        )
        self._overviews: OrderedDict[tuple[int, bool], RunOverview] = OrderedDict()
        self._cache_lock = threading.Lock()
        self._load_lock = threading.Lock()
        self._finished: set[int] = set()

    @property
    def location(self) -> str:
        """The database (path, or URL without password)."""
        return self._meta.location

    def close(self) -> None:
        """Close both connections."""
        self._meta.close()
        self._loader.close()

    def runs(self) -> dict[str, Any]:
        """Every run, oldest first (``GET /api/runs``)."""
        summaries = self._meta.runs()
        self._note(summaries)
        return {"database": self.location, "runs": [_row(s) for s in summaries]}

    def run(self, run_id: int) -> dict[str, Any]:
        """One run with its signals, events and decisions (``GET /api/runs/{id}``)."""
        detail = self._meta.run(run_id)
        self._note([detail.summary])
        out = detail.to_dict()
        out.update(machine=_machine(detail.summary), duration_s=_duration(detail.summary))
        return out

    def _note(self, summaries: list[RunSummary]) -> None:
        for s in summaries:
            if s.status != "running":
                self._finished.add(s.run_id)

    def columns(self, run_id: int, predicted: bool) -> dict[str, np.ndarray]:
        """A run's columns (``time_s`` first, s), from the cache or the database."""
        key = (run_id, predicted)
        with self._load_lock:
            with self._cache_lock:
                hit = self._cache.get(key)
                if hit is not None and (
                    run_id in self._finished or time.monotonic() - hit[0] < LIVE_CACHE_S
                ):
                    self._cache.move_to_end(key)
                    return hit[1]
            columns = self._loader.samples(run_id, predicted=predicted)
            with self._cache_lock:
                self._cache[key] = (time.monotonic(), columns)
                while len(self._cache) > CACHED_COLUMNS:
                    self._cache.popitem(last=False)
        return columns

    def overview(self, run_id: int, predicted: bool) -> RunOverview | None:
        """A closed run's overview (cached), None while it is being recorded."""
        key = (run_id, predicted)
        with self._cache_lock:
            hit = self._overviews.get(key)
            if hit is not None:
                self._overviews.move_to_end(key)
                return hit
        with self._load_lock:
            found = self._loader.overview(run_id, predicted=predicted)
        if found is not None:
            with self._cache_lock:
                self._overviews[key] = found
                while len(self._overviews) > CACHED_COLUMNS:
                    self._overviews.popitem(last=False)
        return found

    def signal(
        self,
        run_id: int,
        name: str,
        kind: str = "measured",
        t0: float | None = None,
        t1: float | None = None,
        buckets: int = 1000,
    ) -> dict[str, Any]:
        """A signal of a run in a time window, min/max per bucket (``GET .../signal``).

        Parameters
        ----------
        run_id
            The run.
        name
            A measured or predicted signal of it.
        kind
            ``"measured"`` or ``"predicted"``.
        t0, t1
            The window, s since the run's start; None: the run's first / last instant.
        buckets
            Width of the plot in pixels, 1..:data:`MAX_BUCKETS`.

        Raises
        ------
        DataError
            For an unknown run or signal.
        InputError
            For a kind, window or bucket count out of range.
        """
        if kind not in _KINDS:
            raise InputError(f"kind {kind!r}; give one of {', '.join(_KINDS)}")
        if not 1 <= buckets <= MAX_BUCKETS:
            raise InputError(f"buckets {buckets}; give 1 to {MAX_BUCKETS} (the plot's pixels)")
        predicted = kind == "predicted"
        found = self.overview(run_id, predicted)
        if found is None:  # still being recorded: its columns, read again now and then
            columns = self.columns(run_id, predicted)
            _known(run_id, kind, name, [n for n in columns if n != TIME_COLUMN])
            t = columns[TIME_COLUMN]
            first = float(t[0]) if t.size else 0.0
            last = float(t[-1]) if t.size else 0.0
        else:
            _known(run_id, kind, name, list(found.signals))
            first, last = found.t_first, found.t_last
        lo = first if t0 is None else t0
        hi = last if t1 is None else t1
        if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
            raise InputError(f"window t0={lo}, t1={hi} s; give finite t0 <= t1")
        whole = t0 is None and t1 is None
        if found is None:
            y = columns[name]
        elif whole and 2 * buckets < found.frames and buckets <= found.buckets:
            envelope = found.envelope(name, buckets)
            return _answer(
                run_id, name, kind, envelope.t, envelope.y, envelope.samples, False,
                (lo, hi), (first, last), envelope.edges,
            )  # fmt: skip
        else:  # a zoom: the frames of the window only
            window = self._loader.samples(run_id, [name], predicted=predicted, t0=lo, t1=hi)
            t, y = window[TIME_COLUMN], window[name]
        points = minmax_buckets(t, y, lo, hi, buckets)
        edges = None if points.raw else np.linspace(lo, hi, buckets + 1)
        return _answer(
            run_id, name, kind, points.t, points.y, points.samples, points.raw, (lo, hi),
            (first, last), edges,
        )  # fmt: skip

    def export(self, run_id: int, fmt: str) -> bytes:
        """The run's four export files (:meth:`Historian.export`) as a zip archive."""
        if fmt not in ("csv", "parquet"):
            raise InputError(f"format {fmt!r}; give csv or parquet")
        with tempfile.TemporaryDirectory(prefix="cnctwin-export-") as folder:
            files = self._meta.export(run_id, Path(folder) / f"run{run_id}.{fmt}")
            buffer = io.BytesIO()
            with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
                for path in files:
                    archive.write(path, path.name)
        return buffer.getvalue()


def _json(value: Any) -> Response:
    return Response(finite_json.dumps(value), media_type="application/json")


def _fail(err: CnctwinError) -> JSONResponse:
    """``{"error": one line}``: 422 for a bad request, 404 for an unknown run or signal."""
    status = 422 if isinstance(err, InputError) else 404
    return JSONResponse({"error": " ".join(str(err).split())}, status)


def runs_router(browser: RunBrowser, page: bytes) -> APIRouter:
    """The run browser's routes: ``GET /runs`` (the page) and the API of the module notes.

    Parameters
    ----------
    browser
        Where the runs come from.
    page
        The page's HTML (``static/runs.html``).

    The including app adds authentication (``dependencies=``) and serves ``/static/``.
    """
    router = APIRouter()

    @router.get("/runs")
    def runs_page() -> Response:
        return Response(page, media_type="text/html", headers={"Cache-Control": "no-store"})

    @router.get("/api/runs")
    def list_runs() -> Response:
        try:
            return _json(browser.runs())
        except CnctwinError as err:
            return _fail(err)

    @router.get("/api/runs/{run_id}")
    def show_run(run_id: int) -> Response:
        try:
            return _json(browser.run(run_id))
        except CnctwinError as err:
            return _fail(err)

    @router.get("/api/runs/{run_id}/signal")
    def signal(
        run_id: int,
        name: str,
        kind: str = "measured",
        t0: Annotated[float | None, Query()] = None,
        t1: Annotated[float | None, Query()] = None,
        buckets: int = 1000,
    ) -> Response:
        try:
            return _json(browser.signal(run_id, name, kind, t0, t1, buckets))
        except CnctwinError as err:
            return _fail(err)

    @router.get("/api/runs/{run_id}/export")
    def export(run_id: int, format: str = "csv") -> Response:
        try:
            data = browser.export(run_id, format)
        except CnctwinError as err:
            return _fail(err)
        return Response(
            data,
            media_type="application/zip",
            headers={"Content-Disposition": f'attachment; filename="run{run_id}-{format}.zip"'},
        )

    return router


def runs_app(browser: RunBrowser, token: str | None = None) -> FastAPI:
    """The app of ``cnctwin web --db``: the run browser with its files.

    Parameters
    ----------
    browser
        The historian to browse.
    token
        None: no token (a loopback address). Else every request needs it, as with the live
        dashboard (:mod:`cnctwin.web.server`): ``Authorization: Bearer TOKEN``, or
        ``?token=TOKEN`` once (the page then keeps it in a cookie).
    """
    import secrets

    from cnctwin.web.server import TOKEN_COOKIE, plotly_js, static_file

    def viewer(request: Request) -> None:
        if token is None:
            return
        header = request.headers.get("authorization", "")
        given = (
            header[7:].strip()
            if header.lower().startswith("bearer ")
            else (request.cookies.get(TOKEN_COOKIE) or request.query_params.get("token") or "")
        )
        if not (given and secrets.compare_digest(given, token)):
            raise HTTPException(
                401,
                "this run browser needs its access token: open the address printed at "
                "start (.../runs?token=TOKEN)",
            )

    view = [Depends(viewer)]
    app = FastAPI(title="cnctwin runs", docs_url=None, redoc_url=None, openapi_url=None)
    app.include_router(runs_router(browser, static_file("runs.html")), dependencies=view)

    @app.middleware("http")
    async def keep_token(request: Request, call_next: Any) -> Response:
        response: Response = await call_next(request)
        given = request.query_params.get("token")
        if token is not None and given and secrets.compare_digest(given, token):
            response.set_cookie(TOKEN_COOKIE, given, httponly=True, samesite="strict")
        return response

    @app.get("/", dependencies=view)
    def root() -> Response:
        return RedirectResponse("/runs")

    @app.get("/static/plotly.min.js", dependencies=view)
    def plotly() -> Response:
        return FileResponse(plotly_js(), media_type="text/javascript")

    @app.get("/static/{name}", dependencies=view)
    def static(name: str) -> Response:
        kind = {".js": "text/javascript", ".css": "text/css"}.get(Path(name).suffix)
        if kind is None or "/" in name or name.startswith("."):
            raise HTTPException(404, f"no file {name!r}")
        try:
            return Response(static_file(name), media_type=kind)
        except FileNotFoundError:
            raise HTTPException(404, f"no file {name!r}") from None

    return app
