"""Fixtures of the twin's tests."""

from __future__ import annotations

import pytest
from twin_helpers import load_demo_config

from cnctwin.twin.config import RunConfig


@pytest.fixture(scope="session")
def demo_config() -> RunConfig:
    """The packaged ``demo_twin.toml``."""
    return load_demo_config()
