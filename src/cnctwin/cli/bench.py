"""``cnctwin bench``: measurements of the digital thread against a machine.

``cnctwin bench latency`` runs Heide 2025 section 2.5's write-to-read-back test over OPC UA
or Modbus TCP. Without ``--endpoint`` it starts the virtual machine (packaged demo program)
and its server in a child process, as a separate machine would be, and measures over
loopback; ``--jitter-ms`` puts a :class:`~cnctwin.thread.latency.JitterProxy` in the path.
"""

from __future__ import annotations

import asyncio
import logging
import multiprocessing
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from multiprocessing.connection import Connection
from typing import Annotated
from urllib.parse import urlsplit, urlunsplit

import typer
from rich.console import Console
from rich.table import Table

from cnctwin import finite_json
from cnctwin.cli._options import MAX_SEED, check_count, check_number
from cnctwin.errors import CnctwinError, ConfigError
from cnctwin.thread.config import ConnectionConfig
from cnctwin.thread.connection import MachineConnection
from cnctwin.thread.latency import JitterProxy, LatencyResult, LatencyStats, measure_latency

__all__ = ["app", "connection_for", "latency", "run_latency", "virtual_machine_server"]

logger = logging.getLogger(__name__)

app = typer.Typer(help="Measurements of the digital thread.", no_args_is_help=True)

TRANSPORTS = ("opcua", "modbus")
#: Most round trips of one run: 100,000 at the default 500 ms pause is 14 hours.
MAX_ROUND_TRIPS = 100_000
#: Longest pause between round trips and largest jitter, ms (one minute).
MAX_PAUSE_MS = 60_000.0
_START_TIMEOUT_S = 120.0


@app.callback()
def _bench() -> None:
    """Measurements of the digital thread."""


def connection_for(transport: str, endpoint: str, timeout_s: float = 2.0) -> MachineConnection:
    """A machine connection of ``transport`` (``"opcua"`` or ``"modbus"``) to ``endpoint``."""
    config = ConnectionConfig(
        transport=transport,  # type: ignore[arg-type]
        endpoint=endpoint,
        timeout_s=timeout_s,
    )
    if transport == "opcua":
        from cnctwin.thread.opcua import OpcUaConnection

        # Reads by request: the round trip measures the protocol, not a subscription's cache.
        return OpcUaConnection(config, subscription_ms=None)
    from cnctwin.thread.modbus import ModbusConnection

    return ModbusConnection(config)


def _serve_child(transport: str, pipe: Connection) -> None:
    """Child process: the virtual machine on its clock behind a server, until told to stop."""
    try:
        asyncio.run(_serve(transport, pipe))
    except Exception as err:  # reported to the parent in one line
        pipe.send(("error", f"virtual machine server failed: {type(err).__name__}: {err}"))


async def _serve(transport: str, pipe: Connection) -> None:
    from cnctwin.virtual import MachineClock, ModbusMachineServer, VirtualMachine
    from cnctwin.virtual.config import VirtualMachineConfig
    from cnctwin.virtual.opcua_server import OpcUaMachineServer
    from cnctwin.virtual.users import UserTable

    logging.getLogger("asyncua").setLevel(logging.ERROR)  # policy-None notices
    vm = VirtualMachine(VirtualMachineConfig())
    vm.step(vm.tick_s)  # the first step loads the compiled kernels (~0.5 s): not on the clock
    server: OpcUaMachineServer | ModbusMachineServer
    if transport == "opcua":  # on loopback; the bench writes the feed override anonymously
        server = OpcUaMachineServer(vm, users=UserTable(anonymous="operator"))
    else:
        server = ModbusMachineServer(vm)
    async with server:
        clock = MachineClock(vm, vm.tick_s)
        clock.add_listener(server.publish)
        async with clock:
            pipe.send(("ready", server.endpoint))
            await asyncio.get_running_loop().run_in_executor(None, _wait_for_parent, pipe)


def _wait_for_parent(pipe: Connection) -> None:
    try:
        pipe.recv()
    except EOFError:  # the parent is gone
        pass


@asynccontextmanager
async def virtual_machine_server(transport: str) -> AsyncIterator[str]:
    """Run the virtual machine (demo program, real time) and its server in a child process.

    Parameters
    ----------
    transport
        ``"opcua"`` or ``"modbus"``.

    Yields
    ------
    str
        The server's endpoint on 127.0.0.1.
    """
    context = multiprocessing.get_context("spawn")
    parent, child = context.Pipe()
    process = context.Process(
        target=_serve_child, args=(transport, child), name=f"cnctwin-vm-{transport}", daemon=True
    )
    process.start()
    child.close()
    loop = asyncio.get_running_loop()
    try:
        ready = await loop.run_in_executor(None, parent.poll, _START_TIMEOUT_S)
        if not ready:
            raise CnctwinError(
                f"virtual machine {transport} server did not start within {_START_TIMEOUT_S} s"
            )
        kind, text = parent.recv()
        if kind != "ready":
            raise CnctwinError(text)
        yield text
    finally:
        try:
            parent.send("stop")
        except OSError:
            pass
        await loop.run_in_executor(None, process.join, 10.0)
        if process.is_alive():
            process.terminate()
            process.join(5.0)
        parent.close()


async def run_latency(
    transport: str,
    *,
    n: int,
    interval_ms: float,
    jitter_ms: float = 0.0,
    endpoint: str | None = None,
    seed: int = 0,
) -> tuple[LatencyResult, str]:
    """Measure the round trip; start the virtual machine unless ``endpoint`` is given.

    Returns
    -------
    tuple
        The result and the endpoint measured (the server's, not the proxy's).
    """
    if transport not in TRANSPORTS:
        raise ConfigError(f"--transport {transport!r}; valid: {', '.join(TRANSPORTS)}")
    if endpoint is None:
        async with virtual_machine_server(transport) as url:
            result = await _measure(transport, url, n, interval_ms, jitter_ms, seed)
            return result, url
    return await _measure(transport, endpoint, n, interval_ms, jitter_ms, seed), endpoint


async def _measure(
    transport: str, endpoint: str, n: int, interval_ms: float, jitter_ms: float, seed: int
) -> LatencyResult:
    timeout_s = 2.0 + 4.0 * jitter_ms / 1e3

    async def once(url: str) -> LatencyResult:
        async with connection_for(transport, url, timeout_s) as connection:
            return await measure_latency(
                connection,
                n=n,
                interval_s=interval_ms / 1e3,
                timeout_s=timeout_s,
                jitter_ms=jitter_ms,
            )

    if jitter_ms <= 0:
        return await once(endpoint)
    parts = urlsplit(endpoint)
    if parts.hostname is None or parts.port is None:
        raise ConfigError(f"--endpoint {endpoint!r} has no host:port; valid: SCHEME://HOST:PORT")
    async with JitterProxy(parts.hostname, parts.port, jitter_ms, seed=seed) as proxy:
        via = parts._replace(netloc=f"{proxy.host}:{proxy.port}")
        return await once(urlunsplit(via))


def latency(
    transport: Annotated[
        str, typer.Option("--transport", help="Protocol: opcua or modbus.")
    ] = "opcua",
    n: Annotated[int, typer.Option("--n", min=1, help="Round trips.")] = 500,
    interval_ms: Annotated[
        float, typer.Option("--interval-ms", min=0.0, help="Pause between round trips, ms.")
    ] = 500.0,
    jitter_ms: Annotated[
        float,
        typer.Option(
            "--jitter-ms",
            min=0.0,
            help="One-way jitter J, ms: each request is delayed U(0, 2J) by a loopback proxy.",
        ),
    ] = 0.0,
    endpoint: Annotated[
        str | None,
        typer.Option(
            "--endpoint",
            help="Measure this server (opc.tcp://HOST:PORT/PATH or modbus://HOST:PORT) "
            "instead of starting the virtual machine.",
        ),
    ] = None,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the jitter.")] = 0,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Write-to-read-back latency of the feed override (Heide 2025, section 2.5)."""
    check_count("--n", n, 1, MAX_ROUND_TRIPS)
    check_number("--interval-ms", interval_ms, 0.0, MAX_PAUSE_MS, unit="ms")
    check_number("--jitter-ms", jitter_ms, 0.0, MAX_PAUSE_MS, unit="ms")
    check_count("--seed", seed, 0, MAX_SEED)
    result, url = asyncio.run(
        run_latency(
            transport,
            n=n,
            interval_ms=interval_ms,
            jitter_ms=jitter_ms,
            endpoint=endpoint,
            seed=seed,
        )
    )
    report = {"transport": transport, "endpoint": url, **result.to_dict()}
    if as_json:
        typer.echo(finite_json.dumps(report))
        return
    table = Table(
        title=f"{transport} write-to-read-back latency, {result.n} round trips "
        f"({url}, jitter {jitter_ms:g} ms)"
    )
    table.add_column("ms")
    for name in ("mean", "std", "min", "median", "p99", "max"):
        table.add_column(name, justify="right")
    rows: tuple[tuple[str, LatencyStats], ...] = (
        ("round trip", result.round_trip_ms),
        ("write", result.write_ms),
        ("read", result.read_ms),
    )
    for label, stats in rows:
        table.add_row(
            label,
            *(f"{getattr(stats, k):.3f}" for k in ("mean", "std", "min", "median", "p99", "max")),
        )
    Console().print(table)
