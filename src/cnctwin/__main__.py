"""``python -m cnctwin``: the same as the ``cnctwin`` command."""

from cnctwin.cli import main

main()
