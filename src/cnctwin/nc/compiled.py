"""Which modules of :mod:`cnctwin.nc` run compiled, the switch back to their sources, the
guard against stale compiled modules, and the compiled classes' docstrings.

An install compiles the interpreter's per-line modules with mypyc where it can (setup.py;
``CNCTWIN_COMPILE=0`` opts out). Each compiled module is a C extension next to its source, and
Python imports the extension first. Two things follow, both handled by
:func:`prepare_imports` when :mod:`cnctwin.nc` is imported:

- with ``CNCTWIN_PURE_PYTHON=1`` set at run time, the sources are imported instead (for
  debugging, profiling with :mod:`cProfile`, or comparing the two);
- in an editable install the sources can change without the extensions: when an extension
  is older than its source, all of :mod:`cnctwin.nc` runs from its sources, with a
  ``RuntimeWarning`` (not only the changed module: compiled modules call one another
  natively, past any module imported as Python).

mypyc drops docstrings; :func:`keep_docstring` gives an exported class its docstring back.
This module itself is never compiled (it reads the file system; the others do not).
"""

from __future__ import annotations

import importlib.machinery
import os
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType

#: The environment variable that asks for the sources at run time: compiled modules are not
#: imported. Any value but "" and "0".
PURE_PYTHON_VARIABLE = "CNCTWIN_PURE_PYTHON"

#: The modules an install compiles (setup.py reads this list): the interpreter's
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
    process, sorted; empty for a pure Python install, with ``CNCTWIN_PURE_PYTHON=1`` and
    with stale compiled modules (:func:`prepare_imports`)."""
    if _sources_imported():
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


def _sources_imported() -> bool:
    return any(isinstance(finder, _SourceFinder) for finder in sys.meta_path)


def first_stale(folder: Path = _HERE) -> tuple[Path, Path] | None:
    """(source, extension) of the first compiled module in ``folder`` (this package's) that
    is older than its source, or ``None``."""
    for source, extension in _compiled_pairs(folder):
        if source.stat().st_mtime > extension.stat().st_mtime:
            return source, extension
    return None


def prepare_imports() -> None:
    """Before any module of :mod:`cnctwin.nc` is imported: the sources with
    ``CNCTWIN_PURE_PYTHON=1`` or when a compiled module is stale (then with a
    ``RuntimeWarning`` that names it), else the compiled modules (see the module's text)."""
    if not pure_python_requested():
        stale = first_stale()
        if stale is None:
            return
        source, extension = stale
        warnings.warn(
            f"{__package__}.{source.stem} changed since it was compiled ({extension.name} is "
            f"older than {source.name}): all of {__package__} runs as Python; install again "
            "(pip install -e .) to compile it again",
            RuntimeWarning,
            stacklevel=2,
        )
    if not _sources_imported():
        sys.meta_path.insert(0, _SourceFinder())


def source_docstring(module: str, name: str) -> str | None:
    """The docstring of the class or function ``name`` defined in ``module`` (a module of this
    package), read from its source with :mod:`ast`: what a compiled module no longer
    carries."""
    import ast  # only when a docstring is asked for: 5 ms

    source = _HERE / f"{module.rpartition('.')[2]}.py"
    for node in ast.parse(source.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.ClassDef | ast.FunctionDef) and node.name == name:
            return ast.get_docstring(node, clean=False)
    return None


class _SourceDocstring:
    """A compiled class's ``__doc__``: :func:`source_docstring`, read when first asked.
    ``type.__doc__`` calls ``__get__`` of a descriptor stored as ``__doc__`` (as does an
    instance's ``__doc__``)."""

    def __init__(self, module: str, name: str) -> None:
        self._module = module
        self._name = name
        self._doc: str | None = None
        self._read = False

    def __get__(self, instance: object, owner: type | None = None) -> str | None:
        if not self._read:
            self._doc = source_docstring(self._module, self._name)
            self._read = True
        return self._doc


def keep_docstring(value: object) -> None:
    """Give ``value``, when it is a class of a compiled module of this package, its docstring
    back, read from its source when first asked (``help()``, :func:`inspect.getdoc`). mypyc
    drops docstrings; a compiled function's (or method's) cannot be set."""
    if not isinstance(value, type) or not value.__module__.startswith(f"{__package__}."):
        return
    if not (sys.modules[value.__module__].__file__ or "").endswith(".py"):
        value.__doc__ = _SourceDocstring(value.__module__, value.__name__)  # type: ignore[assignment]
