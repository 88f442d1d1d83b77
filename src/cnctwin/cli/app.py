"""The ``cnctwin`` command: the root of the command groups, global options and error reporting.

Errors reach the user as one line on stderr and an exit code: 2 for bad input (any
:class:`~cnctwin.errors.CnctwinError`, a file that cannot be read), 1 for a bug
("internal error", with the traceback under ``--debug``), 130 on Ctrl-C.
"""

from __future__ import annotations

import logging
import sys
import traceback
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Annotated

import typer

from cnctwin import __version__
from cnctwin.cli import (
    bench,
    chatter,
    demo,
    dynamics,
    forces,
    modal,
    nc,
    roadmap,
    roughness,
    runs,
    signals,
    simulate,
    stability,
    study,
    vibration,
    virtual,
    wear,
    wear_ekf,
    wear_registry,
)
from cnctwin.cli import run as run_cli
from cnctwin.errors import CnctwinError

__all__ = ["app", "main", "run"]

EXIT_BAD_INPUT = 2
EXIT_INTERNAL = 1
EXIT_INTERRUPTED = 130

app = typer.Typer(
    name="cnctwin",
    help="cnctwin: a digital twin for CNC machining.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    # Plain help text: option help and docstrings name TOML tables such as [lobes] and
    # [[modes]], which rich markup would swallow.
    rich_markup_mode=None,
)
app.add_typer(nc.app, name="nc")
bench.app.command("latency")(bench.latency)
app.add_typer(bench.app, name="bench")
wear.app.command("ekf")(wear_ekf.ekf)
for _name in ("mount", "compensate", "retire", "history"):
    wear.app.command(_name)(getattr(wear_registry, _name))
app.add_typer(wear.app, name="wear")
app.add_typer(study.app, name="study")
app.add_typer(roughness.app, name="roughness")
app.add_typer(dynamics.app, name="dynamics")
stability.app.command("roadmap")(roadmap.roadmap)
app.add_typer(stability.app, name="stability")
app.add_typer(chatter.app, name="chatter")
app.add_typer(vibration.app, name="vibration")
app.add_typer(modal.app, name="modal")
app.add_typer(runs.app, name="runs")
app.add_typer(virtual.app, name="virtual")
app.command("demo")(demo.demo)
app.command("run")(run_cli.run)
app.command("forces")(forces.forces)
app.command("simulate")(simulate.simulate)
app.command("signals")(signals.signals)


@dataclass
class _Options:
    """Global options of the current invocation."""

    debug: bool = False


_options = _Options()


def _version(value: bool) -> None:
    if value:
        typer.echo(f"cnctwin {__version__}")
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
    _options.debug = debug
    logging.getLogger("cnctwin").setLevel(logging.DEBUG if debug else logging.WARNING)


def run(argv: Sequence[str] | None = None) -> int:
    """Run the command line and return its exit code instead of exiting.

    Parameters
    ----------
    argv
        Arguments after the program name; ``None`` takes ``sys.argv[1:]``.

    Returns
    -------
    int
        0 on success, 2 for bad input, 1 for an internal error, 130 when interrupted.
    """
    _options.debug = False
    logging.basicConfig(format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr)
    command = typer.main.get_command(app)
    try:
        result = command.main(
            args=list(sys.argv[1:] if argv is None else argv),
            prog_name="cnctwin",
            standalone_mode=False,
        )
    except SystemExit as done:
        return done.code if isinstance(done.code, int) else int(done.code is not None)
    except typer.Exit as done:
        return done.exit_code
    except typer.Abort:
        return _fail("interrupted", EXIT_INTERRUPTED)
    except typer.TyperException as err:
        # Usage errors (unknown option, bad value, missing argument) in one line; a group
        # called without a command has already printed its help.
        message = err.format_message()
        if not message:
            return EXIT_BAD_INPUT
        return _fail(f"{message} (see --help)", EXIT_BAD_INPUT)
    except CnctwinError as err:
        return _fail(str(err), EXIT_BAD_INPUT)
    except OSError as err:
        where = f"{err.filename}: " if err.filename else ""
        return _fail(f"{where}{err.strerror or err}", EXIT_BAD_INPUT)
    except KeyboardInterrupt:
        return _fail("interrupted", EXIT_INTERRUPTED)
    except Exception as err:  # the last resort: report in one line, never a bare traceback
        return _fail(
            f"internal error: {type(err).__name__}: {err} (re-run with --debug for the traceback)",
            EXIT_INTERNAL,
        )
    return result if isinstance(result, int) else 0


def main() -> None:
    """Entry point of the ``cnctwin`` console script."""
    sys.exit(run())


def _fail(message: str, code: int) -> int:
    if _options.debug:
        traceback.print_exc(file=sys.stderr)
    sys.stderr.write(" ".join(message.splitlines()) + "\n")
    sys.stderr.flush()
    return code
