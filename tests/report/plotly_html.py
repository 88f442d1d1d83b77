"""Read back what an HTML report holds: its plotly figures and its embedded JSON result.

Written for the tests, independently of :mod:`cnctwin.report`: the figures are found as the
``Plotly.newPlot(id, data, layout, config)`` calls of the page and decoded as JSON; arrays that
plotly stored as typed arrays (``{"dtype": "f8", "bdata": base64}``) are decoded to numpy.
"""

from __future__ import annotations

import base64
import json
import re
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import numpy as np

_NEW_PLOT = re.compile(r"Plotly\.newPlot\(\s*\"([^\"]+)\",\s*")
#: Tags that would make a browser fetch something, with the attribute that names it.
_FETCHING = {"script": "src", "link": "href", "img": "src", "iframe": "src", "embed": "src"}


def figures(text: str) -> dict[str, dict[str, Any]]:
    """Every figure of the page by its div id: ``{"data": [...], "layout": {...}}``."""
    decoder = json.JSONDecoder()
    found: dict[str, dict[str, Any]] = {}
    for match in _NEW_PLOT.finditer(text):
        data, end = decoder.raw_decode(text, match.end())
        rest = re.match(r"\s*,\s*", text[end:])
        assert rest is not None
        layout, _ = decoder.raw_decode(text, end + rest.end())
        found[match.group(1)] = {"data": data, "layout": layout}
    return found


def array(value: Any) -> np.ndarray:
    """A trace's array as float64 (typed array or list; None -> NaN)."""
    if isinstance(value, dict) and "bdata" in value:
        raw = np.frombuffer(base64.b64decode(value["bdata"]), dtype=np.dtype(value["dtype"]))
        shape = value.get("shape")
        if shape:
            dims = [int(n) for n in str(shape).split(",")]
            raw = raw.reshape(dims)
        return raw.astype(np.float64)
    return np.array(
        [np.nan if v is None else v for v in np.ravel(np.array(value, dtype=object))], dtype=float
    ).reshape(np.shape(np.array(value, dtype=object)))


def result(text: str) -> dict[str, Any]:
    """The command's JSON result embedded in the page."""
    match = re.search(
        r'<script type="application/json" id="cnctwin-result">(.*?)</script>', text, re.DOTALL
    )
    assert match is not None, "no embedded result"
    return json.loads(match.group(1).replace("<\\/", "</"))


class _Fetches(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.urls: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        name = _FETCHING.get(tag)
        for key, value in attrs:
            if key == name and value:
                self.urls.append(f"<{tag} {key}={value}>")


def fetched(text: str) -> list[str]:
    """The tags of the page that would load a file (script src, link href, img src, ...)."""
    parser = _Fetches()
    parser.feed(text)
    return parser.urls


def read(path: Path) -> str:
    """The report's text."""
    return path.read_text(encoding="utf-8")
