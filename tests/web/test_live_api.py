"""The live dashboard's server without a browser: the token, the bounded hand-over, control.

Control is checked against the machine itself: a twin cycles in lockstep against an
in-process virtual machine (the packaged demo without its rules and its hole), the page's
requests go through the FastAPI app (Starlette's TestClient), and the machine's own feed
override, the safety filter's verdict and the historian's decision record say what happened.
"""

from __future__ import annotations

import asyncio
import socket
import sqlite3
import time
from pathlib import Path
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient
from timeouts import CHILD_START_S

from cnctwin.errors import ConfigError
from cnctwin.store.historian import Historian
from cnctwin.twin.local import LocalConnection
from cnctwin.twin.pipeline import build_twin
from cnctwin.twin.recorder import Recorder
from cnctwin.twin.state import CycleState
from cnctwin.virtual import VirtualMachine
from cnctwin.web.feed import Hub, LiveFeed
from cnctwin.web.server import DASHBOARD_RULE, LiveDashboard

REPO = Path(__file__).resolve().parents[2]
DEMO_CONFIG = REPO / "src" / "cnctwin" / "examples" / "demo_twin.toml"


#: Machine time per lockstep cycle, s (the demo's 2x real time at its 12.5 ms cycle).
STEP_S = 0.025


# ---------------------------------------------------------------------- the token
def test_non_loopback_host_needs_insecure() -> None:
    with pytest.raises(ConfigError, match=r"--host '0\.0\.0\.0'.*--insecure"):
        LiveDashboard(host="0.0.0.0")


def test_a_port_in_use_is_refused_naming_it() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        with pytest.raises(ConfigError, match=f"--port {port}: cannot listen on 127.0.0.1:{port}"):
            LiveDashboard(port=port)


def test_insecure_dashboard_needs_the_token_for_every_page() -> None:
    board = LiveDashboard(host="0.0.0.0", insecure=True, token="right-token")
    try:
        client = TestClient(board.app())
        for path in ("/", "/static/live.js", "/static/plotly.min.js", "/api/snapshot"):
            assert client.get(path).status_code == 401, path
            assert client.get(path, params={"token": "wrong"}).status_code == 401, path
            bearer = {"Authorization": "Bearer right-token"}
            assert client.get(path, headers=bearer).status_code == 200, path
        # the printed address (…/?token=) sets a cookie: the page's own requests need no token
        fresh = TestClient(board.app())
        assert fresh.get("/", params={"token": "right-token"}).status_code == 200
        assert fresh.get("/api/snapshot").status_code == 200
        assert fresh.get("/static/live.js").status_code == 200
    finally:
        board.close()


def test_loopback_dashboard_serves_pages_but_commands_need_the_token() -> None:
    board = LiveDashboard(control_enabled=True, token="right-token")
    try:
        client = TestClient(board.app())
        page = client.get("/")
        assert page.status_code == 200 and "plotly.min.js" in page.text
        # plotly.js comes from the installed plotly package, nothing from the internet
        assert "plotly" in client.get("/static/plotly.min.js").text[:2000].lower()
        assert "http://" not in page.text and "https://" not in page.text
        body = {"command": "stop"}
        assert client.post("/api/control", json=body).status_code == 401
        wrong = {"Authorization": "Bearer wrong-token"}
        assert client.post("/api/control", json=body, headers=wrong).status_code == 401
        # with the token but no twin: nothing can be sent, and the page is told why
        right = {"Authorization": "Bearer right-token"}
        answer = client.post("/api/control", json=body, headers=right)
        assert answer.status_code == 409 and "not connected" in answer.json()["error"]
        bad = client.post("/api/control", json={"command": "spin"}, headers=right)
        assert bad.status_code == 422 and "'spin'" in bad.json()["error"]
        high = client.post(
            "/api/control", json={"command": "feed_override", "value": 400}, headers=right
        )
        assert high.status_code == 422 and "0 to 150 %" in high.json()["error"]
    finally:
        board.close()


def test_control_off_refuses_every_command_even_with_the_token() -> None:
    board = LiveDashboard(control_enabled=False, token="right-token")
    try:
        client = TestClient(board.app())
        answer = client.post(
            "/api/control",
            json={"command": "stop"},
            headers={"Authorization": "Bearer right-token"},
        )
        assert answer.status_code == 403 and "enabled = false" in answer.json()["error"]
        assert client.get("/api/snapshot").json()["info"]["control_enabled"] is False
    finally:
        board.close()


# ---------------------------------------------------------------------- control, end to end
def _lockstep(
    tmp_path: Path, requests: dict[int, list[tuple[dict[str, Any], str | None]]], cycles: int
) -> tuple[LiveDashboard, list[float], dict[int, list[int]], list[Any], Path]:
    """Run the demo twin without rules or hole for ``cycles`` lockstep cycles; at cycle k
    post each (body, token) of ``requests[k]`` to the dashboard's control endpoint.

    Returns the dashboard, the machine's feed override per cycle (%), the status codes per
    cycle, the action stage's results and the historian's file.
    """
    from cnctwin.twin.config import load_run_config

    config = load_run_config(DEMO_CONFIG)
    config = config.model_copy(update={"rules": []})
    assert config.virtual is not None
    virtual = config.virtual.model_copy(update={"faults": []})
    vm = VirtualMachine(virtual, config)
    board = LiveDashboard(control_enabled=True, token="right-token")
    client = TestClient(board.app())
    overrides: list[float] = []
    codes: dict[int, list[int]] = {}
    db = tmp_path / "live.sqlite"

    async def main() -> list[Any]:
        conn = LocalConnection(vm, step_s=STEP_S, tick_s=vm.tick_s)
        await conn.connect()
        stop = asyncio.Event()
        with Historian.open(str(db)) as historian:
            recorder = Recorder(historian, {"test": "live"}, 0.0)
            twin = build_twin(
                config, conn, recorder=recorder, program=virtual.program, realtime=False
            )
            board.attach(twin)

            def on_cycle(state: CycleState) -> None:
                board.observe(state)
                overrides.append(state.measured.get("feed_override_pct", float("nan")))
                for body, token in requests.get(state.index, []):
                    headers = {} if token is None else {"Authorization": f"Bearer {token}"}
                    answer = client.post("/api/control", json=body, headers=headers)
                    codes.setdefault(state.index, []).append(answer.status_code)
                if state.index >= cycles:
                    stop.set()

            twin.runtime.on_cycle = on_cycle
            await twin.runtime.run(stop_event=stop)
            await conn.close()
            return twin.actions.results

    results = asyncio.run(main())
    board.close()
    return board, overrides, codes, results, db


def _dashboard_decisions(db: Path) -> list[tuple[str, float, str, int]]:
    with sqlite3.connect(db) as conn:
        return conn.execute(
            "SELECT action, value, reason, accepted FROM hist_decisions WHERE rule = ? "
            "ORDER BY seq",
            (DASHBOARD_RULE,),
        ).fetchall()


def test_command_without_or_with_a_wrong_token_leaves_the_machine_unchanged(
    tmp_path: Path,
) -> None:
    stop = {"command": "stop"}
    low = {"command": "feed_override", "value": 50}
    requests = {40: [(stop, None), (low, None), (stop, "wrong-token"), (low, "")]}
    board, overrides, codes, results, db = _lockstep(tmp_path, requests, cycles=120)
    assert codes == {40: [401, 401, 401, 401]}
    assert [r for r in results if r.verdict.decision.rule == DASHBOARD_RULE] == []
    assert _dashboard_decisions(db) == []
    # the machine kept its override and kept cutting (no stop)
    assert min(overrides[40:]) == pytest.approx(100.0)
    assert board.feed.latest is not None
    assert board.feed.latest.measured["run_state"] == 1.0


def test_command_with_the_token_passes_the_safety_filter_and_is_recorded(
    tmp_path: Path,
) -> None:
    # [control.feed_override] of the demo: 30 % to 100 %
    requests = {
        30: [({"command": "feed_override", "value": 140}, "right-token")],
        60: [({"command": "feed_override", "value": 10}, "right-token")],
    }
    board, overrides, codes, results, db = _lockstep(tmp_path, requests, cycles=140)
    assert codes == {30: [202], 60: [202]}
    mine = [r for r in results if r.verdict.decision.rule == DASHBOARD_RULE]
    assert [(r.verdict.decision.value, r.verdict.outcome, r.verdict.value) for r in mine] == [
        (140.0, "clamped", 100.0),
        (10.0, "clamped", 30.0),
    ]
    assert mine[1].confirmed
    # the machine itself: never above 100 %, and down to the filter's 30 %, not the asked 10 %
    assert max(overrides) == pytest.approx(100.0)
    assert overrides[-1] == pytest.approx(30.0, abs=0.5)
    assert min(overrides) > 29.5
    # the audit trail: the historian's decision record names the dashboard and the client
    recorded = _dashboard_decisions(db)
    assert [(a, v, ok) for a, v, _, ok in recorded] == [
        ("feed_override_pct", 100.0, 1),
        ("feed_override_pct", 30.0, 1),
    ]
    assert all("operator on the dashboard (testclient)" in reason for _, _, reason, _ in recorded)
    # and the timeline of the page shows who issued them
    timeline = board.tick(stock=False)["timeline"]
    who = [(item["who"], item["outcome"], item.get("value")) for item in timeline]
    assert ("dashboard", "clamped", 100.0) in who and ("dashboard", "clamped", 30.0) in who


# ---------------------------------------------------------------------- the bounded hand-over
def test_feed_keeps_the_newest_cycles_and_counts_the_dropped() -> None:
    feed = LiveFeed(capacity=4)
    for index in range(10):
        feed.put(CycleState(index, 0.0, 0.0))
    cycles, _ = feed.take()
    assert [c.index for c in cycles] == [6, 7, 8, 9]
    assert feed.dropped == 6
    feed.put(CycleState(10, 0.0, 0.0))
    assert [c.index for c in feed.take()[0]] == [10] and feed.dropped == 6


def test_hub_drops_a_browser_whose_queue_is_full_without_waiting() -> None:
    async def main() -> None:
        hub = Hub(queue_size=3)
        fast, slow = hub.subscribe(), hub.subscribe()
        for n in range(5):
            started = time.perf_counter()
            hub.publish(f"m{n}")
            assert time.perf_counter() - started < 0.5  # never waits for a page
            assert await hub.next_message(fast, 1.0) == f"m{n}"
        assert slow.closed and hub.subscribers == {fast} and hub.dropped == 1
        assert await hub.next_message(slow, 0.01) is None

    asyncio.run(main())


def test_a_page_that_stops_reading_is_dropped_while_another_keeps_its_stream() -> None:
    board = LiveDashboard(rate_hz=10.0)
    with board:
        host, port = "127.0.0.1", board.port
        # the dead page: asks for the stream with a tiny receive buffer and never reads
        dead = socket.socket()
        dead.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        dead.connect((host, port))
        dead.sendall(b"GET /api/stream HTTP/1.1\r\nHost: x\r\n\r\n")
        got = 0
        with (
            httpx.Client(timeout=CHILD_START_S) as client,
            client.stream("GET", f"http://{host}:{port}/api/stream") as live,
        ):
            deadline = time.monotonic() + CHILD_START_S
            big = "x" * 200_000  # fills the dead page's socket buffers within a few messages
            for line in live.iter_lines():
                if line.startswith("data:"):
                    got += 1
                    assert board._loop is not None
                    board._loop.call_soon_threadsafe(board.hub.publish, big)
                if board.hub.dropped >= 1 and got >= 40:
                    break
                assert time.monotonic() < deadline, "the dead page was never dropped"
        dead.close()
    assert board.hub.dropped == 1  # the dead page, and only it
    assert got >= 40
