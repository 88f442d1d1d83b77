"""mypy --strict passes on the physics packages (the [tool.mypy] section of pyproject.toml).

The packages and the per-module exceptions (numba kernels) are listed there; ``.venv/bin/mypy``
from the repository root runs the same check. A cold run takes about 20 s on the 2-core
development machine (see docs/testing.md); the cache goes to a temporary folder so that a run
never reads a stale cache of another checkout.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

from skips import missing

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "pyproject.toml"


def _mypy(*args: str, cache: Path) -> subprocess.CompletedProcess[str]:
    if importlib.util.find_spec("mypy") is None:
        missing("mypy is not installed (pip install -e '.[test]')", "CNCTWIN_REQUIRE_SERVICES")
    return subprocess.run(
        [sys.executable, "-m", "mypy", "--config-file", str(CONFIG), "--cache-dir", str(cache)]
        + list(args),
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_physics_packages_pass_mypy_strict(tmp_path: Path) -> None:
    done = _mypy(cache=tmp_path / "cache")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "Success: no issues found" in done.stdout
    # The files of [tool.mypy] were the ones checked: every physics package, not an empty list.
    checked = int(done.stdout.split(" in ")[1].split()[0])
    assert checked >= 80, done.stdout


def test_the_configuration_is_strict(tmp_path: Path) -> None:
    """The same configuration refuses an unannotated function and an Any returned as a float
    (so the check above would fail on such code in a physics package)."""
    bad = tmp_path / "unannotated.py"
    bad.write_text(
        "import json\n\n\ndef area(width_mm, height_mm):\n    return width_mm * height_mm\n\n\n"
        "def load_mm(text: str) -> float:\n    return json.loads(text)\n"
    )
    done = _mypy(str(bad), cache=tmp_path / "cache")
    assert done.returncode == 1, done.stdout + done.stderr
    assert "[no-untyped-def]" in done.stdout
    assert "[no-any-return]" in done.stdout
