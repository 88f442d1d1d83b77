"""Skip a test for a missing environment, or fail where the environment demands it; run a
test on the sources where the compiled NC interpreter hides what it checks.

Lives outside ``conftest.py`` so that test helpers import it by a name no other module shares
(pytest loads every folder's ``conftest.py`` under that one name).
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys

import pytest

from cnctwin.nc import compiled_modules
from cnctwin.nc.compiled import PURE_PYTHON_VARIABLE


def missing(reason: str, required_by: str) -> None:
    """Skip, or fail when the environment variable ``required_by`` is ``1``."""
    if os.environ.get(required_by) == "1":
        pytest.fail(f"{reason} ({required_by}=1)")
    pytest.skip(reason)


def require_service(host: str, port: int, name: str) -> None:
    """Skip the calling test unless ``name`` accepts TCP connections at ``host:port``.

    Fails instead of skipping when ``CNCTWIN_REQUIRE_SERVICES=1`` (CI).
    """
    try:
        with socket.create_connection((host, port), timeout=2.0):
            return
    except OSError as err:
        missing(f"{name} is not reachable at {host}:{port}: {err}", "CNCTWIN_REQUIRE_SERVICES")


def on_sources(request: pytest.FixtureRequest) -> bool:
    """On a compiled build of cnctwin.nc (whose functions ``monkeypatch`` cannot reach, whose
    ``__init__`` shows no signature): run the calling test again in a child pytest on the
    sources (``CNCTWIN_PURE_PYTHON=1``), fail as it fails, and return True for the caller to
    return. False on the sources: the caller runs its checks itself."""
    if not compiled_modules():
        return False
    child = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", request.node.nodeid],
        cwd=request.config.rootpath,
        env={**os.environ, PURE_PYTHON_VARIABLE: "1"},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert child.returncode == 0, child.stdout[-3000:]
    return True
