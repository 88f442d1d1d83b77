"""Build hook: compiles the NC interpreter's per-line modules to C extensions with mypyc.

Everything else about the package is declared in pyproject.toml. ``CNCTWIN_COMPILE`` at
install chooses the build: unset or empty, the modules that
``cnctwin.nc.compiled.COMPILED_MODULES`` lists are compiled where a C compiler and Python's
headers exist, else installed as Python (one line on stderr says why); ``1`` compiles them or
fails; ``0`` never compiles (docs/nc.md, "Compiled with mypyc"; figures in docs/benchmarks.md).
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import os
import sys
from pathlib import Path
from types import ModuleType

from setuptools import setup

HERE = Path(__file__).resolve().parent


def _compiled() -> ModuleType:
    """``cnctwin.nc.compiled``, read without importing the package (whose dependencies the
    build does not have)."""
    path = HERE / "src" / "cnctwin" / "nc" / "compiled.py"
    spec = importlib.util.spec_from_file_location("_cnctwin_compiled", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _extensions() -> list[object]:
    choice = os.environ.get("CNCTWIN_COMPILE", "")
    if choice not in ("", "0", "1"):
        sys.exit(
            f"CNCTWIN_COMPILE={choice!r} is not a choice: 1 (compile), 0 (do not compile) or "
            "unset (compile where a C compiler and Python's headers exist)"
        )
    if choice == "0":
        _remove_compiled()
        return []
    compiled = _compiled()
    reason = compiled.cannot_compile()
    if reason is not None:
        if choice == "1":
            sys.exit(f"CNCTWIN_COMPILE=1: {reason}; install it, or install with CNCTWIN_COMPILE=0")
        print(
            f"cnctwin: the NC interpreter is not compiled ({reason}); it runs as Python",
            file=sys.stderr,
        )
        _remove_compiled()
        return []
    from mypyc.build import mypycify

    modules = [f"src/cnctwin/nc/{name}.py" for name in compiled.COMPILED_MODULES]
    return list(mypycify(modules, opt_level="3"))


def _remove_compiled() -> None:
    """Delete the modules an earlier compiled editable install left in the sources: Python
    would import them before the sources."""
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        for stale in [*HERE.glob(f"src/cnctwin/nc/*{suffix}"), *HERE.glob(f"src/*__mypyc{suffix}")]:
            stale.unlink()


setup(ext_modules=_extensions())
