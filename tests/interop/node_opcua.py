"""node-opcua, the independent OPC UA implementation: its server and client scripts as child
processes.

node-opcua is installed by ``npm ci`` in tests/interop (``.ci/run``'s ``ensure_node_opcua``;
node_modules is not committed). Without node or the modules the tests skip (fail in CI,
``CNCTWIN_REQUIRE_SERVICES=1``; tests/skips.py).
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import threading
import time
from pathlib import Path
from typing import Any

from skips import missing
from timeouts import SERVER_START_S

HERE = Path(__file__).resolve().parent

#: How long :meth:`NodeProcess.writes_since` waits after the expected writes for one more, s:
#: the server prints a write before it answers it, so its line is at most the reader thread's
#: turn behind.
SETTLE_S = 0.3

#: The user of the node-opcua server who may write the overrides (role Operator).
USER, PASSWORD = "twin", "op-s3cret"


def require_node_opcua() -> str:
    """Path of ``node``; skip (fail in CI) when node or the node-opcua modules are absent."""
    node = shutil.which("node")
    if node is None:
        missing("node is not installed (node-opcua interop tests)", "CNCTWIN_REQUIRE_SERVICES")
    if not (HERE / "node_modules" / "node-opcua-server").is_dir():
        missing(
            "node-opcua is not installed: run `npm ci` in tests/interop",
            "CNCTWIN_REQUIRE_SERVICES",
        )
    assert node is not None
    return node


class NodeProcess:
    """A node script as a child, its stdout JSON lines collected in :attr:`lines`."""

    def __init__(self, args: list[str]) -> None:
        node = require_node_opcua()
        self.proc = subprocess.Popen(
            [node, *args],
            cwd=HERE,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env={**os.environ, "NODE_NO_WARNINGS": "1"},
        )
        self.lines: list[dict[str, Any]] = []
        self.stderr: list[str] = []
        self._new = threading.Condition()
        threading.Thread(target=self._collect, daemon=True).start()
        threading.Thread(target=self._collect_stderr, daemon=True).start()

    def _collect(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            try:
                item = json.loads(line)
            except json.JSONDecodeError:
                continue  # node-opcua's own log lines
            with self._new:
                self.lines.append(item)
                self._new.notify_all()

    def _collect_stderr(self) -> None:
        assert self.proc.stderr is not None
        for line in self.proc.stderr:
            self.stderr.append(line)

    def wait_for(self, key: str, timeout_s: float = SERVER_START_S) -> dict[str, Any]:
        """The first line with ``key``; AssertionError after ``timeout_s`` or an exit."""
        deadline = time.monotonic() + timeout_s
        with self._new:
            while True:
                for item in self.lines:
                    if key in item:
                        return item
                left = deadline - time.monotonic()
                if left <= 0 or self.proc.poll() is not None:
                    raise AssertionError(
                        f"node script gave no {key!r} (exit {self.proc.poll()}): "
                        + "".join(self.stderr[-20:])
                    )
                self._new.wait(min(left, 0.2))

    def send(self, line: str) -> None:
        """Write one command line to the script's stdin and wait for its ack."""
        assert self.proc.stdin is not None
        before = sum(1 for item in self.lines if item.get("ack") == line)
        self.proc.stdin.write(line + "\n")
        self.proc.stdin.flush()
        deadline = time.monotonic() + 30.0
        while sum(1 for item in self.lines if item.get("ack") == line) <= before:
            assert time.monotonic() < deadline, f"no ack of {line!r}"
            time.sleep(0.01)

    def writes(self) -> list[dict[str, Any]]:
        """The writes the server applied, in order, as far as their lines have come in."""
        return [item for item in self.lines if "write" in item]

    def writes_since(self, before: int, expected: int) -> list[dict[str, Any]]:
        """The writes after the first ``before``, once ``expected`` of them have come in (a
        write the server has answered may not have been read from its stdout yet), and
        :data:`SETTLE_S` later, so that one more than expected would show too; an
        AssertionError when they have not come within 30 s."""
        deadline = time.monotonic() + 30.0
        with self._new:
            while len(self.writes()) < before + expected:
                left = deadline - time.monotonic()
                assert left > 0, f"{len(self.writes()) - before} of {expected} writes came"
                self._new.wait(min(left, 0.2))
        time.sleep(SETTLE_S)
        return self.writes()[before:]

    def kill(self) -> None:
        """SIGKILL: the server vanishes without closing its sessions."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGKILL)
        self.proc.wait(30)

    def close(self) -> None:
        """Stop the child (SIGTERM, then SIGKILL) and close its pipes."""
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.kill()
        for pipe in (self.proc.stdin, self.proc.stdout, self.proc.stderr):
            if pipe is not None:
                pipe.close()


def start_sinumerik_like(port: int, pki: Path) -> NodeProcess:
    """tests/interop/sinumerik_like_server.js on 127.0.0.1:``port``, ready to serve."""
    server = NodeProcess(
        [
            "sinumerik_like_server.js",
            "--port",
            str(port),
            "--pki",
            str(pki),
            "--user",
            USER,
            "--password",
            PASSWORD,
        ]
    )
    try:
        server.wait_for("ready")
    except BaseException:
        server.close()
        raise
    return server
