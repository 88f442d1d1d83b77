"""OPC UA write-to-read-back latency: node-opcua and cnctwin's own server, in one run.

Issue 17, item 6: the OPC UA figure beside an OPC UA server the project did not write. Heide
2025 section 2.5's test (:func:`cnctwin.thread.measure_latency`: write the feed override, poll
it until the new value reads back) runs over cnctwin's OPC UA client against

- ``cnctwin``: the virtual machine's server (asyncua) in a child process, as
  ``cnctwin bench latency --transport opcua`` starts it (anonymous session, default node map);
- ``node-opcua``: tests/interop/sinumerik_like_server.js (node-opcua, an independent stack) with
  the node ids of examples/opcua/sinumerik_840d_sl.toml, written by its operator user.

Both sessions use message security None and read by request (no subscription). The two
servers are measured in alternating rounds, so the machine's load falls on both alike.

Usage::

    python benchmarks/bench_opcua_interop_latency.py [--n 200] [--interval-ms 20] [--rounds 3]
                                                     [--quick] [--json]

``--quick`` (CI): 20 round trips, one round. Needs node and ``npm ci`` in tests/interop
(``.ci/run`` installs both); without them it says so and measures cnctwin's server alone.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import platform
import shutil
import socket
import subprocess
import tempfile
import time
import tomllib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from cnctwin.thread import (
    ConnectionConfig,
    OpcUaConnection,
    OpcUaSecurityConfig,
    measure_endpoint_latency,
    measure_latency,
)
from cnctwin.virtual import virtual_machine_server

REPO = Path(__file__).resolve().parents[1]
INTEROP = REPO / "tests" / "interop"
PRESET = REPO / "examples" / "opcua" / "sinumerik_840d_sl.toml"
#: The node-opcua server's user that may write the overrides (role Operator).
USER, PASSWORD = "bench", "bench-s3cret"


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _node_ready() -> bool:
    return (
        shutil.which("node") is not None
        and (INTEROP / "node_modules" / "node-opcua-server").is_dir()
    )


@contextlib.contextmanager
def _sinumerik_like(port: int, folder: Path) -> Iterator[None]:
    """tests/interop/sinumerik_like_server.js (node-opcua) on 127.0.0.1:``port``, its user
    ``USER`` an operator, from its ``{"ready": PORT}`` line until SIGTERM. Its certificate and
    its output (one line per write, not read) go to ``folder``."""
    args = ["--port", str(port), "--pki", str(folder), "--user", USER, "--password", PASSWORD]
    log = folder / "server.log"
    with log.open("ab") as out:  # appended to: the child's writes never overwrite
        server = subprocess.Popen(
            ["node", "sinumerik_like_server.js", *args],
            cwd=INTEROP,
            stdin=subprocess.DEVNULL,
            stdout=out,
            stderr=subprocess.STDOUT,
            env={**os.environ, "NODE_NO_WARNINGS": "1"},
        )
    try:
        deadline = time.monotonic() + 60.0
        while '"ready"' not in (said := log.read_text(errors="replace")):
            if server.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"node-opcua server not ready: {said[-2000:]}")
            time.sleep(0.05)
        yield
    finally:
        server.terminate()
        try:
            server.wait(10)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait()


async def _cnctwin_rounds(
    n: int, interval_s: float, rounds: int, out: list[dict[str, Any]]
) -> None:
    async with virtual_machine_server("opcua") as url:
        for _ in range(rounds):
            result = await measure_endpoint_latency("opcua", url, n=n, interval_s=interval_s)
            out.append(result.to_dict())


def _node_config(port: int, user: str, password: str) -> ConnectionConfig:
    table = tomllib.loads(PRESET.read_text())["connection"]
    return ConnectionConfig(
        transport="opcua",
        endpoint=f"opc.tcp://127.0.0.1:{port}",
        timeout_s=10.0,
        mapping=table["mapping"],
        security=OpcUaSecurityConfig(username=user, password=password),
    )


async def _node_round(port: int, n: int, interval_s: float) -> dict[str, Any]:
    connection = OpcUaConnection(_node_config(port, USER, PASSWORD), subscription_ms=None)
    async with connection:
        result = await measure_latency(connection, n=n, interval_s=interval_s, timeout_s=5.0)
    return result.to_dict()


def _summary(runs: list[dict[str, Any]]) -> dict[str, float]:
    def trip(key: str) -> list[float]:
        return [r["round_trip_ms"][key] for r in runs]

    return {
        "median_ms": float(np.median(trip("median"))),
        "p99_ms": float(np.median(trip("p99"))),
        "min_ms": float(min(trip("min"))),
        "write_median_ms": float(np.median([r["write_ms"]["median"] for r in runs])),
        "read_median_ms": float(np.median([r["read_ms"]["median"] for r in runs])),
        "rounds": len(runs),
    }


def run(n: int, interval_ms: float, rounds: int) -> dict[str, Any]:
    """Alternate rounds of ``n`` round trips on node-opcua and cnctwin's server."""
    interval_s = interval_ms / 1e3
    report: dict[str, Any] = {
        "machine": f"{platform.machine()}, {os.cpu_count()} CPUs, "
        f"Python {platform.python_version()}",
        "load_before": os.getloadavg()[0],
        "n": n,
        "interval_ms": interval_ms,
        "security": "None",
    }
    ours: list[dict[str, Any]] = []
    theirs: list[dict[str, Any]] = []
    if _node_ready():
        port = _free_port()
        with tempfile.TemporaryDirectory() as pki, _sinumerik_like(port, Path(pki)):
            for _ in range(rounds):
                theirs.append(asyncio.run(_node_round(port, n, interval_s)))
                asyncio.run(_cnctwin_rounds(n, interval_s, 1, ours))
    else:
        report["node_opcua"] = "not installed: node and `npm ci` in tests/interop"
        asyncio.run(_cnctwin_rounds(n, interval_s, rounds, ours))
    report["load_after"] = os.getloadavg()[0]
    report["cnctwin"] = _summary(ours)
    if theirs:
        report["node-opcua"] = _summary(theirs)
    return report


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=200, help="round trips per round")
    parser.add_argument("--interval-ms", type=float, default=20.0, help="pause between them, ms")
    parser.add_argument("--rounds", type=int, default=3, help="alternating rounds per server")
    parser.add_argument("--quick", action="store_true", help="20 round trips, one round (CI)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args()
    n, rounds = (20, 1) if args.quick else (args.n, args.rounds)
    report = run(n, args.interval_ms, rounds)
    if args.json:
        print(json.dumps(report))
        return
    print(
        f"OPC UA write-to-read-back, {n} round trips x {report['cnctwin']['rounds']} rounds, "
        f"{args.interval_ms:g} ms apart, security None; {report['machine']}; "
        f"load {report['load_before']:.1f} -> {report['load_after']:.1f}"
    )
    if "node_opcua" in report:
        print(f"node-opcua: {report['node_opcua']}")
    print(
        "| server | round trip median ms | p99 ms (median of rounds) | min ms "
        "| write median ms | read median ms |"
    )
    print("|---|---|---|---|---|---|")
    for name in ("cnctwin", "node-opcua"):
        if name in report:
            s = report[name]
            print(
                f"| {name} | {s['median_ms']:.2f} | {s['p99_ms']:.2f} | {s['min_ms']:.2f} | "
                f"{s['write_median_ms']:.2f} | {s['read_median_ms']:.2f} |"
            )


if __name__ == "__main__":
    main()
