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
    if os.environ.get("CNCTWIN_COMPILE", "") in ("", "0"):
        return []
    compiled = _compiled()
    reason = compiled.cannot_compile()
    if reason is not None:
        sys.exit(f"CNCTWIN_COMPILE=1: {reason}; install it, or install without CNCTWIN_COMPILE")
    from mypyc.build import mypycify

    modules = [f"src/cnctwin/nc/{name}.py" for name in compiled.COMPILED_MODULES]
    return list(mypycify(modules, opt_level="3"))


setup(ext_modules=_extensions())
