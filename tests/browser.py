"""A real headless Chromium for the web tests, driven by Playwright.

The browser is Debian's ``chromium`` package (``/usr/bin/chromium``, or ``$CNCTWIN_CHROMIUM``);
Playwright drives it through ``executable_path``, so nothing is downloaded. Where the browser
or Playwright is missing the tests skip with the reason, and fail in CI
(``CNCTWIN_REQUIRE_SERVICES=1``, tests/skips.py).

The fixtures reach the tests through ``tests/web/conftest.py`` (imported there once, so that
every module shares the one definition).

``browser`` is one Chromium per test module; ``page`` is a fresh page in
its own context for each test, and fails the test if the page raised a JavaScript error.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from typing import Any

import pytest
from skips import missing

#: Where Debian's chromium package puts the browser.
CHROMIUM_CANDIDATES = ("/usr/bin/chromium", "/usr/bin/chromium-browser")

#: Limit of one Playwright wait (navigation, selector, function), ms.
WAIT_MS = 20_000


def chromium_path() -> str:
    """The Chromium executable: ``$CNCTWIN_CHROMIUM``, else Debian's; skip (or fail) if none."""
    env = os.environ.get("CNCTWIN_CHROMIUM")
    candidates = (env,) if env else CHROMIUM_CANDIDATES
    for path in candidates:
        if path and (os.path.isfile(path) or shutil.which(path)):
            return path
    missing(
        f"Chromium is not installed at {', '.join(c for c in candidates if c)}"
        " (apt-get install chromium, or set CNCTWIN_CHROMIUM)",
        "CNCTWIN_REQUIRE_SERVICES",
    )
    raise AssertionError("unreachable")  # missing skips or fails


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    """One headless Chromium per test module (a ``playwright.sync_api.Browser``).

    Per module, not per session: while Playwright's sync API is open it keeps an asyncio loop
    running on the main thread, where ``asyncio.run`` then fails; closed after each browser
    module, it leaves the tests that follow a thread without a running loop.
    """
    try:
        from playwright.sync_api import sync_playwright
    except ImportError as err:
        missing(
            f"Playwright is not installed ({err}); pip install -e '.[test]'",
            "CNCTWIN_REQUIRE_SERVICES",
        )
    path = chromium_path()
    with sync_playwright() as pw:
        chromium = pw.chromium.launch(
            executable_path=path,
            headless=True,
            # --no-sandbox: CI runs as root, where Chromium refuses its sandbox.
            args=["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
        )
        yield chromium
        chromium.close()


@pytest.fixture
def page(browser: Any) -> Iterator[Any]:
    """A fresh page (``playwright.sync_api.Page``, 1280x900) in its own context.

    A JavaScript error raised on the page fails the test after its body.
    """
    context = browser.new_context(viewport={"width": 1280, "height": 900})
    context.set_default_timeout(WAIT_MS)
    tab = context.new_page()
    errors: list[str] = []
    tab.on("pageerror", lambda err: errors.append(str(err)))
    yield tab
    context.close()
    assert not errors, f"JavaScript errors on the page: {errors}"
