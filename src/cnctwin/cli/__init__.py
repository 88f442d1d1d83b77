"""The ``cnctwin`` command line (typer + rich): one module per command group.

``main()`` is the console script; ``run(argv)`` does the same and returns the exit code;
``app`` is the typer root (:mod:`cnctwin.cli.app`), imported on first use: plain
``nc inspect`` and ``nc trace`` invocations run without typer (:mod:`cnctwin.cli._entry`).
"""

import sys
from types import ModuleType
from typing import TYPE_CHECKING, Any

from cnctwin import _lazy
from cnctwin.cli._entry import main, run

if TYPE_CHECKING:
    from cnctwin.cli.app import app

__all__ = ["app", "main", "run"]

__getattr__, __dir__ = _lazy.exports(__name__, {"app": "app"})


class _Package(ModuleType):
    """This package: its submodules ``app`` and ``run`` do not hide the names it exports.

    Python binds a submodule on its package once imported, so ``import cnctwin.cli.run``
    (the ``run`` command's module) would replace the function ``cnctwin.cli.run``.
    """

    def __setattr__(self, name: str, value: Any) -> None:
        if name in __all__ and isinstance(value, ModuleType):
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
