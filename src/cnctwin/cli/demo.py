"""``cnctwin demo``: the twin watching a virtual machine, both of Heide 2025's use cases armed.

Starts the packaged virtual machine (``cnctwin/examples/demo_twin.toml`` and
``demo_twin.ngc``: a slender end mill, three passes, a hole in the machine's blank that the
twin does not know of) in a child process serving OPC UA (or Modbus TCP) on loopback, runs
the twin against it, and prints a summary. On the way the predicted form error of the heavy
second pass makes the twin lower the feed override (use case 2), and the hole in the blank
drops the measured force out of the band around the prediction, so the twin stops the
machine (use case 1). See docs/demo.md.

``--config FILE`` runs another twin configuration's own ``[virtual]`` machine and twin the
same way: the shipped closed-loop examples (adaptive feed, chatter avoidance, tool wear)
print what each loop did in the summary (docs/demo.md, "The closed loops").
"""

from __future__ import annotations

import sys
from contextlib import ExitStack
from importlib.resources import as_file, files
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal

import platformdirs
import typer
from rich.console import Console

from cnctwin import finite_json
from cnctwin.cli._options import MAX_SPEED_FACTOR, HistorianDb, check_count, check_number
from cnctwin.cli.run import (
    WEB_PORT,
    linger,
    note,
    quiet_protocol_logs,
    run_with_view,
    summary_report,
    summary_table,
    web_dashboard,
)
from cnctwin.errors import InputError

if TYPE_CHECKING:
    pass

__all__ = ["DEMO_CONFIG", "demo"]

#: The packaged twin configuration of the demo (in :mod:`cnctwin.examples`).
DEMO_CONFIG = "demo_twin.toml"
#: Longest demo, s: its program ends (at the stop) well within a minute at the default speed.
MAX_DEMO_S = 3_600.0
#: With ``--web``, longest wait for the first page before the machine starts anyway, s.
PAGE_WAIT_S = 60.0


def demo(
    duration: Annotated[
        float,
        typer.Option("--duration", help="Longest run in seconds (the demo ends at the stop)."),
    ] = 40.0,
    speed: Annotated[
        float | None,
        typer.Option(
            "--speed",
            help="Machine seconds per wall-clock second (default: the demo's 2).",
        ),
    ] = None,
    db: HistorianDb = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    transport: Annotated[
        str, typer.Option("--transport", help="Protocol of the virtual machine: opcua or modbus.")
    ] = "opcua",
    web: Annotated[
        bool,
        typer.Option(
            "--web",
            help="Serve the live dashboard on 127.0.0.1; the machine starts once a page is open "
            "(docs/dashboard.md).",
        ),
    ] = False,
    port: Annotated[
        int, typer.Option("--port", help="Port of the dashboard (with --web; 0: a free one).")
    ] = WEB_PORT,
    config_file: Annotated[
        Path | None,
        typer.Option(
            "--config",
            help="A twin configuration with a [virtual] machine to run instead of the packaged "
            "demo, e.g. examples/adaptive/adaptive.toml (docs/demo.md, 'The closed loops').",
        ),
    ] = None,
) -> None:
    """Run the twin against a virtual machine on loopback: feed adaptation, then a stop.

    The virtual machine cuts a block with a slender end mill; the twin mirrors it, lowers the
    feed override while the predicted form error is above 40 um, and stops the machine when
    a hole in the blank drops the measured force out of the predicted band.
    """
    from cnctwin.store import Historian
    from cnctwin.twin import MachineProcess, TwinPhysics, load_run_config

    check_number("--duration", duration, 0.0, MAX_DEMO_S, low_open=True, unit="s")
    if speed is not None:
        check_number("--speed", speed, 0.0, MAX_SPEED_FACTOR, low_open=True, unit="x real time")
    check_count("--port", port, 0, 65535)
    if transport not in ("opcua", "modbus"):
        raise InputError(f"--transport {transport!r}; valid: opcua, modbus")
    protocol: Literal["opcua", "modbus"] = "opcua" if transport == "opcua" else "modbus"
    quiet_protocol_logs()
    with ExitStack() as files_of:
        if config_file is None:
            folder = files_of.enter_context(as_file(files("cnctwin.examples")))
            config = load_run_config(folder / DEMO_CONFIG)
        else:
            config = load_run_config(config_file)
            folder = config_file.resolve().parent
            if config.virtual is None:
                raise InputError(
                    f"--config {config_file}: no [virtual] table; valid: a twin configuration "
                    "with the virtual machine to run, e.g. examples/adaptive/adaptive.toml"
                )
        command = "cnctwin demo" if config_file is None else f"cnctwin demo --config {config_file}"
        with (
            Historian.open(db) as historian,
            web_dashboard(
                config, folder, enabled=web, host="127.0.0.1", port=port, insecure=False
            ) as board,
        ):
            note(f"history: {historian.location}")
            # the machine's log, per user (a shared /tmp file could belong to another user)
            log = Path(platformdirs.user_log_dir("cnctwin")) / "demo-machine.log"
            log.parent.mkdir(parents=True, exist_ok=True)
            log.write_text("")
            machine = MachineProcess(config, protocol, speed, log=log)
            try:
                machine.spawn()
                # compile the twin's kernels while the machine compiles its own
                TwinPhysics(config, density_per_mm=config.twin.density_per_mm).warm_up()
                endpoint = machine.wait_ready()
                factor = speed if speed is not None else machine.speed_factor
                note(
                    f"virtual machine: {endpoint} ({protocol}, {factor:g}x real time; "
                    f"its log: {log})"
                )
                if board is not None:
                    note(f"open {board.url} in a browser: the machine starts once a page is open")
                    board.wait_for_page(PAGE_WAIT_S)
                settings = config.model_copy(
                    update={
                        "connection": config.connection.model_copy(
                            update={"endpoint": endpoint, "transport": protocol}
                        )
                    }
                )
                summary = run_with_view(
                    settings,
                    historian,
                    live=not as_json,
                    web=board,
                    on_start=lambda _twin: machine.go(),
                    duration_s=duration,
                    meta={"command": command, "virtual_machine": endpoint},
                    base_dir=folder,
                )
                machine_state = machine.state() or {}
            finally:
                machine.stop()
            report = summary_report(
                summary,
                transport=protocol,
                endpoint=endpoint,
                machine_time_s=machine_state.get("t_s"),
                machine_tool_wear_mm=machine_state.get("tool_wear_mm"),
            )
            if as_json:
                sys.stdout.write(finite_json.dumps(report) + "\n")
            else:
                Console().print(summary_table(report, title=command))
            linger(board, summary)
