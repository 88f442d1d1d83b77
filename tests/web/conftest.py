"""The web tests' fixtures: one headless Chromium for the session (tests/browser.py).

The fixtures are imported here, once, and not in each test module: a session-scoped fixture
imported into two modules would be two fixtures, each starting its own Playwright.
"""

from browser import browser, page  # noqa: F401  (pytest fixtures)
