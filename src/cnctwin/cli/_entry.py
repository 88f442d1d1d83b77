"""The ``cnctwin`` console script: dispatch and error reporting, without typer.

Errors reach the user as one line on stderr and an exit code: 2 for bad input (any
:class:`~cnctwin.errors.CnctwinError`, a file that cannot be read), 1 for a bug
("internal error", with the traceback under ``--debug``), 130 on Ctrl-C.

Plain invocations of ``cnctwin nc inspect`` and ``cnctwin nc trace`` (:mod:`cnctwin.cli.nc_argv`)
run without importing typer: its import and its option coercion (pydantic) cost more than
reading a short program. Every other invocation, and any of these that the plain reader does
not take (help, a wrong value, an option it does not know), goes through the typer root
(:mod:`cnctwin.cli.app`), which gives the same results for what both read.
"""

from __future__ import annotations

import errno
import logging
import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from cnctwin.errors import CnctwinError

__all__ = ["EXIT_BAD_INPUT", "EXIT_INTERNAL", "EXIT_INTERRUPTED", "fail", "main", "options", "run"]

EXIT_BAD_INPUT = 2
EXIT_INTERNAL = 1
EXIT_INTERRUPTED = 130


@dataclass
class _Options:
    """Global options of the current invocation."""

    debug: bool = False


#: The global options of the current invocation (``--debug``), set by the root command.
options = _Options()


def set_debug(debug: bool) -> None:
    """Apply ``--debug``: tracebacks of errors and the ``cnctwin`` loggers' debug messages."""
    options.debug = debug
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
    options.debug = False
    logging.basicConfig(format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr)
    args = list(sys.argv[1:] if argv is None else argv)
    try:
        from cnctwin.cli.nc_argv import plain_nc_command

        plain = plain_nc_command(args)
        if plain is None:
            from cnctwin.cli.app import invoke

            return invoke(args)
        set_debug(plain.debug)
        return _command(plain.call)
    except SystemExit as done:
        return done.code if isinstance(done.code, int) else int(done.code is not None)
    except CnctwinError as err:
        return fail(str(err), EXIT_BAD_INPUT)
    except OSError as err:
        where = f"{err.filename}: " if err.filename else ""
        return fail(f"{where}{err.strerror or err}", EXIT_BAD_INPUT)
    except KeyboardInterrupt:
        return fail("interrupted", EXIT_INTERRUPTED)
    except Exception as err:  # the last resort: report in one line, never a bare traceback
        return fail(
            f"internal error: {type(err).__name__}: {err} (re-run with --debug for the traceback)",
            EXIT_INTERNAL,
        )


def _command(call: Callable[[], None]) -> int:
    """Run a command read without typer, ending as one that typer runs would.

    Ctrl-C ends it with 130 and no message, end of input (EOFError) as "interrupted" after
    an empty line, a closed output pipe with 1 and nothing more (its final flush is
    silenced); any other error goes on to :func:`run`.
    """
    try:
        call()
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED
    except EOFError:
        sys.stderr.write("\n")
        sys.stderr.flush()
        return fail("interrupted", EXIT_INTERRUPTED)
    except OSError as err:
        if err.errno != errno.EPIPE:
            raise
        # The interpreter flushes stdout at exit; to a closed pipe that raises again.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_INTERNAL
    return 0


def main() -> None:
    """Entry point of the ``cnctwin`` console script."""
    sys.unraisablehook = _unraisable
    sys.exit(run())


def _unraisable(unraisable: Any) -> None:
    """Python's report of an exception it cannot raise, but for Ctrl-C.

    Ctrl-C that lands in a C callback (numba compiling a kernel) is such an exception; Python
    would print it as a traceback ("Exception ignored ..."). The interrupt itself is not lost:
    the command ends with exit code 130 as for any Ctrl-C.
    """
    if isinstance(unraisable.exc_value, KeyboardInterrupt):
        return
    sys.__unraisablehook__(unraisable)


def fail(message: str, code: int) -> int:
    """Report ``message`` as one line on stderr (after the traceback under ``--debug``).

    Returns
    -------
    int
        ``code``, the exit code to end with.
    """
    if options.debug:
        import traceback

        traceback.print_exc(file=sys.stderr)
    sys.stderr.write(" ".join(message.splitlines()) + "\n")
    sys.stderr.flush()
    return code
