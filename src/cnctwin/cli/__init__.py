"""The ``cnctwin`` command line (typer + rich): one module per command group.

``main()`` is the console script; ``run(argv)`` does the same and returns the exit code.
"""

from cnctwin.cli.app import app, main, run

__all__ = ["app", "main", "run"]
