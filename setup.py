"""Build hook: with ``CNCTWIN_COMPILE=1``, the NC interpreter's per-line modules are compiled
to C extensions with mypyc.

Everything else about the package is declared in pyproject.toml. An ordinary install compiles
nothing. ``CNCTWIN_COMPILE=1 pip install -e .`` compiles the modules that
``cnctwin.nc.compiled.COMPILED_MODULES`` lists, from the same typed sources (docs/nc.md,
"Compiled with mypyc"; figures in docs/benchmarks.md).
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import sys
import sysconfig
from pathlib import Path

from setuptools import setup

HERE = Path(__file__).resolve().parent


def _compiled_modules() -> list[str]:
    """The source files to compile, from ``cnctwin.nc.compiled`` (read without importing
    the package, whose dependencies the build does not have)."""
    path = HERE / "src" / "cnctwin" / "nc" / "compiled.py"
    spec = importlib.util.spec_from_file_location("_cnctwin_compiled", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return [f"src/cnctwin/nc/{name}.py" for name in module.COMPILED_MODULES]


def _cannot_compile() -> str | None:
    """Why this machine cannot compile the modules (no C compiler, no Python headers), or
    ``None``."""
    compiler = (sysconfig.get_config_var("CC") or "cc").split()[0]
    if shutil.which(compiler) is None:
        return f"no C compiler ({compiler})"
    headers = Path(sysconfig.get_paths()["include"], "Python.h")
    if not headers.is_file():
        return f"no Python headers ({headers}; Debian: python3-dev)"
    return None


def _extensions() -> list[object]:
    if os.environ.get("CNCTWIN_COMPILE", "") in ("", "0"):
        return []
    reason = _cannot_compile()
    if reason is not None:
        sys.exit(f"CNCTWIN_COMPILE=1: {reason}; install it, or install without CNCTWIN_COMPILE")
    from mypyc.build import mypycify

    return list(mypycify(_compiled_modules(), opt_level="3"))


setup(ext_modules=_extensions())
