"""``cnctwin virtual serve``: a virtual machine behind OPC UA, Modbus TCP or MTConnect, for a twin.

Serves the ``[virtual]`` machine of a twin configuration (default: the packaged demo's) until
its program ends or Ctrl-C, so that ``cnctwin run`` (or any OPC UA, Modbus or MTConnect
client) can be tried without a real machine. The machine's kernels are compiled before it
listens. ``--once`` ends with the program (:data:`END_GRACE_S` later, for a watching client to
read the end, or once the last OPC UA client has gone, :data:`END_HOLD_MAX_S` at most);
otherwise the machine idles after it, still answering. Security (docs/security.md):
``--security-mode``, ``--certificate``, ``--private-key``, ``--trust``, ``--users``,
``--anonymous``; a non-loopback ``--host`` without security needs ``--insecure``.
``cnctwin virtual hash-password`` makes a users file's entry. ``--replay LOG`` serves a
recorded log instead (``--map``, ``--loop``; docs/replay.md).
"""

from __future__ import annotations

import asyncio
import contextlib
import signal
import sys
from importlib.resources import as_file, files
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal, cast

import typer

from cnctwin.cli._options import MAX_SPEED_FACTOR, MAX_WAIT_S, check_number
from cnctwin.cli.run import note, quiet_protocol_logs
from cnctwin.errors import InputError
from cnctwin.virtual import ROLES, Role, UserTable, check_exposure, hash_password, load_users

if TYPE_CHECKING:
    from cnctwin.twin import MachineServer, RunConfig
    from cnctwin.virtual import OpcUaServerSecurity, ReplayMachine

__all__ = ["app", "hash_password_command", "serve"]

app = typer.Typer(
    help="The virtual machine: serve it over OPC UA, Modbus TCP or MTConnect.",
    no_args_is_help=True,
)

#: With ``--once``: seconds the server still answers after the program ends, so that a client
#: polling it (a twin over MTConnect or Modbus, or one whose cycles run late on a loaded
#: machine) reads the finished state before it goes. A twin that misses it keeps waiting for
#: the machine to come back (docs/twin.md, "The lost-connection policy"); 2 s was missed by
#: twins on a 2-core machine at load 10.
END_GRACE_S = 10.0
#: With ``--once``: the longest the server stays after the program ends while an OPC UA client
#: is still connected, s. A twin that connected and then spent its first run compiling its
#: kernels (about 35 s on 2 cores, more under load) reads the finished state and disconnects.
END_HOLD_MAX_S = 120.0

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
    transport: Annotated[
        str,
        typer.Option(help="Protocol: opcua, modbus, mtconnect (an agent, read-only) or ads."),
    ] = "opcua",
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
    security_mode: Annotated[
        str,
        typer.Option(
            "--security-mode",
            help="OPC UA: None (loopback), Sign or SignAndEncrypt (policy Basic256Sha256).",
        ),
    ] = "None",
    certificate: Annotated[
        Path | None, typer.Option("--certificate", help="Server certificate (DER or PEM).")
    ] = None,
    private_key: Annotated[
        Path | None, typer.Option("--private-key", help="Server private key (PEM).")
    ] = None,
    trust: Annotated[
        Path | None,
        typer.Option("--trust", help="Folder of the client certificates to accept."),
    ] = None,
    users: Annotated[
        Path | None,
        typer.Option("--users", help="Users file (TOML: roles, password hashes)."),
    ] = None,
    anonymous: Annotated[
        str | None,
        typer.Option(
            "--anonymous",
            help="What an anonymous session may do: none, read-only or operator "
            "(default: the users file's, else read-only).",
        ),
    ] = None,
    insecure: Annotated[
        bool,
        typer.Option(
            "--insecure", help="Allow a non-loopback --host without security (trusted network)."
        ),
    ] = False,
    replay: Annotated[
        Path | None,
        typer.Option(
            "--replay",
            help="Serve a recorded log (CSV or Parquet) instead of the simulated machine.",
        ),
    ] = None,
    mapping: Annotated[
        Path | None,
        typer.Option(
            "--map",
            help="Mapping TOML of the log's columns (default: the historian's export format).",
        ),
    ] = None,
    loop: Annotated[
        bool, typer.Option("--loop", help="With --replay: start again after the last row.")
    ] = False,
) -> None:
    """Serve a virtual machine until Ctrl-C (or, with --once, until its program ends).

    The endpoint is printed on stdout as soon as the server listens; point a twin at it with
    ``cnctwin run --config TWIN.toml --endpoint URL``. With ``--replay`` it serves a
    recorded log at recorded time (x ``--speed``) the same way (docs/replay.md).
    """
    from cnctwin.twin import load_run_config

    if transport not in ("opcua", "modbus", "mtconnect", "ads"):
        raise InputError(f"--transport {transport!r}; valid: opcua, modbus, mtconnect, ads")
    secured = transport == "opcua" and security_mode != "None"
    check_exposure(host, transport, secured=secured, insecure=insecure)
    security, table = _access(
        transport, security_mode, certificate, private_key, trust, users, anonymous
    )
    if not 0 <= port <= 65535:
        raise InputError(f"--port {port}; give 0 (a free port) to 65535")
    if speed is not None:
        check_number("--speed", speed, 0.0, MAX_SPEED_FACTOR, low_open=True, unit="x real time")
    check_number("--delay", delay, 0.0, MAX_WAIT_S, unit="s")
    protocol = cast(Literal["opcua", "modbus", "mtconnect", "ads"], transport)
    recorded = _recorded(replay, mapping, loop, config, once)
    quiet_protocol_logs()
    settings = None
    if recorded is not None:
        note(f"replay {recorded.log.summary()}")
    elif config is None:
        with as_file(files("cnctwin.examples")) as folder:
            settings = load_run_config(folder / DEFAULT_CONFIG)
    else:
        settings = load_run_config(config)
    asyncio.run(
        _serve(
            settings, protocol, speed, host, port, delay, once, security, table, insecure, recorded
        )
    )


def _recorded(
    replay: Path | None, mapping: Path | None, loop: bool, config: Path | None, once: bool
) -> ReplayMachine | None:
    """The recorded machine of ``--replay`` (None without it); InputError on options that do
    not go with it."""
    if replay is None:
        if mapping is not None or loop:
            raise InputError(f"{'--map' if mapping is not None else '--loop'} needs --replay LOG")
        return None
    if config is not None:
        raise InputError("--config and --replay: give one (a replay has no [virtual] table)")
    if loop and once:
        raise InputError("--loop and --once: give one (a looping replay never ends)")
    from cnctwin.virtual import ReplayMachine, load_replay_map, read_replay_log

    log = read_replay_log(replay, load_replay_map(mapping) if mapping is not None else None)
    return ReplayMachine(log, loop=loop)


@app.command("hash-password")
def hash_password_command(
    user: Annotated[
        str | None,
        typer.Option("--user", help="Print a [users.NAME] table for a users file."),
    ] = None,
    role: Annotated[str, typer.Option(help="Role of --user: read-only or operator.")] = "operator",
) -> None:
    """Hash a password for a users file (read from stdin, or asked for twice on a terminal).

    Prints the salted scrypt hash, or with ``--user`` the whole ``[users.NAME]`` table.
    """
    if role not in ROLES:
        raise InputError(f"--role {role!r}; valid: {', '.join(ROLES)}")
    if sys.stdin.isatty():
        password = typer.prompt("Password", hide_input=True, confirmation_prompt=True)
    else:
        password = sys.stdin.readline().rstrip("\r\n")
    hashed = hash_password(password)
    if user is None:
        typer.echo(hashed)
    else:
        typer.echo(f'[users.{_toml_key(user)}]\nrole = "{role}"\npassword_hash = "{hashed}"')


def _toml_key(name: str) -> str:
    """``name`` as a TOML key: bare if it can be, else quoted."""
    if name and all(c.isascii() and (c.isalnum() or c in "-_") for c in name):
        return name
    if any(c in name for c in '"\\') or not name.isprintable():
        raise InputError(f"--user {name!r}; valid: printable, without quotes or backslashes")
    return f'"{name}"'


def _access(
    transport: str,
    mode: str,
    certificate: Path | None,
    private_key: Path | None,
    trust: Path | None,
    users: Path | None,
    anonymous: str | None,
) -> tuple[OpcUaServerSecurity | None, UserTable]:
    """The OPC UA server's security and users from the options (InputError if invalid)."""
    given = [
        name
        for name, value in (
            ("--certificate", certificate),
            ("--private-key", private_key),
            ("--trust", trust),
            ("--users", users),
            ("--anonymous", anonymous),
        )
        if value is not None
    ]
    if transport in ("modbus", "mtconnect", "ads"):
        if given or mode != "None":
            options = ", ".join(given or ["--security-mode"])
            name = {"modbus": "Modbus TCP", "mtconnect": "the MTConnect agent", "ads": "ADS"}[
                transport
            ]
            raise InputError(f"{options}: OPC UA only; {name} has no security")
        return None, UserTable()
    if mode not in ("None", "Sign", "SignAndEncrypt"):
        raise InputError(f"--security-mode {mode!r}; valid: None, Sign, SignAndEncrypt")
    if anonymous is not None and anonymous not in (*ROLES, "none"):
        raise InputError(f"--anonymous {anonymous!r}; valid: none, {', '.join(ROLES)}")
    table = load_users(users) if users is not None else UserTable()
    if anonymous is not None:
        table = UserTable(table.accounts, None if anonymous == "none" else cast(Role, anonymous))
    from cnctwin.virtual import OpcUaServerSecurity, SecurityMode

    security = OpcUaServerSecurity(cast(SecurityMode, mode), certificate, private_key, trust)
    return security, table


async def _serve(
    settings: RunConfig | None,
    transport: Literal["opcua", "modbus", "mtconnect", "ads"],
    speed: float | None,
    host: str,
    port: int,
    delay_s: float,
    once: bool,
    security: OpcUaServerSecurity | None,
    users: UserTable,
    insecure: bool,
    replay: ReplayMachine | None,
) -> None:
    from cnctwin.twin import MachineServer

    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError):
            loop.add_signal_handler(sig, stop.set)
    try:
        machine = MachineServer(
            settings,
            transport,
            speed,
            host,
            port,
            security,
            users,
            insecure,
            replay,
            machine_tool_model=True,  # OPC 40501's MachineTool object (docs/opcua.md)
        )
        machine.warm_up()
        await machine.start()
    except OSError as err:
        raise InputError(f"cannot listen on {host}:{port}: {err.strerror or err}") from err
    try:
        typer.echo(machine.endpoint)
        what = "replay" if replay is not None else "virtual machine"
        note(
            f"{what} serving {transport} at {machine.endpoint}, "
            f"{machine.clock.speed:g}x real time; program starts in {delay_s:g} s; Ctrl-C ends"
        )
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(stop.wait(), delay_s)
        machine.go()
        while not stop.is_set():
            if once and machine.vm.finished:
                done = "replay" if replay is not None else "program"
                note(f"{done} finished at t = {machine.vm.time_s:.2f} s")
                await _linger(machine, stop)
                break
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(stop.wait(), 0.1)
    finally:
        await machine.stop()


async def _linger(machine: MachineServer, stop: asyncio.Event) -> None:
    """After the program's end with ``--once``: serve ``END_GRACE_S`` more, and on while an
    OPC UA client stays connected, ``END_HOLD_MAX_S`` at most (or until Ctrl-C)."""
    loop = asyncio.get_running_loop()
    ended = loop.time()
    while not stop.is_set():
        elapsed = loop.time() - ended
        if elapsed >= END_HOLD_MAX_S or (elapsed >= END_GRACE_S and not machine.clients):
            return
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(stop.wait(), 0.1)
