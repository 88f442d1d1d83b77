"""Skip a test for a missing environment, or fail where the environment demands it.

Lives outside ``conftest.py`` so that test helpers import it by a name no other module shares
(pytest loads every folder's ``conftest.py`` under that one name).
"""

from __future__ import annotations

import os
import socket

import pytest


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
