"""The NC interpreter compiled with mypyc (an install's default) gives what its sources give.

The compiled modules are those of the installed build when it is compiled; on a pure Python
install the modules ``COMPILED_MODULES`` lists are compiled once, with mypyc, in a copy of the
package (about two minutes of one core; skipped without a C compiler and Python's headers,
failed in CI). The reference is the same modules run as Python (``CNCTWIN_PURE_PYTHON=1``):
two child processes interpret the same programs (the 45 real programs of ../shared/data/gcode,
one of expressions and O-word loops, an erroring one), one on the compiled modules and one on
the sources, and their segments (floats by ``repr``), warnings, summaries and errors must be
identical. Also checked: the switch to the sources at run time, ``cnctwin --version``, the
exported classes' docstrings, and that a compiled module older than its source makes all of
:mod:`cnctwin.nc` run from its sources, with a warning.
"""

from __future__ import annotations

import dataclasses
import importlib.machinery
import inspect
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from skips import missing, on_sources

import cnctwin
from cnctwin.nc import compiled_modules
from cnctwin.nc.compiled import (
    COMPILED_MODULES,
    PURE_PYTHON_VARIABLE,
    cannot_compile,
    first_stale,
)
from cnctwin.nc.lexer import Block, OWord
from cnctwin.nc.segments import MachineState, MotionKind, Segment

REPO = Path(__file__).resolve().parents[2]

# A child interprets every program on its command line; it prints which modules it runs
# compiled, then one JSON object per program: segments and summary by repr, warnings, or the
# error.
CHILD = r"""
import dataclasses, json, sys
from cnctwin.errors import NCError
from cnctwin.nc import Interpreter, NCSetup, ToolEntry, compiled_modules, summarize

def described(value):
    if dataclasses.is_dataclass(value):
        return [described(getattr(value, f.name)) for f in dataclasses.fields(value)]
    if isinstance(value, (list, tuple)):
        return [described(v) for v in value]
    return repr(value)

print(json.dumps(compiled_modules()))
setup = NCSetup(tools={1: ToolEntry(number=1, diameter_mm=6.0, length_mm=50.0)})
for path in sys.argv[1:]:
    interp = Interpreter(setup)
    try:
        segments = list(interp.run_file(path))
        result = {
            "segments": described(segments),
            "summary": described(summarize(segments, rapid_mm_min=10000.0)),
            "warnings": described(interp.warnings),
        }
    except NCError as error:
        result = {"error": str(error)}
    print(json.dumps(result))
"""


@pytest.fixture(scope="module")
def compiled_tree(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The folder holding a ``cnctwin`` whose compiled modules are imported: the installed one
    when it runs compiled, else a copy of ``src/`` with setup.py's modules compiled by mypyc in
    place."""
    if compiled_modules():
        return Path(cnctwin.__file__).parents[1]
    reason = cannot_compile()
    if reason is not None:
        missing(f"mypyc cannot compile here: {reason}", "CNCTWIN_REQUIRE_SERVICES")
    root = tmp_path_factory.mktemp("compiled")
    shutil.copytree(
        REPO / "src" / "cnctwin",
        root / "src" / "cnctwin",
        ignore=shutil.ignore_patterns("__pycache__", "*.so"),
    )
    built = subprocess.run(
        [sys.executable, "-m", "mypyc", *(f"cnctwin/nc/{name}.py" for name in COMPILED_MODULES)],
        cwd=root / "src",
        capture_output=True,
        text=True,
        timeout=1200,
    )
    assert built.returncode == 0, built.stdout[-3000:] + built.stderr[-3000:]
    return root / "src"


def _python(tree: Path, pure: bool, *args: str) -> subprocess.CompletedProcess[str]:
    """``python *args`` with ``tree`` first on the path, the sources forced when ``pure``."""
    env = {**os.environ, "PYTHONPATH": str(tree)}
    env.pop(PURE_PYTHON_VARIABLE, None)
    if pure:
        env[PURE_PYTHON_VARIABLE] = "1"
    return subprocess.run(
        [sys.executable, *args], env=env, capture_output=True, text=True, timeout=600, check=True
    )


def _child(tree: Path, programs: list[Path], pure: bool) -> tuple[list[str], list[str]]:
    first, *results = _python(tree, pure, "-c", CHILD, *map(str, programs)).stdout.splitlines()
    return json.loads(first), results


def _expressions(path: Path, blocks: int) -> Path:
    """Parameters, functions, O-word if and repeat, as the speed benchmark writes them."""
    text = ["G21 G90 G17 G94\nT1 M6\nS12000 M3\nG0 X0 Y0 Z5\nG1 Z-1 F1200\n#1 = 0\n#3 = 0\n"]
    for n in range(blocks):
        text.append(
            "#1 = [#1 + 0.25]\n#2 = [SIN[#1 * 3] * 10 + COS[#1] * 2]\n"
            "G1 X[#1] Y[#2] F[1000 + #3 * 10]\n"
            f"o{2 * n + 100} if [#2 GT 5]\n  #3 = [#3 + 1]\no{2 * n + 100} endif\n"
            f"o{2 * n + 101} repeat [2]\n  G1 Y[#2 - ABS[#1 MOD 3]]\no{2 * n + 101} endrepeat\n"
            "G0 X[#1 + 0.1] Y[ROUND[#2 * 100] / 100]\n"
        )
    path.write_text("".join(text) + "M2\n")
    return path


def test_compiled_and_source_modules_give_the_same_results(
    compiled_tree: Path, shared_data: Path, tmp_path: Path
) -> None:
    programs = sorted(p for p in (shared_data / "gcode").rglob("*") if p.is_file())
    programs.append(_expressions(tmp_path / "expressions.ngc", 300))
    bad = tmp_path / "bad.ngc"
    bad.write_text("G21 G90 F100\n#1 = [1 / 0]\nG1 X#1\nM2\n")
    programs.append(bad)
    compiled, from_compiled = _child(compiled_tree, programs, pure=False)
    sources, from_sources = _child(compiled_tree, programs, pure=True)
    assert compiled == sorted(f"cnctwin.nc.{name}" for name in COMPILED_MODULES), (
        "the installed build compiles other modules than COMPILED_MODULES: pip install -e ."
    )
    assert sources == []
    assert len(from_compiled) == len(programs)
    for path, one, other in zip(programs, from_compiled, from_sources, strict=True):
        assert one == other, path
    assert sum('"segments"' in result for result in from_compiled) >= 30
    assert "division by zero" in json.loads(from_compiled[-1])["error"]


def test_the_version_says_which_build_runs(compiled_tree: Path) -> None:
    for pure, build in ((False, "compiled"), (True, "pure Python")):
        done = _python(compiled_tree, pure, "-m", "cnctwin", "--version")
        assert done.stdout.endswith(f"(NC interpreter: {build})\n")
    done = _python(compiled_tree, True, "-c", "import cnctwin.nc.lexer as m; print(m.__file__)")
    assert done.stdout.strip() == str(compiled_tree / "cnctwin/nc/lexer.py")


def test_compiled_classes_keep_their_docstrings(compiled_tree: Path) -> None:
    code = (
        "import inspect, json, cnctwin.nc as nc\n"
        "values = [getattr(nc, name) for name in nc.__all__]\n"
        "print(json.dumps({v.__name__: inspect.getdoc(v) for v in values if inspect.isclass(v)}))"
    )
    compiled, sources = (
        json.loads(_python(compiled_tree, p, "-c", code).stdout) for p in (False, True)
    )
    assert compiled == sources
    assert compiled["Interpreter"].startswith("Interpret NC programs")


def test_first_stale_finds_a_compiled_module_older_than_its_source(tmp_path: Path) -> None:
    source = tmp_path / "lexer.py"
    source.write_text("")
    extension = tmp_path / ("lexer" + importlib.machinery.EXTENSION_SUFFIXES[0])
    extension.write_bytes(b"")
    os.utime(source, (1_000, 1_000))
    os.utime(extension, (2_000, 2_000))
    assert first_stale(tmp_path) is None  # compiled after the last change
    os.utime(source, (3_000, 3_000))
    assert first_stale(tmp_path) == (source, extension)


def test_a_stale_compiled_module_runs_all_from_sources(compiled_tree: Path, tmp_path: Path) -> None:
    """Compiled modules call one another natively: one changed source makes all of cnctwin.nc
    run as Python, with one warning that names it."""
    tree = tmp_path / "src"
    shutil.copytree(compiled_tree / "cnctwin", tree / "cnctwin")  # mtimes kept
    for shared in compiled_tree.glob("*__mypyc.*"):  # the compiled modules' common library
        shutil.copy2(shared, tree)
    code = (
        "import cnctwin.nc.lexer as m, cnctwin.nc as nc; print(nc.compiled_modules(), m.__file__)"
    )
    current = _python(tree, False, "-c", code)
    assert current.stderr == "" and current.stdout.split()[-1].endswith(".so")
    os.utime(tree / "cnctwin/nc/trace.py")  # now: after its compiled module
    stale = _python(tree, False, "-c", code)
    assert stale.stdout == f"[] {tree / 'cnctwin/nc/lexer.py'}\n"
    warning = [line for line in stale.stderr.splitlines() if "RuntimeWarning" in line]
    assert len(warning) == 1, stale.stderr
    assert "cnctwin.nc.trace changed since it was compiled" in warning[0]
    assert "runs as Python" in warning[0] and "pip install -e ." in warning[0]
    version = _python(tree, False, "-m", "cnctwin", "--version")
    assert version.stdout.endswith("(NC interpreter: pure Python)\n")


@pytest.mark.parametrize("cls", [Segment, Block, OWord])
def test_written_out_inits_take_the_dataclass_fields(
    cls: type, request: pytest.FixtureRequest
) -> None:
    """Segment, Block and OWord write their ``__init__`` out (so that mypyc compiles it):
    its parameters are the dataclass's fields, in order, with the fields' defaults."""
    if on_sources(request):  # a compiled __init__ shows (*args, **kwargs)
        return
    parameters = list(inspect.signature(cls.__init__).parameters.values())[1:]
    fields = dataclasses.fields(cls)
    assert [p.name for p in parameters] == [f.name for f in fields]
    for parameter, field in zip(parameters, fields, strict=True):
        if field.default is not dataclasses.MISSING:
            assert parameter.default == field.default, field.name


def test_a_segment_is_still_a_dataclass_value() -> None:
    state = MachineState()
    segment = Segment(MotionKind.LINEAR, 3, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 100.0, 0.0, state)
    moved = dataclasses.replace(segment, line=4)
    assert (moved.line, moved.turns, moved.file, moved.center_mm) == (4, 0, "", None)
    assert dataclasses.replace(moved, line=3) == segment
    assert repr(segment).startswith("Segment(kind=")
    block = Block()
    assert (block.gcodes, block.words, block.oword) == ([], {}, None)
    assert Block().gcodes is not block.gcodes
