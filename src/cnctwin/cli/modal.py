"""``cnctwin modal``: modal parameters from a tap test; ``modal fit`` is ``dynamics fit-frf``.

The same options, output and errors as ``cnctwin dynamics fit-frf``
(:mod:`cnctwin.cli.dynamics`, docs/dynamics-frf.md), under the name issue 5 gives it.
"""

from __future__ import annotations

import typer

from cnctwin.cli import dynamics

__all__ = ["app"]

app = typer.Typer(help="Modal parameters from tap tests.", no_args_is_help=True)


@app.callback()
def _modal() -> None:
    """Modal parameters from tap tests."""


app.command("fit")(dynamics.fit_frf)
