"""The child process of :class:`cnctwin.twin.host.MachineProcess`: serve one virtual machine.

``python -m cnctwin.twin.serve TRANSPORT HOST PORT SPEED`` reads the run configuration (JSON)
from the first line of stdin, answers ``{"endpoint": ...}`` on stdout once listening, then
takes ``go``, ``state`` and ``stop`` on stdin.
"""

from __future__ import annotations

import asyncio
import logging
import sys

from cnctwin.twin.config import RunConfig
from cnctwin.twin.host import serve

__all__ = ["main"]


def main(argv: list[str]) -> None:
    """``python -m cnctwin.twin.serve TRANSPORT HOST PORT SPEED``, config JSON on stdin."""
    logging.basicConfig(format="%(levelname)s %(name)s: %(message)s", level=logging.WARNING)
    # the server's notes on its security set-up are not the demo's business
    logging.getLogger("asyncua").setLevel(logging.ERROR)
    transport, host, port, speed = argv
    config = RunConfig.model_validate_json(sys.stdin.readline())
    if transport not in ("opcua", "modbus", "mtconnect", "ads"):
        raise SystemExit(f"transport {transport!r}; valid: opcua, modbus, mtconnect, ads")
    asyncio.run(
        serve(config, transport, float(speed) if speed else None, host, int(port))  # type: ignore[arg-type]
    )


if __name__ == "__main__":
    main(sys.argv[1:])
