"""Plain invocations of ``cnctwin nc inspect`` and ``cnctwin nc trace``, read without typer.

typer's import and its option coercion (it builds a pydantic ``TypeAdapter`` per option) cost
about as much as reading 100,000 lines of moves, so the console script (:mod:`cnctwin.cli._entry`)
first asks :func:`plain_nc_command` whether the command line is one it can run directly.
It takes only what typer would take with the same values and nothing to report: the global
``--debug``; then ``nc inspect`` or ``nc trace``; one program path; ``--config``/``-c``, the
work guards within their ranges (a plain decimal integer) and ``--json`` (inspect) or
``--frame program|machine`` (trace), each at most once, as ``--name VALUE`` or
``--name=VALUE``. Anything else (``--help``, ``--plot``, a value out of range or not plain,
an option twice, ``--``, an empty path, a value starting with ``-``, an existing file that
cannot be read, shell completion) is left to typer, which reads it and reports its errors.
The options and their ranges are those declared in :mod:`cnctwin.cli.nc` (a test compares
them).
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from pathlib import Path

__all__ = ["PlainCommand", "plain_nc_command"]

#: Options that take a path, by the names they may be given.
_PATHS = {"--config": "--config", "-c": "--config"}
#: Flags (no value), per command.
_FLAGS = {"inspect": ("--json",), "trace": ()}
#: Options with a fixed set of values, per command.
_CHOICES: dict[str, dict[str, tuple[str, ...]]] = {
    "inspect": {},
    "trace": {"--frame": ("program", "machine")},
}
#: The work guards, both commands: their ranges are ``cnctwin.cli.nc_work.GUARD_LIMITS``.
_COUNTS = ("--max-segments", "--max-bytes", "--max-repeated-lines")
#: A count as typer reads it without doubt: decimal digits, no sign, no leading zero.
_PLAIN_COUNT = re.compile(r"0|[1-9][0-9]*")


@dataclass(frozen=True)
class PlainCommand:
    """A command line read without typer: the global ``--debug`` and the command to run."""

    debug: bool
    call: Callable[[], None]


def plain_nc_command(args: list[str]) -> PlainCommand | None:
    """The ``nc inspect``/``nc trace`` command of ``args``, or ``None`` if typer must read it.

    Parameters
    ----------
    args
        The command line after the program name.

    Returns
    -------
    PlainCommand or None
        The command, which runs as typer would run it, or ``None`` for a command line that is
        not such an invocation or not a plain one (see the module's description).
    """
    debug = args[:1] == ["--debug"]
    head = args[int(debug) : int(debug) + 2]
    if head not in (["nc", "inspect"], ["nc", "trace"]) or "_CNCTWIN_COMPLETE" in os.environ:
        return None
    command = head[1]
    given = _options(command, args[int(debug) + 2 :])
    if given is None:
        return None
    program = _path(given.pop("", ""))
    config = _path(given["--config"]) if "--config" in given else None
    if program is None or (config is None and "--config" in given):
        return None
    from cnctwin.cli.nc_work import GUARD_LIMITS, inspect_program, trace_program

    guards = []
    for name in _COUNTS:
        default, least, greatest = GUARD_LIMITS[name]
        text = given.get(name)
        if text is None:
            guards.append(default)
        elif _PLAIN_COUNT.fullmatch(text) and least <= int(text) <= greatest:
            guards.append(int(text))
        else:
            return None
    if command == "inspect":
        call = partial(inspect_program, program, config, "--json" in given, None, *guards)
    else:
        call = partial(trace_program, program, config, given.get("--frame", "program"), *guards)
    return PlainCommand(debug, call)


def _options(command: str, tokens: list[str]) -> dict[str, str] | None:
    """The options of ``tokens`` by their long names, the program under ``""``.

    ``None`` for anything but one program and known options, each given once, with values
    not starting with ``-`` and (choices) among the allowed ones.
    """
    flags, choices = _FLAGS[command], _CHOICES[command]
    given: dict[str, str] = {}
    rest = iter(tokens)
    for token in rest:
        if not token.startswith("-"):
            name, value = "", token
        else:
            # Only long options take "=VALUE": click reads "-c=x" as the value "=x".
            written, equals, value = token.partition("=") if token[1:2] == "-" else (token, "", "")
            name = _PATHS.get(written, written)
            if name in flags:
                if equals:
                    return None
            elif name in _PATHS or name in choices or name in _COUNTS:
                if not equals:
                    value = next(rest, "-")
                if value.startswith("-") or value not in choices.get(name, (value,)):
                    return None
            else:
                return None
        if name in given:
            return None
        given[name] = value
    return given


def _path(text: str) -> Path | None:
    """``text`` as typer reads a path: ``None`` where typer would refuse it or read it
    differently (empty, or a file that exists but cannot be read)."""
    if not text:
        return None
    try:
        os.stat(text)
    except OSError:
        return Path(text)
    return Path(text) if os.access(text, os.R_OK) else None
