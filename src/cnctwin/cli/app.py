"""The ``cnctwin`` command under typer: the root of the command groups and global options.

:func:`invoke` runs a command line through it and reports usage errors; the console script
(:mod:`cnctwin.cli._entry`, re-exported here as ``run`` and ``main``) reports the others.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Annotated, Any

import typer
from typer.core import TyperCommand, TyperGroup

from cnctwin import __version__
from cnctwin.cli._entry import EXIT_BAD_INPUT, EXIT_INTERRUPTED, fail, main, run, set_debug

__all__ = ["COMMANDS", "app", "invoke", "load_command", "main", "run"]


@dataclass(frozen=True)
class _Lazy:
    """A command imported only when it runs or shows its own help.

    ``module`` is a module of :mod:`cnctwin.cli`; ``attribute`` is either its
    :class:`typer.Typer` (a command group) or a command function. ``summary`` is the line
    ``cnctwin --help`` lists (the command's first sentence; a test keeps them equal).
    ``extra`` adds commands defined in other modules to a group: (name, module, function).
    """

    module: str
    attribute: str
    summary: str
    extra: tuple[tuple[str, str, str], ...] = ()


#: Every command of ``cnctwin``, in the order ``--help`` lists them. Nothing here is
#: imported until a command is used, so ``--version`` and ``--help`` stay light.
COMMANDS: dict[str, _Lazy] = {
    "demo": _Lazy(
        "demo",
        "demo",
        "Run the twin against a virtual machine on loopback: feed adaptation, then a stop.",
    ),
    "run": _Lazy("run", "run", "Run the twin against a machine until its program ends or Ctrl-C."),
    "forces": _Lazy(
        "forces",
        "forces",
        "Mean forces, torque and power of a flat end mill in a straight cut.",
    ),
    "materials": _Lazy(
        "forces",
        "materials_app",
        "The materials library: list its entries, identify your own from measured forces.",
    ),
    "simulate": _Lazy(
        "simulate",
        "simulate",
        "Cut the stock along a program: engagement per step, removed volume, final stock.",
    ),
    "signals": _Lazy(
        "signals",
        "signals",
        "Predicted forces, spindle torque, power and current, and feed-drive loads over time.",
    ),
    "optimize": _Lazy(
        "optimize",
        "optimize",
        "Rewrite a program's feeds (and speeds) per block from force, power and chip limits.",
    ),
    "nc": _Lazy("nc", "app", "Read NC programs: summarize, trace, plot."),
    "bench": _Lazy(
        "bench", "app", "Measurements of the digital thread.", (("latency", "bench", "latency"),)
    ),
    "wear": _Lazy(
        "wear",
        "app",
        "Tool wear twins: monitoring and compensation.",
        (
            ("ekf", "wear_ekf", "ekf"),
            ("mount", "wear_registry", "mount"),
            ("compensate", "wear_registry", "compensate"),
            ("retire", "wear_registry", "retire"),
            ("history", "wear_registry", "history"),
        ),
    ),
    "study": _Lazy("study", "app", "Parameter studies of the simulation."),
    "roughness": _Lazy(
        "roughness",
        "app",
        "Surface roughness: fit the power-law model to cuts, predict with it.",
    ),
    "mirs": _Lazy(
        "mirs",
        "app",
        "Elastic machining-induced residual stress (Ward 2021): predict, search feed and speed.",
    ),
    "dynamics": _Lazy(
        "dynamics", "app", "Structural dynamics: FRFs and modal fits from tap tests."
    ),
    "stability": _Lazy(
        "stability",
        "app",
        "Chatter stability of milling and turning.",
        (("roadmap", "roadmap", "roadmap"),),
    ),
    "chatter": _Lazy(
        "chatter",
        "app",
        "Time-domain milling vibration, chatter detection, process-damping calibration.",
    ),
    "vibration": _Lazy("vibration", "app", "Milling vibration over time (time-domain model)."),
    "modal": _Lazy("modal", "app", "Modal parameters from tap tests."),
    "runs": _Lazy("runs", "app", "Recorded runs of the twin: list, show, export."),
    "learn": _Lazy(
        "learn",
        "app",
        "Learned models: train on recorded runs with grouped splits, evaluate, inspect.",
    ),
    "web": _Lazy(
        "web",
        "web",
        "Serve the run browser: list recorded runs, open one, zoom any signal, overlay, export.",
    ),
    "virtual": _Lazy(
        "virtual", "app", "The virtual machine: serve it over OPC UA, Modbus TCP or MTConnect."
    ),
}


def load_command(name: str) -> Any:
    """Import the command ``name`` of :data:`COMMANDS` and build its click command."""
    entry = COMMANDS[name]
    target = getattr(importlib.import_module(f"cnctwin.cli.{entry.module}"), entry.attribute)
    if isinstance(target, typer.Typer):
        registered = {info.name for info in target.registered_commands}
        for command, module, function in entry.extra:
            if command not in registered:
                target.command(command)(
                    getattr(importlib.import_module(f"cnctwin.cli.{module}"), function)
                )
    # Built under a root like the real one, so help renders alike (plain text, no
    # completion options).
    holder = typer.Typer(add_completion=False, rich_markup_mode=None)
    if isinstance(target, typer.Typer):
        holder.add_typer(target, name=name)
    else:
        holder.command(name)(target)
    built = typer.main.get_command(holder)
    return built.commands[name] if isinstance(built, TyperGroup) else built


class _LazyCommands(Mapping[str, Any]):
    """The root group's commands: names known up front, each command built on first use."""

    def __init__(self) -> None:
        self._loaded: dict[str, Any] = {}

    def __getitem__(self, name: str) -> Any:
        if name not in self._loaded:
            if name not in COMMANDS:
                raise KeyError(name)
            self._loaded[name] = load_command(name)
        return self._loaded[name]

    def __iter__(self) -> Iterator[str]:
        return iter(COMMANDS)

    def __len__(self) -> int:
        return len(COMMANDS)

    def __contains__(self, name: object) -> bool:
        return name in COMMANDS


class _LazyGroup(TyperGroup):
    """The root group: lists its commands from :data:`COMMANDS` without importing them."""

    def __init__(self, **attrs: Any) -> None:
        super().__init__(**attrs)
        self.commands = _LazyCommands()  # type: ignore[assignment]

    def format_commands(self, ctx: Any, formatter: Any) -> None:
        limit = formatter.width - 6 - max(len(name) for name in COMMANDS)
        rows = [
            (name, TyperCommand(name, help=entry.summary).get_short_help_str(limit))
            for name, entry in COMMANDS.items()
        ]
        with formatter.section("Commands"):
            formatter.write_dl(rows)


app = typer.Typer(
    name="cnctwin",
    cls=_LazyGroup,
    help="cnctwin: a digital twin for CNC machining.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    # Plain help text: option help and docstrings name TOML tables such as [lobes] and
    # [[modes]], which rich markup would swallow.
    rich_markup_mode=None,
)


def _version(value: bool) -> None:
    if value:
        from cnctwin.nc import compiled_modules  # light: numpy and the interpreter stay out

        build = "compiled" if compiled_modules() else "pure Python"
        typer.echo(f"cnctwin {__version__} (NC interpreter: {build})")
        raise typer.Exit()


@app.callback()
def _root(
    debug: Annotated[
        bool, typer.Option("--debug", help="Log debug messages and show tracebacks of errors.")
    ] = False,
    version: Annotated[
        bool,
        typer.Option("--version", callback=_version, is_eager=True, help="Print the version."),
    ] = False,
) -> None:
    set_debug(debug)


def invoke(args: list[str]) -> int:
    """Run the command line ``args`` through typer and return its exit code.

    Usage errors (unknown option, bad value, missing argument) are reported here in one
    line; other errors go on to the caller (:func:`cnctwin.cli.run`), which reports them.
    """
    command = typer.main.get_command(app)
    try:
        result = command.main(args=args, prog_name="cnctwin", standalone_mode=False)
    except typer.Exit as done:
        return done.exit_code
    except typer.Abort:
        return fail("interrupted", EXIT_INTERRUPTED)
    except typer.TyperException as err:
        # A group called without a command has already printed its help.
        message = err.format_message()
        if not message:
            return EXIT_BAD_INPUT
        return fail(f"{message} (see --help)", EXIT_BAD_INPUT)
    return result if isinstance(result, int) else 0
