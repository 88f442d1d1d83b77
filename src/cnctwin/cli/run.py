"""``cnctwin run``: the running twin against a machine, with a live terminal view.

Connects to the machine of the configuration's ``[connection]`` (OPC UA, Modbus TCP,
MTConnect, ADS or LinuxCNC), runs the twin cycle until the program ends, the machine stops,
``--duration`` is up or Ctrl-C, records the run in the historian, and prints a summary
(``--json``: one object).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import signal
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.console import Console, Group
from rich.live import Live
from rich.table import Table
from rich.text import Text

from cnctwin import finite_json
from cnctwin.cli._options import MAX_RUN_S, MAX_WAIT_S, check_count, check_number
from cnctwin.errors import InputError
from cnctwin.thread import RunState

if TYPE_CHECKING:
    from cnctwin.store import Historian
    from cnctwin.twin import CycleState, RunConfig, RunSummary, Twin, TwinRuntime
    from cnctwin.web import LiveDashboard

__all__ = [
    "LiveView",
    "linger",
    "note",
    "quiet_protocol_logs",
    "run",
    "run_until_interrupted",
    "run_with_view",
    "summary_report",
    "summary_table",
    "web_dashboard",
]

#: Default port of the dashboard (``--web``).
WEB_PORT = 8765

#: Keys of the summary every ``--json`` output has (see docs/twin.md).
SUMMARY_KEYS = (
    "cycles",
    "cycle_p50_ms",
    "cycle_p99_ms",
    "overruns",
    "stop_reaction_ms",
    "feed_override_min",
    "events",
    "samples_recorded",
    "database",
)


def run(
    config: Annotated[
        Path, typer.Option("--config", "-c", help="Twin configuration TOML (see docs/twin.md).")
    ],
    db: Annotated[
        str | None,
        typer.Option(
            "--db",
            help="Historian: SQLite file or postgresql://USER@HOST:PORT/DB "
            "(default: [historian] url, else the installation's file).",
        ),
    ] = None,
    duration: Annotated[
        float | None,
        typer.Option("--duration", help="Stop after this many seconds (default: program end)."),
    ] = None,
    endpoint: Annotated[
        str | None,
        typer.Option(
            "--endpoint",
            help="Machine address (opc.tcp://..., modbus://..., an MTConnect agent's "
            "http://..., ads://AMSNETID:AMSPORT@HOST or LinuxCNC's linuxcncrsh://...), "
            "overriding [connection].",
        ),
    ] = None,
    connect_timeout: Annotated[
        float,
        typer.Option("--connect-timeout", help="Seconds to keep trying to reach the machine."),
    ] = 10.0,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print one JSON object at the end, no live view.")
    ] = False,
    web: Annotated[
        bool,
        typer.Option("--web", help="Serve the live dashboard in the browser (docs/dashboard.md)."),
    ] = False,
    host: Annotated[
        str, typer.Option("--host", help="Address the dashboard listens on (with --web).")
    ] = "127.0.0.1",
    port: Annotated[
        int, typer.Option("--port", help="Port of the dashboard (with --web; 0: a free one).")
    ] = WEB_PORT,
    insecure: Annotated[
        bool,
        typer.Option(
            "--insecure",
            help="Allow a non-loopback --host for the dashboard (plain HTTP, trusted network).",
        ),
    ] = False,
) -> None:
    """Run the twin against a machine until its program ends or Ctrl-C.

    Reads the machine every cycle, cuts the twin's own stock, predicts forces and form error,
    evaluates the rules and (with [control] enabled) commands the machine through the safety
    filter; everything goes to the historian.
    """
    from cnctwin.store import Historian
    from cnctwin.twin import load_run_config

    if duration is not None:
        check_number("--duration", duration, 0.0, MAX_RUN_S, low_open=True, unit="s")
    check_number("--connect-timeout", connect_timeout, 0.0, MAX_WAIT_S, low_open=True, unit="s")
    check_count("--port", port, 0, 65535)
    if web:  # before anything is opened or created (the historian file)
        from cnctwin.web import check_host

        check_host(host, insecure)
    settings = load_run_config(config)
    quiet_protocol_logs()
    if endpoint is not None:
        update: dict[str, str] = {"endpoint": endpoint}
        if endpoint.startswith("modbus://"):
            update["transport"] = "modbus"
        elif endpoint.startswith("opc.tcp://"):
            update["transport"] = "opcua"
        elif endpoint.startswith("http://"):
            update["transport"] = "mtconnect"
        elif endpoint.startswith("ads://"):
            update["transport"] = "ads"
        elif endpoint.startswith("linuxcncrsh://"):
            update["transport"] = "linuxcnc"
        else:
            raise InputError(
                f"--endpoint {endpoint!r}; give opc.tcp://HOST:PORT/PATH, modbus://HOST:PORT, "
                "http://HOST:PORT (MTConnect), ads://AMSNETID:AMSPORT@HOST[:PORT] or "
                "linuxcncrsh://HOST:PORT (LinuxCNC)"
            )
        settings = settings.model_copy(
            update={"connection": settings.connection.model_copy(update=update)}
        )
    historian = Historian.open(db) if db is not None else Historian.from_config(settings.historian)
    base_dir = config.resolve().parent
    with (
        historian,
        web_dashboard(
            settings, base_dir, enabled=web, host=host, port=port, insecure=insecure
        ) as board,
    ):
        note(f"history: {historian.location}")
        summary = run_with_view(
            settings,
            historian,
            live=not as_json,
            web=board,
            duration_s=duration,
            meta={"config": str(config.resolve()), "command": "cnctwin run"},
            base_dir=base_dir,
            connect_timeout_s=connect_timeout,
        )
        report = summary_report(summary)
        if as_json:
            sys.stdout.write(finite_json.dumps(report) + "\n")
        else:
            Console().print(summary_table(report, title=f"twin run: {config.name}"))
        linger(board, summary)


async def run_until_interrupted(
    start: Callable[[asyncio.Event], Any], view: LiveView
) -> RunSummary:
    """Run a session; Ctrl-C (SIGINT) or SIGTERM ends it cleanly after the current cycle."""
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    installed = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError):
            loop.add_signal_handler(sig, stop.set)
            installed.append(sig)
    refresher = loop.create_task(view.refresh_loop())
    try:
        result: RunSummary = await start(stop)
        return result
    finally:
        refresher.cancel()
        for sig in installed:
            loop.remove_signal_handler(sig)


def summary_report(summary: RunSummary, **extra: Any) -> dict[str, Any]:
    """The summary as one JSON-ready object, the keys of :data:`SUMMARY_KEYS` first."""
    data = summary.to_dict()
    report = {key: data.pop(key) for key in SUMMARY_KEYS}
    report.update(data)
    report.update(extra)
    return report


def summary_table(report: dict[str, Any], title: str) -> Table:
    """A two-column table of a summary report."""

    def ms(value: float | None) -> str:
        return "-" if value is None else f"{value:.2f} ms"

    table = Table(title=title, show_header=False, title_justify="left")
    override = report["feed_override_min"]
    rows = [
        ("ended", str(report["ended"])),
        ("cycles", str(report["cycles"])),
        ("cycle time p50 / p99", f"{ms(report['cycle_p50_ms'])} / {ms(report['cycle_p99_ms'])}"),
        ("overruns", str(report["overruns"])),
        ("stop reaction", ms(report["stop_reaction_ms"])),
        ("lowest feed override", "-" if override is None else f"{override:.0f} %"),
        ("decisions", str(report["decisions"])),
        ("events", str(report["events"])),
        ("reconnections", str(report["reconnects"])),
        ("samples recorded", str(report["samples_recorded"])),
        ("history", str(report["database"])),
    ]
    mqtt = report.get("outlets", {}).get("mqtt_publish", {})
    if "publisher" in mqtt:
        pub = mqtt["publisher"]
        rows.append(
            (
                "MQTT messages",
                f"{pub['acked']} of {pub['offered']} acknowledged, {pub['dropped']} dropped, "
                f"{pub['reconnects']} reconnections",
            )
        )
    if "source" in mqtt:
        src = mqtt["source"]
        rejected = sum(src["rejected"].values())
        rows.append(("MQTT sensor messages", f"{src['received']} received, {rejected} rejected"))
    rows.extend(_loop_rows(report))
    for key, value in rows:
        table.add_row(key, value)
    return table


def _loop_rows(report: dict[str, Any]) -> list[tuple[str, str]]:
    """What the closed loops did, from the summary's ``stage_results`` (and, with a virtual
    machine, its true tool wear ``machine_tool_wear_mm``): one row per loop."""
    results = report.get("stage_results", {})
    rows: list[tuple[str, str]] = []
    feed = results.get("adaptive_feed")
    if feed is not None:
        unit = "N" if feed["quantity"] == "force" else "W"
        reference = feed["reference"]
        low = feed["lowest_override_pct"]
        rows.append(
            (
                "adaptive feed",
                f"peak {feed['quantity']} {feed['peak_engaged']:.0f} {unit} while engaged"
                + ("" if reference is None else f" (reference {reference:.0f} {unit})")
                + f", {feed['commands']} feed commands"
                + ("" if low is None else f", lowest {low:.0f} %"),
            )
        )
    chatter = results.get("chatter")
    if chatter is not None:
        found = chatter["detections"]
        text = "none detected"
        if found:
            first = found[0]
            text = (
                f"detected {1e3 * first['after_engagement_s']:.0f} ms after the engagement began, "
                f"at "
                f"{first['frequency_hz']:.0f} Hz, {first['spindle_rpm']:.0f} rpm (line "
                f"{first['line']})"
            )
        for change in chatter["avoidances"]:
            text += (
                f"; spindle {change['programmed_rpm']:.0f} -> {change['stable_rpm']:.0f} rpm "
                f"at {change['machine_s']:.2f} s machine time"
            )
        rows.append(("chatter", text))
    true_vb = report.get("machine_tool_wear_mm")
    for number, tool in results.get("wear", {}).items():
        text = f"VB {tool['vb_mm']:.3f} +- {tool['sd_mm']:.3f} mm, stage {tool['stage']}"
        entry = tool["stage_entries"].get("4")
        if entry is not None:
            text += f"; stage IV at VB {entry['vb_mm']:.3f} mm after {entry['cut_s']:.1f} s cutting"
        if true_vb:
            text += f"; machine's true VB {true_vb:.3f} mm at the end"
        rows.append((f"wear T{number}", text))
    return rows


class LiveView:
    """The live terminal view: machine signals, predictions, cycle time and decisions.

    :meth:`observe` is called by the runtime after each cycle (it only keeps the state);
    :meth:`refresh_loop` redraws a few times a second between cycles.

    Parameters
    ----------
    enabled
        Draw at all (off for ``--json`` and when stdout is not a terminal).
    refresh_s
        Time between redraws, s.
    """

    def __init__(self, enabled: bool, refresh_s: float = 0.25) -> None:
        self.enabled = enabled
        self.refresh_s = refresh_s
        self.state: CycleState | None = None
        self.cycles = 0
        self.decisions: list[str] = []
        self.events: list[str] = []
        self.runtime: TwinRuntime | None = None
        self._live: Live | None = None
        self._started = time.monotonic()
        self._cycle_ms: list[float] = []

    def attach(self, twin: Twin) -> None:
        """Show the cycle times of this twin (``on_start`` of the session)."""
        self.runtime = twin.runtime

    def observe(self, state: CycleState) -> None:
        """Keep the latest cycle, its decisions and events."""
        self.state = state
        self.cycles += 1
        for result in state.decisions:
            verdict = result.verdict
            value = "-" if verdict.value is None else f"{verdict.value:.4g}"
            self.decisions.append(
                f"{verdict.decision.rule}: {verdict.outcome} {verdict.command or ''}={value}"
            )
        for event in state.events:
            self.events.append(event.message)
        del self.decisions[:-5]
        del self.events[:-4]

    @contextlib.contextmanager
    def running(self) -> Iterator[None]:
        """Show the view while the block runs."""
        if not self.enabled:
            yield
            return
        with Live(self.render(), auto_refresh=False, transient=False) as live:
            self._live = live
            try:
                yield
            finally:
                live.update(self.render(), refresh=True)
                self._live = None

    async def refresh_loop(self) -> None:
        """Redraw every ``refresh_s`` until cancelled."""
        while self._live is not None:
            self._live.update(self.render(), refresh=True)
            await asyncio.sleep(self.refresh_s)

    def render(self) -> Group:
        """The view's renderable."""
        s = self.state
        table = Table(show_header=True, expand=False, box=None)
        table.add_column("machine")
        table.add_column("", justify="right")
        table.add_column("twin")
        table.add_column("", justify="right")
        if s is None:
            return Group(Text("waiting for the machine ..."), table)
        m, p = s.measured, s.predicted

        def f(values: dict[str, float], key: str, fmt: str = ".1f") -> str:
            value = values.get(key)
            return "-" if value is None else format(value, fmt)

        state = m.get("run_state")
        state_name = RunState(int(state)).name if state is not None and 0 <= state <= 5 else "-"
        rows = [
            ("run state", state_name, "cycle", str(s.index)),
            ("t (s)", f(m, "t_s", ".2f"), "line", str(s.line)),
            ("X / Y / Z (mm)", _xyz(m), "tool", f"T{s.tool}"),
            (
                "spindle (rpm)",
                f(m, "spindle_rpm", ".0f"),
                "ae / ap (mm)",
                f"{f(p, 'ae_mm', '.2f')} / {f(p, 'ap_mm', '.2f')}",
            ),
            (
                "feed (mm/min)",
                f(m, "feed_mm_min", ".0f"),
                "force predicted (N)",
                f(p, "predicted_force_xy_n"),
            ),
            (
                "feed override (%)",
                f(m, "feed_override_pct", ".0f"),
                "force band (N)",
                f"{f(p, 'force_band_low_n', '.0f')} .. {f(p, 'force_band_high_n', '.0f')}",
            ),
            (
                "force measured (N)",
                f(p, "measured_force_xy_n"),
                "form error (um)",
                f"{f(p, 'form_error_um')} / {f(p, 'form_error_tolerance_um', '.0f')}",
            ),
            (
                "spindle power (W)",
                f(m, "spindle_power_w", ".0f"),
                "torque predicted (N m)",
                f(p, "predicted_torque_nm", ".2f"),
            ),
        ]
        runtime = self.runtime
        if runtime is not None:
            times = runtime.cycle_times
            rows.append(
                (
                    "connected",
                    "yes" if runtime.connected else "NO",
                    "cycle p50 / p99 (ms)",
                    f"{times.recent_percentile_ms(50):.2f} / {times.recent_percentile_ms(99):.2f}"
                    f"  overruns {runtime.overruns}",
                )
            )
        for row in rows:
            table.add_row(*row)
        parts: list[Any] = [table]
        if self.decisions:
            parts.append(Text("decisions: " + " | ".join(self.decisions[-3:])))
        if self.events:
            parts.append(Text("events: " + " | ".join(self.events[-2:])))
        return Group(*parts)


def run_with_view(
    settings: RunConfig,
    historian: Historian,
    *,
    live: bool,
    on_start: Callable[[Twin], None] | None = None,
    web: LiveDashboard | None = None,
    **session: Any,
) -> RunSummary:
    """Run one twin session under the live view (on a terminal, when ``live``) until it ends
    or Ctrl-C; ``on_start`` runs once the twin is built (after the view is attached);
    ``web``, a started dashboard, watches it too; ``session`` goes to
    :func:`cnctwin.twin.session.run_session`."""
    from cnctwin.twin import run_session

    view = LiveView(enabled=live and sys.stdout.isatty())

    def on_cycle(state: CycleState) -> None:
        view.observe(state)
        if web is not None:
            web.observe(state)

    def start(twin: Twin) -> None:
        view.attach(twin)
        if web is not None:
            web.attach(twin)
        if on_start is not None:
            on_start(twin)

    with view.running():
        return asyncio.run(
            run_until_interrupted(
                lambda stop: run_session(
                    settings,
                    historian=historian,
                    stop_event=stop,
                    on_cycle=on_cycle,
                    on_start=start,
                    **session,
                ),
                view,
            )
        )


@contextlib.contextmanager
def web_dashboard(
    settings: RunConfig, base_dir: Path, *, enabled: bool, host: str, port: int, insecure: bool
) -> Iterator[LiveDashboard | None]:
    """The live dashboard of ``--web``, serving for the block with its address on stderr;
    ``None`` when not ``enabled``."""
    if not enabled:
        yield None
        return
    from cnctwin.web import LiveDashboard

    program = settings.twin.program
    if program is None and settings.virtual is not None:
        program = settings.virtual.program
    board = LiveDashboard(
        host=host,
        port=port,
        insecure=insecure,
        control_enabled=settings.control.enabled,
        title=settings.machine.name,
        program=None if program is None else base_dir / program,
    )
    with board:
        if board.token_for_view:
            note(f"dashboard: {board.url}?token={board.token} (every page needs the token)")
        else:
            note(f"dashboard: {board.url}")
        if settings.control.enabled:
            note(f"dashboard control token: {board.token} (open {board.url}?token={board.token})")
        else:
            note("dashboard control: off ([control] enabled = false)")
        yield board


def linger(board: LiveDashboard | None, summary: RunSummary) -> None:
    """After the run, keep the dashboard serving until Ctrl-C so the run can still be read."""
    if board is None:
        return
    board.finish(summary)
    note(f"run ended ({summary.ended}); the dashboard stays at {board.url} until Ctrl-C")
    board.wait_until_interrupted()


_PROTOCOL_LOGGERS = ("asyncua", "asyncuagds", "pymodbus")


class _OneLine(logging.Filter):
    """A protocol library's error with its exception on one line, without the traceback
    (e.g. asyncua's "Publish iteration crashed" when the server closes first)."""

    def filter(self, record: logging.LogRecord) -> bool:
        if record.exc_info and record.name.split(".")[0] in _PROTOCOL_LOGGERS:
            error = record.exc_info[1]
            record.msg = f"{record.getMessage()}: {type(error).__name__}: {error}"
            record.args = None
            record.exc_info = record.exc_text = None
        return True


def quiet_protocol_logs() -> None:
    """Keep the protocol libraries' notes (asyncua, pymodbus) off the terminal unless they
    are errors, each error on one line; ``--debug`` shows everything."""
    if not logging.getLogger("cnctwin").isEnabledFor(logging.DEBUG):
        for name in _PROTOCOL_LOGGERS:
            logging.getLogger(name).setLevel(logging.ERROR)
        for handler in logging.getLogger().handlers:
            if not any(isinstance(f, _OneLine) for f in handler.filters):
                handler.addFilter(_OneLine())


def note(line: str) -> None:
    """One line of information on stderr (stdout stays for the result)."""
    sys.stderr.write(line + "\n")
    sys.stderr.flush()


def _xyz(m: dict[str, float]) -> str:
    values = [m.get(k) for k in ("x_mm", "y_mm", "z_mm")]
    return " / ".join("-" if v is None else f"{v:.2f}" for v in values)
