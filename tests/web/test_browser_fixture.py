"""The shared Chromium fixture (tests/browser.py) runs JavaScript and WebGL."""

from browser import browser, page  # noqa: F401  (pytest fixtures)


def test_page_runs_script_and_has_webgl(page) -> None:  # noqa: F811
    page.set_content(
        "<canvas id=c></canvas><script>"
        "document.title = String(6 * 7) + ':' +"
        " String(!!document.getElementById('c').getContext('webgl'))</script>"
    )
    assert page.title() == "42:true"
