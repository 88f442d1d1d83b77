"""A private Mosquitto broker on loopback, for ``cnctwin bench latency --transport mqtt`` and
for tests that stop and restart their broker.

It runs Eclipse Mosquitto (``/usr/sbin/mosquitto``, Debian package ``mosquitto``) with a
configuration of its own in a temporary folder: one listener on ``127.0.0.1`` at a free
port, anonymous clients allowed (loopback only), optionally persistence (sessions and
queued messages saved to disk every ``autosave_s`` and at a clean stop).
"""

from __future__ import annotations

import os
import pwd
import shutil
import signal
import socket
import subprocess
import tempfile
import time
from pathlib import Path
from types import TracebackType

from cnctwin.errors import CnctwinError

__all__ = ["Mosquitto"]

#: Where Debian installs the broker.
MOSQUITTO = "/usr/sbin/mosquitto"


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


class Mosquitto:
    """One Mosquitto process on 127.0.0.1 (a context manager: started, then always stopped).

    Parameters
    ----------
    port
        Port to listen on; 0 picks a free one (kept across :meth:`restart`).
    persistence
        Save sessions and queued QoS 1 messages to disk, reload them at a restart.
    autosave_s
        With persistence: seconds between saves (Mosquitto also saves at a clean stop).

    Attributes
    ----------
    url
        ``mqtt://127.0.0.1:PORT``.
    """

    def __init__(self, port: int = 0, *, persistence: bool = False, autosave_s: int = 1) -> None:
        binary = shutil.which("mosquitto") or (MOSQUITTO if Path(MOSQUITTO).exists() else None)
        if binary is None:
            raise CnctwinError(
                "Mosquitto is not installed (no mosquitto on PATH or at /usr/sbin/mosquitto); "
                "install the Debian package mosquitto, or give --endpoint mqtt://HOST:PORT"
            )
        self.binary = binary
        self.port = port or _free_port()
        self.url = f"mqtt://127.0.0.1:{self.port}"
        self._dir = Path(tempfile.mkdtemp(prefix="cnctwin-mosquitto-"))
        # started as root (or in a user namespace that maps us to root), Mosquitto would drop
        # to the user "mosquitto"; as the user that starts it, it keeps running as that one
        user = pwd.getpwuid(os.geteuid()).pw_name
        lines = [
            f"listener {self.port} 127.0.0.1",
            "allow_anonymous true",
            "log_dest none",
            f"user {user}",
        ]
        if persistence:
            lines += [
                "persistence true",
                f"persistence_location {self._dir}/",
                f"autosave_interval {autosave_s}",
            ]
        self.conf = self._dir / "mosquitto.conf"
        self.conf.write_text("\n".join(lines) + "\n", encoding="utf-8")
        self._process: subprocess.Popen[bytes] | None = None

    def start(self, timeout_s: float = 10.0) -> None:
        """Start the broker and wait until it accepts connections."""
        self._process = subprocess.Popen(
            [self.binary, "-c", str(self.conf)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
        )
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self._process.poll() is not None:
                stderr = self._process.stderr
                err = stderr.read().decode(errors="replace") if stderr is not None else ""
                raise CnctwinError(f"mosquitto on port {self.port} exited at start: {err[-200:]}")
            try:
                with socket.create_connection(("127.0.0.1", self.port), timeout=0.5):
                    return
            except OSError:
                time.sleep(0.05)
        self.stop()
        raise CnctwinError(f"mosquitto did not listen on 127.0.0.1:{self.port} in {timeout_s} s")

    def stop(self, sig: int = signal.SIGTERM) -> None:
        """Stop the broker with ``sig`` (SIGKILL: no chance to save) and wait for it."""
        process, self._process = self._process, None
        if process is None or process.poll() is not None:
            return
        process.send_signal(sig)
        try:
            process.wait(timeout=10.0)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
        if process.stderr is not None:
            process.stderr.close()

    def restart(self, sig: int = signal.SIGTERM) -> None:
        """Stop with ``sig`` and start again on the same port."""
        self.stop(sig)
        self.start()

    def __enter__(self) -> Mosquitto:
        try:
            self.start()
        except BaseException:
            shutil.rmtree(self._dir, ignore_errors=True)
            raise
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()
        shutil.rmtree(self._dir, ignore_errors=True)
