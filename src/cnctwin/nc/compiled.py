"""Which modules of :mod:`cnctwin.nc` run compiled, the switch back to their sources, and a
guard against stale compiled modules.

Installed with ``CNCTWIN_COMPILE=1``, ``setup.py`` compiles the interpreter's per-line
modules with mypyc. Each compiled module is a C extension next to its source, and Python
imports the extension first. Two things follow, both handled by :func:`prepare_imports` when
:mod:`cnctwin.nc` is imported:

- with ``CNCTWIN_PURE_PYTHON=1`` set at run time, the sources are imported instead (for
  debugging, profiling with :mod:`cProfile`, or comparing the two);
- in an editable install the sources can change without the extensions: an extension
  older than its source is refused rather than run.

This module itself is never compiled (it reads the file system; the others do not).
"""

from __future__ import annotations

import importlib.machinery
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType

#: The environment variable that asks for the sources at run time: compiled modules are not
#: imported. Any value but "" and "0".
PURE_PYTHON_VARIABLE = "CNCTWIN_PURE_PYTHON"

#: The modules ``CNCTWIN_COMPILE=1`` compiles (setup.py reads this list): the interpreter's
#: per-line path of reading lines, words and expressions, O-word control, executing blocks,
#: modes, motion and the summary. Not compiled: ``runs`` (numpy does its work), the numba
#: kernels, plotting, sampling, the tool table (read once) and this module.
COMPILED_MODULES = (
    "arcs",
    "blocks",
    "canned_cycles",
    "cursor",
    "cutter_comp",
    "executor",
    "expressions",
    "interpreter",
    "lexer",
    "limits",
    "modal",
    "motion",
    "offsets",
    "owords",
    "segments",
    "source",
    "summary",
    "tool_state",
    "trace",
)

_HERE = Path(__file__).resolve().parent


def pure_python_requested() -> bool:
    """Whether ``CNCTWIN_PURE_PYTHON`` asks for the sources."""
    return os.environ.get(PURE_PYTHON_VARIABLE, "") not in ("", "0")


def _compiled_pairs(folder: Path) -> list[tuple[Path, Path]]:
    """(source, extension) of each module in ``folder`` that has both, by name."""
    names = {entry.name for entry in os.scandir(folder)}
    pairs: list[tuple[Path, Path]] = []
    for name in sorted(names):
        if name.endswith(".py"):
            for suffix in importlib.machinery.EXTENSION_SUFFIXES:
                if name[:-3] + suffix in names:
                    pairs.append((folder / name, folder / (name[:-3] + suffix)))
                    break
    return pairs


def cannot_compile() -> str | None:
    """Why this Python cannot compile :data:`COMPILED_MODULES` (no C compiler, no Python
    headers), or ``None``. Called at install and by tests only: its imports stay out of
    every import of :mod:`cnctwin.nc` (shutil costs 5 ms)."""
    import shutil
    import sysconfig

    compiler = (sysconfig.get_config_var("CC") or "cc").split()[0]
    if shutil.which(compiler) is None:
        return f"no C compiler ({compiler})"
    headers = Path(sysconfig.get_paths()["include"], "Python.h")
    if not headers.is_file():
        return f"no Python headers ({headers}; Debian: python3-dev)"
    return None


def compiled_modules() -> list[str]:
    """Names (``cnctwin.nc.lexer``, ...) of the modules that are imported compiled in this
    process, sorted; empty for an ordinary install or with ``CNCTWIN_PURE_PYTHON=1``."""
    if pure_python_requested():
        return []
    return [f"{__package__}.{source.stem}" for source, _ in _compiled_pairs(_HERE)]


class _SourceFinder:
    """Finds this package's modules as their ``.py`` sources, never as extensions (a meta
    path finder; not derived from ``importlib.abc``, whose import costs 25 ms)."""

    def find_spec(
        self,
        fullname: str,
        path: Sequence[str] | None,
        target: ModuleType | None = None,
    ) -> importlib.machinery.ModuleSpec | None:
        package, _, name = fullname.rpartition(".")
        source = _HERE / f"{name}.py"
        if package != __package__ or not source.is_file():
            return None
        loader = importlib.machinery.SourceFileLoader(fullname, str(source))
        spec = importlib.machinery.ModuleSpec(fullname, loader, origin=str(source))
        spec.has_location = True  # sets the module's __file__
        return spec


def check_compiled_are_current(folder: Path = _HERE) -> None:
    """Refuse compiled modules in ``folder`` (this package's) older than their sources.

    Raises
    ------
    ImportError
        Naming the first such module and how to compile it again or run the sources.
    """
    for source, extension in _compiled_pairs(folder):
        if source.stat().st_mtime > extension.stat().st_mtime:
            raise ImportError(
                f"{extension} is older than {source.name}, which changed since it was "
                "compiled: install again with CNCTWIN_COMPILE=1 (pip install -e .) to compile it "
                f"again, delete the compiled modules ({folder}/*.so) to run the sources, or set "
                f"{PURE_PYTHON_VARIABLE}=1 to run them this time"
            )


def prepare_imports() -> None:
    """Before any module of :mod:`cnctwin.nc` is imported: the sources with
    ``CNCTWIN_PURE_PYTHON=1``, else refuse stale compiled modules (see the module's text).

    Raises
    ------
    ImportError
        From :func:`check_compiled_are_current`.
    """
    if pure_python_requested():
        if not any(isinstance(finder, _SourceFinder) for finder in sys.meta_path):
            sys.meta_path.insert(0, _SourceFinder())
        return
    check_compiled_are_current()
