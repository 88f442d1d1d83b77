"""The shared Chromium fixture (tests/browser.py) runs JavaScript and WebGL."""


def test_page_runs_script_and_has_webgl(page) -> None:
    page.set_content(
        "<canvas id=c></canvas><script>"
        "document.title = String(6 * 7) + ':' +"
        " String(!!document.getElementById('c').getContext('webgl'))</script>"
    )
    assert page.title() == "42:true"
