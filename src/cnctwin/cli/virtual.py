"""``cnctwin virtual serve``: a virtual machine behind OPC UA or Modbus TCP, for a twin to watch.

Serves the ``[virtual]`` machine of a twin configuration (default: the packaged demo's) until
its program ends or Ctrl-C, so that ``cnctwin run`` (or any OPC UA / Modbus client) can be
tried without a real machine. ``--once`` ends with the program; otherwise the machine idles
after it, still answering.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import signal
from importlib.resources import as_file, files
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal

import typer

from cnctwin.cli.run import note, quiet_protocol_logs
from cnctwin.errors import ConfigError

if TYPE_CHECKING:
    from cnctwin.twin.config import RunConfig

__all__ = ["app", "serve"]

app = typer.Typer(
    help="The virtual machine: serve it over OPC UA or Modbus TCP.", no_args_is_help=True
)

#: The packaged twin configuration whose [virtual] table is served by default.
DEFAULT_CONFIG = "demo_twin.toml"


@app.command("serve")
def serve(
    config: Annotated[
        Path | None,
        typer.Option(
            "--config", help="Twin configuration with a [virtual] table (default: the demo's)."
        ),
    ] = None,
    transport: Annotated[str, typer.Option(help="Protocol: opcua or modbus.")] = "opcua",
    host: Annotated[str, typer.Option(help="Address to listen on.")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="Port (0: a free one, printed).")] = 4840,
    speed: Annotated[
        float | None,
        typer.Option(help="Machine seconds per wall-clock second (default: [virtual] speed)."),
    ] = None,
    delay: Annotated[
        float,
        typer.Option(
            help="Seconds to wait, listening, before the program starts (time for a twin to "
            "connect and watch it from its start)."
        ),
    ] = 0.0,
    once: Annotated[
        bool, typer.Option("--once", help="End when the program ends (default: keep serving).")
    ] = False,
) -> None:
    """Serve a virtual machine until Ctrl-C (or, with --once, until its program ends).

    The endpoint is printed on stdout as soon as the server listens; point a twin at it with
    ``cnctwin run --config TWIN.toml --endpoint URL``.
    """
    from cnctwin.twin.config import load_run_config

    if transport not in ("opcua", "modbus"):
        raise ConfigError(f"--transport {transport!r}; valid: opcua, modbus")
    if not 0 <= port <= 65535:
        raise ConfigError(f"--port {port}; give 0 (a free port) to 65535")
    if speed is not None and not (math.isfinite(speed) and 0 < speed <= 20):
        raise ConfigError(f"--speed {speed}: give 0 < speed <= 20 machine seconds per second")
    if not (math.isfinite(delay) and delay >= 0):
        raise ConfigError(f"--delay {delay}: give a number of seconds >= 0")
    protocol: Literal["opcua", "modbus"] = "opcua" if transport == "opcua" else "modbus"
    quiet_protocol_logs()
    if config is None:
        with as_file(files("cnctwin.examples")) as folder:
            settings = load_run_config(folder / DEFAULT_CONFIG)
    else:
        settings = load_run_config(config)
    asyncio.run(_serve(settings, protocol, speed, host, port, delay, once))


async def _serve(
    settings: RunConfig,
    transport: Literal["opcua", "modbus"],
    speed: float | None,
    host: str,
    port: int,
    delay_s: float,
    once: bool,
) -> None:
    from cnctwin.twin.host import MachineServer

    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError):
            loop.add_signal_handler(sig, stop.set)
    try:
        machine = MachineServer(settings, transport, speed, host, port)
        await machine.start()
    except OSError as err:
        raise ConfigError(f"cannot listen on {host}:{port}: {err.strerror or err}") from err
    try:
        typer.echo(machine.endpoint)
        note(
            f"virtual machine serving {transport} at {machine.endpoint}, "
            f"{machine.clock.speed:g}x real time; program starts in {delay_s:g} s; Ctrl-C ends"
        )
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(stop.wait(), delay_s)
        machine.go()
        while not stop.is_set():
            if once and machine.vm.finished:
                note(f"program finished at t = {machine.vm.time_s:.2f} s")
                break
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(stop.wait(), 0.1)
    finally:
        await machine.stop()
