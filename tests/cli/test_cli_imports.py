"""The command line is a leaf: nothing outside it imports :mod:`cnctwin.cli`.

The library (every package of ``src/cnctwin``), the tests of the library, the benchmarks and
the documentation's code use the library's own modules; only the command line itself
(``src/cnctwin/cli``), its tests (``tests/cli``) and ``python -m cnctwin``
(``src/cnctwin/__main__.py``) import ``cnctwin.cli``. The sources are parsed (AST), so an
import inside a function, under ``TYPE_CHECKING`` or through :func:`importlib.import_module`
counts as well.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: Where ``cnctwin.cli`` may be imported, relative to the repository.
ALLOWED = ("src/cnctwin/cli/", "tests/cli/", "src/cnctwin/__main__.py")
#: The trees scanned: Python sources, and the Python blocks of the Markdown documents.
PYTHON_TREES = ("src", "tests", "benchmarks", "examples", "scripts")
MARKDOWN = ("docs", "README.md", "examples")
_FENCE = re.compile(r"^```(?:python|py|pycon)\s*\n(.*?)^```", re.MULTILINE | re.DOTALL)


def _is_cli(module: str) -> bool:
    return module == "cnctwin.cli" or module.startswith("cnctwin.cli.")


def cli_imports(source: str) -> list[int]:
    """Line numbers of the imports of ``cnctwin.cli`` (or a module in it) in ``source``."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            if any(_is_cli(alias.name) for alias in node.names):
                found.append(node.lineno)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            if _is_cli(node.module) or (
                node.module == "cnctwin" and any(alias.name == "cli" for alias in node.names)
            ):
                found.append(node.lineno)
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Name | ast.Attribute)
            and (node.func.id if isinstance(node.func, ast.Name) else node.func.attr)
            in ("import_module", "__import__")
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and isinstance(node.args[0].value, str)
            and _is_cli(node.args[0].value)
        ):
            found.append(node.lineno)
    return sorted(found)


def _allowed(relative: str) -> bool:
    return relative.startswith(ALLOWED[:2]) or relative == ALLOWED[2]


def _python_files() -> list[Path]:
    files = []
    for tree in PYTHON_TREES:
        base = ROOT / tree
        if base.is_dir():
            files += [path for path in base.rglob("*.py") if "__pycache__" not in path.parts]
    return sorted(files)


def _markdown_files() -> list[Path]:
    files = []
    for name in MARKDOWN:
        path = ROOT / name
        files += sorted(path.rglob("*.md")) if path.is_dir() else [path] if path.exists() else []
    return files


@pytest.mark.parametrize(
    ("source", "lines"),
    [
        ("from cnctwin.cli.simulate import simulate_report\n", [1]),
        ("import cnctwin.cli\n", [1]),
        ("x = 1\nfrom cnctwin import cli, config\n", [2]),
        ("def f():\n    from cnctwin.cli.app import run\n", [2]),
        ("import importlib\nimportlib.import_module('cnctwin.cli.bench')\n", [2]),
        ("from cnctwin.client import x\nimport cnctwin.config\nfrom . import cli\n", []),
    ],
)
def test_the_scanner_finds_every_form_of_import(source: str, lines: list[int]) -> None:
    assert cli_imports(source) == lines


def test_no_module_outside_the_command_line_imports_it() -> None:
    files = _python_files()
    assert any(p.relative_to(ROOT).as_posix() == "src/cnctwin/__main__.py" for p in files)
    offenders = []
    for path in files:
        relative = path.relative_to(ROOT).as_posix()
        if _allowed(relative):
            continue
        offenders += [f"{relative}:{line}" for line in cli_imports(path.read_text("utf-8"))]
    assert offenders == [], "import cnctwin.cli outside the command line: " + ", ".join(offenders)


def test_no_document_imports_it_in_its_python() -> None:
    offenders = []
    for path in _markdown_files():
        text = path.read_text("utf-8")
        for block in _FENCE.finditer(text):
            try:
                lines = cli_imports(block.group(1))
            except SyntaxError:  # a session transcript or a fragment: read its import lines
                lines = [
                    i
                    for i, line in enumerate(block.group(1).splitlines(), start=1)
                    if re.match(r"\s*(from|import)\s+cnctwin(\.cli\b|\s+import\s+cli\b)", line)
                ]
            start = text.count("\n", 0, block.start(1))
            offenders += [f"{path.relative_to(ROOT)}:{start + line}" for line in lines]
    assert offenders == [], "import cnctwin.cli in the documentation: " + ", ".join(offenders)
