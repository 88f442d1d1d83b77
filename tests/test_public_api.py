"""Each package's public API is the ``__all__`` of its ``__init__``, and nothing reaches past it.

The rule (docs/architecture.md, "Public API"): a module imports a name of another package from
the package itself (``from cnctwin.nc import Interpreter``), never from one of its modules
(``cnctwin.nc.interpreter``), and only a name the package lists in ``__all__``. Modules of one
package import one another freely; a module's own ``__all__`` says what it shares inside its
package. The top-level modules (``cnctwin.errors``, ``cnctwin.finite_json``, ``cnctwin.memory``)
are imported as modules, names from their ``__all__``. Tests may reach inside; the library, the
benchmarks and the Python examples in the docs may not.

In the manner of httpx's exported-members test, every package's ``__init__`` binds exactly the
names of its ``__all__`` (plus private names and helpers from outside cnctwin), and each exported
class and function says what it is in a docstring.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import pkgutil
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

import cnctwin
from cnctwin.nc.compiled import source_docstring

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "cnctwin"

#: The subpackages of cnctwin (``cnctwin.nc``, ...).
PACKAGES = sorted(m.name for m in pkgutil.iter_modules(cnctwin.__path__, "cnctwin.") if m.ispkg)
#: The top-level modules others import names from.
MODULES = ["cnctwin.errors", "cnctwin.finite_json", "cnctwin.memory"]


def _module_all(name: str) -> list[str]:
    return list(importlib.import_module(name).__all__)


# -- the exported members ---------------------------------------------------------------------


def _bound_in_init(path: Path) -> set[str]:
    """Public names an ``__init__`` binds from cnctwin or defines itself (``if TYPE_CHECKING``
    imports included: they are the names a lazy package hands out on first use)."""
    names: set[str] = set()

    def visit(body: list[ast.stmt]) -> None:
        for node in body:
            if isinstance(node, ast.ImportFrom):
                if node.level or (node.module or "").startswith("cnctwin"):
                    names.update(a.asname or a.name for a in node.names)
            elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                names.add(node.name)
            elif isinstance(node, ast.Assign):
                names.update(t.id for t in node.targets if isinstance(t, ast.Name))
            elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
                names.add(node.target.id)
            elif isinstance(node, ast.If):
                visit(node.body)
                visit(node.orelse)

    visit(ast.parse(path.read_text(encoding="utf-8")).body)
    return {n for n in names if not n.startswith("_")}


def test_every_package_is_listed() -> None:
    on_disk = sorted(f"cnctwin.{p.name}" for p in SRC.iterdir() if (p / "__init__.py").is_file())
    assert PACKAGES == on_disk
    assert "cnctwin.nc" in PACKAGES and "cnctwin.twin" in PACKAGES


@pytest.mark.parametrize("package", PACKAGES)
def test_the_package_binds_exactly_its_all(package: str) -> None:
    module = importlib.import_module(package)
    exported = getattr(module, "__all__", None)
    assert exported is not None, f"{package} has no __all__"
    assert len(set(exported)) == len(exported), f"{package}.__all__ lists a name twice"
    init = Path(module.__file__ or "")
    bound = _bound_in_init(init)
    assert bound - set(exported) == set(), f"{init}: public names missing from __all__"
    assert set(exported) - bound == set(), f"{init}: __all__ names it never binds"


def _own_docstring(obj: object) -> str | None:
    if inspect.isclass(obj):
        # A class's own, never a base's; on a compiled build of cnctwin.nc, read from its source
        # by a descriptor stored as __doc__ (cnctwin.nc.compiled.keep_docstring).
        doc = obj.__doc__
        # A dataclass without a docstring gets its signature as one.
        if doc and doc.startswith(f"{obj.__name__}("):
            return None
        return doc
    if inspect.isbuiltin(obj):  # compiled by mypyc, which drops docstrings: its source's
        return source_docstring(obj.__module__, obj.__name__)
    return inspect.getdoc(obj)


@pytest.mark.parametrize("package", PACKAGES + MODULES)
def test_every_exported_name_resolves_and_is_documented(package: str) -> None:
    module = importlib.import_module(package)
    assert module.__doc__, f"{package} has no docstring"
    undocumented = []
    for name in module.__all__:
        value = getattr(module, name)  # resolves the lazy ones too
        if (
            inspect.isclass(value) or inspect.isfunction(value) or inspect.isbuiltin(value)
        ) and not _own_docstring(value):
            undocumented.append(name)
    assert undocumented == [], f"{package}: exported without a docstring"


# -- nothing imports past an API ---------------------------------------------------------------


@dataclass(frozen=True)
class Violation:
    """One import past a package's API."""

    file: str
    line: int
    module: str
    name: str
    why: str

    def __str__(self) -> str:
        return f"{self.file}:{self.line}: {self.module} -> {self.name}: {self.why}"


def _top(module: str) -> str:
    """``cnctwin.nc`` for ``cnctwin.nc.interpreter``; ``cnctwin.errors`` for itself."""
    return ".".join(module.split(".")[:2])


def _owner(file: Path) -> str:
    """The package (or top-level module) a file of src/cnctwin belongs to; '' elsewhere."""
    try:
        parts = file.relative_to(SRC.parent).with_suffix("").parts
    except ValueError:
        return ""
    return ".".join(parts[:2]) if len(parts) > 1 else "cnctwin"


def _absolute(node: ast.ImportFrom, file: Path) -> str:
    if not node.level:
        return node.module or ""
    parts = list(file.relative_to(SRC.parent).with_suffix("").parts)
    base = parts[: len(parts) - node.level]
    return ".".join(base + ([node.module] if node.module else []))


def check_imports(tree: ast.AST, file: Path, shown: str) -> Iterator[Violation]:
    """Every import in ``tree`` that reaches past a package's API (the rule of this module)."""
    owner = _owner(file)
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                target = alias.name
                if target.startswith("cnctwin.") and target.count(".") >= 2:
                    if _top(target) != owner:
                        yield Violation(shown, node.lineno, target, "*", "a module, imported")
        elif isinstance(node, ast.ImportFrom):
            target = _absolute(node, file)
            if target != "cnctwin" and not target.startswith("cnctwin."):
                continue
            top = _top(target)
            if top == owner or top == "cnctwin.__main__":
                continue
            for alias in node.names:
                if target == "cnctwin":
                    continue  # a top-level module or __version__
                if target != top:
                    exported = top in PACKAGES and alias.name in _module_all(top)
                    why = f"import it from {top}" + (", which exports it" if exported else "")
                    yield Violation(shown, node.lineno, target, alias.name, why)
                elif alias.name not in _module_all(top):
                    yield Violation(shown, node.lineno, target, alias.name, f"not in {top}.__all__")


def _python_files() -> Iterator[Path]:
    yield from sorted(SRC.rglob("*.py"))
    yield from sorted((ROOT / "benchmarks").rglob("*.py"))


def _violations() -> list[Violation]:
    found = []
    for file in _python_files():
        tree = ast.parse(file.read_text(encoding="utf-8"), filename=str(file))
        found.extend(check_imports(tree, file, str(file.relative_to(ROOT))))
    return found


def test_no_module_imports_past_a_package_api() -> None:
    found = [str(v) for v in _violations()]
    assert found == [], (
        "imports past a package's __all__ (see docs/architecture.md):\n" + "\n".join(found)
    )


_FENCE = re.compile(r"^```python\n(.*?)^```", re.DOTALL | re.MULTILINE)
_IMPORT_LINE = re.compile(r"^(from cnctwin[\w.]* import [\w, ]+|import cnctwin[\w.]*)$")


def test_the_docs_python_examples_import_from_packages() -> None:
    found = []
    for doc in sorted((ROOT / "docs").glob("*.md")) + [ROOT / "README.md"]:
        for block in _FENCE.findall(doc.read_text(encoding="utf-8")):
            try:
                tree = ast.parse(block)
            except SyntaxError:  # a sketch, not a program: check its one-line imports
                lines = [line for line in block.splitlines() if _IMPORT_LINE.match(line)]
                tree = ast.parse("\n".join(lines))
            found.extend(check_imports(tree, ROOT / "docs" / doc.name, doc.name))
    assert [str(v) for v in found] == [], "doc examples importing past a package's __all__:\n" + (
        "\n".join(str(v) for v in found)
    )


# -- the checker itself catches what it should ---------------------------------------------------


def _check(code: str, file: str) -> list[str]:
    return [v.why for v in check_imports(ast.parse(code), SRC / file, file)]


def test_checker_flags_a_submodule_import_from_another_package() -> None:
    assert _check("from cnctwin.nc.interpreter import Interpreter\n", "twin/program.py") == [
        "import it from cnctwin.nc, which exports it"
    ]
    assert _check("import cnctwin.geometry.dexel\n", "twin/program.py") == ["a module, imported"]


def test_checker_flags_a_private_module_and_a_name_past_all() -> None:
    assert _check("from cnctwin.geometry._dexel_kernels import x\n", "nc/sampler.py") == [
        "import it from cnctwin.geometry"
    ]
    assert _check("from cnctwin.nc import ModalState\n", "geometry/dexel.py") == [
        "not in cnctwin.nc.__all__"
    ]


def test_checker_lets_a_package_import_its_own_modules() -> None:
    assert _check("from cnctwin.nc.lexer import lex_block\n", "nc/interpreter.py") == []
    assert _check("from .lexer import lex_block\n", "nc/interpreter.py") == []
    assert _check("from cnctwin.nc import Interpreter\n", "twin/program.py") == []
    assert _check("from cnctwin import finite_json\n", "twin/program.py") == []
