"""Fixtures of the interoperability tests: node-opcua's certificate folder, one per session."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def node_pki(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Where node-opcua keeps its server's certificate (made on the first start, then kept)."""
    return tmp_path_factory.mktemp("node-opcua-pki")
