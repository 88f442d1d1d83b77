"""``cnctwin vibration``: milling vibration over time (issue 5's name for the time-domain model).

``vibration simulate`` is ``chatter simulate`` (:mod:`cnctwin.cli.chatter`, docs/chatter.md):
the same options, output and errors under the name the issue gives it.
"""

from __future__ import annotations

import typer

from cnctwin.cli import chatter

__all__ = ["app"]

app = typer.Typer(help="Milling vibration over time (time-domain model).", no_args_is_help=True)


@app.callback()
def _vibration() -> None:
    """Milling vibration over time (time-domain model)."""


app.command("simulate")(chatter.simulate)
