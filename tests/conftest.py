"""Shared test helpers: the real-data folder, external services and Hypothesis profiles.

The data and the services skip with a reason on a developer's machine that lacks them, and
fail in CI, which sets ``CNCTWIN_REQUIRE_DATA=1`` and ``CNCTWIN_REQUIRE_SERVICES=1``.

Property tests (Hypothesis) draw the same examples on every run (profile ``reproducible``), so
a run of main passes or fails the same way each time; ``HYPOTHESIS_PROFILE=explore`` draws new
examples to look for failures.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import settings
from skips import missing

settings.register_profile("reproducible", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "reproducible"))

REPO_ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The real-data folder: ``$CNCTWIN_DATA``, else ``<repo>/../shared/data``."""
    path = Path(os.environ.get("CNCTWIN_DATA") or REPO_ROOT.parent / "shared" / "data")
    if not path.is_dir():
        missing(f"real data folder {path} is absent (set CNCTWIN_DATA)", "CNCTWIN_REQUIRE_DATA")
    return path
