"""Names a package exports but imports on first use (PEP 562 module ``__getattr__``).

A package whose public names pull in heavy libraries (numpy, asyncua, FastAPI, scikit-learn)
lists where each lives and binds the two module hooks this returns::

    if TYPE_CHECKING:  # the names as type checkers see them
        from cnctwin.web.server import LiveDashboard

    _LAZY = {"LiveDashboard": "server"}
    __getattr__, __dir__ = _lazy.exports(__name__, _LAZY)

Importing the package then imports none of those modules; the first access of a name does,
and binds the name in the package so that later accesses are plain attribute look-ups.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["exports"]


def exports(
    package: str, homes: Mapping[str, str]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of a package with lazily imported names.

    Parameters
    ----------
    package
        The package's ``__name__`` (``"cnctwin.nc"``).
    homes
        Public name -> the package's submodule that defines it, relative (``"sampler"`` for
        ``cnctwin.nc.sampler``).

    Returns
    -------
    tuple
        ``__getattr__(name)``, which imports the name's submodule, binds the name in the
        package and returns it (AttributeError for a name not in ``homes``), and
        ``__dir__()``, the package's names with the lazy ones.
    """

    def __getattr__(name: str) -> Any:
        home = homes.get(name)
        if home is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f"{package}.{home}"), name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:
        return sorted({*vars(sys.modules[package]), *homes})

    return __getattr__, __dir__
