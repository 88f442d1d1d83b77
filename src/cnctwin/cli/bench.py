"""``cnctwin bench``: measurements of the digital thread against a machine.

``cnctwin bench latency`` runs Heide 2025 section 2.5's write-to-read-back test over OPC UA,
Modbus TCP or ADS, the read round trip alone over MTConnect (read-only), and the publish-to-
receive round trip through a broker over MQTT. Without ``--endpoint`` it starts the virtual
machine (packaged demo program) and its server in a child process, as a separate machine
would be (for MQTT: a private Mosquitto), and measures over loopback; ``--jitter-ms`` puts a
:class:`~cnctwin.thread.latency.JitterProxy` in the path.
"""

from __future__ import annotations

import asyncio
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from cnctwin import finite_json
from cnctwin.cli._options import MAX_SEED, check_count, check_number
from cnctwin.errors import InputError
from cnctwin.thread import (
    LatencyResult,
    LatencyStats,
    measure_broker_latency,
    measure_endpoint_latency,
)

__all__ = ["app", "latency", "run_latency"]

app = typer.Typer(help="Measurements of the digital thread.", no_args_is_help=True)

#: Most round trips of one run: 100,000 at the default 500 ms pause is 14 hours.
MAX_ROUND_TRIPS = 100_000
#: Longest pause between round trips and largest jitter, ms (one minute).
MAX_PAUSE_MS = 60_000.0


@app.callback()
def _bench() -> None:
    """Measurements of the digital thread."""


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
    from cnctwin.virtual import TRANSPORTS, virtual_machine_server

    if transport == "linuxcnc" and endpoint is None:
        raise InputError(
            "--transport linuxcnc needs --endpoint linuxcncrsh://HOST:PORT (a running LinuxCNC; "
            "the virtual machine does not serve linuxcncrsh)"
        )
    if transport not in (*TRANSPORTS, "linuxcnc", "mqtt"):
        raise InputError(
            f"--transport {transport!r}; valid: {', '.join(TRANSPORTS)}, linuxcnc, mqtt"
        )
    interval_s = interval_ms / 1e3
    if transport == "mqtt":
        try:
            return await measure_broker_latency(
                endpoint, n=n, interval_s=interval_s, jitter_ms=jitter_ms, seed=seed
            )
        except InputError as err:
            raise InputError(f"--endpoint: {err}") from None
    if endpoint is None:
        async with virtual_machine_server(transport) as url:
            result = await measure_endpoint_latency(
                transport, url, n=n, interval_s=interval_s, jitter_ms=jitter_ms, seed=seed
            )
            return result, url
    try:
        result = await measure_endpoint_latency(
            transport, endpoint, n=n, interval_s=interval_s, jitter_ms=jitter_ms, seed=seed
        )
    except InputError as err:
        raise InputError(f"--endpoint: {err}") from None
    return result, endpoint


def latency(
    transport: Annotated[
        str,
        typer.Option(
            "--transport",
            help="Protocol: opcua, modbus, mtconnect (read only), ads, linuxcnc (with --endpoint),"
            " mqtt (publish to receive).",
        ),
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
            help="Measure this server (opc.tcp://HOST:PORT/PATH, modbus://HOST:PORT, an "
            "MTConnect agent's http://HOST:PORT, ads://AMSNETID:AMSPORT@HOST:PORT or an MQTT"
            " broker's mqtt://HOST:PORT) instead of starting the virtual machine (or a private"
            " Mosquitto).",
        ),
    ] = None,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the jitter.")] = 0,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Write-to-read-back latency of the feed override (Heide 2025, section 2.5); over
    MTConnect (read-only) the read round trip; over MQTT publish to receive via the broker."""
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
    kind = {"mqtt": "publish-to-receive"}.get(
        transport, "read" if result.write_ms is None else "write-to-read-back"
    )
    security = "" if result.security is None else f", security {result.security}"
    table = Table(
        title=f"{transport} {kind} latency, {result.n} round trips "
        f"({url}, jitter {jitter_ms:g} ms{security})"
    )
    table.add_column("ms")
    for name in ("mean", "std", "min", "median", "p99", "max"):
        table.add_column(name, justify="right")
    rows: tuple[tuple[str, LatencyStats | None], ...] = (
        ("round trip", result.round_trip_ms),
        ("write", result.write_ms),
        ("read", result.read_ms),
    )
    for label, stats in rows:
        if stats is None:
            continue
        table.add_row(
            label,
            *(f"{getattr(stats, k):.3f}" for k in ("mean", "std", "min", "median", "p99", "max")),
        )
    Console().print(table)
