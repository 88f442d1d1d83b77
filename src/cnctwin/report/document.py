"""A self-contained HTML report: key figures, interactive plotly plots, the command's JSON.

The file carries plotly.js inline, taken from the installed ``plotly`` package, so it opens in
any browser without a network; nothing in it refers to a server. The command's whole JSON
result is embedded as ``<script type="application/json" id="cnctwin-result">`` (the object
its ``--json`` prints), and its scalar figures are listed in a table.
"""

from __future__ import annotations

import html
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cnctwin import __version__, finite_json
from cnctwin.errors import InputError

if TYPE_CHECKING:
    import plotly.graph_objects as go

__all__ = ["Report", "check_report_path", "scalar_rows"]

#: Rows of the key-figure table at most (long lists stay in the embedded JSON).
MAX_ROWS = 60

_STYLE = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1200px;
       color: #222; padding: 0 1em; }
h1 { font-size: 1.5em; margin-bottom: 0.2em; }
h2 { font-size: 1.15em; margin-top: 1.6em; border-bottom: 1px solid #ddd; }
p.sub { color: #666; margin-top: 0; }
table.figures { border-collapse: collapse; font-size: 0.9em; }
table.figures td { padding: 2px 10px; border-bottom: 1px solid #eee; }
table.figures td.v { text-align: right; font-variant-numeric: tabular-nums; }
div.plot { height: 480px; margin: 0.5em 0 1em; }
"""


def check_report_path(path: Path, option: str = "--report") -> Path:
    """``path`` if an HTML report can be written there, checked before any work is done.

    The folder must exist and the path must not be a folder; a file that does not exist yet
    is created and removed again, so a folder that refuses new files (read-only, no
    permission) is found even where permission bits do not tell (root).

    Raises
    ------
    InputError
        Naming ``option``, the path and what would be valid.
    """
    if path.is_dir():
        raise InputError(f"{option} {path}: is a folder; give a file name, e.g. report.html")
    folder = path.parent
    if not folder.is_dir():
        raise InputError(f"{option} {path}: folder {folder} does not exist; create it first")
    try:
        if path.exists():
            if not os.access(path, os.W_OK):
                raise PermissionError(13, "Permission denied")
        else:
            with path.open("x", encoding="utf-8"):
                pass
            path.unlink()
    except OSError as err:
        raise InputError(
            f"{option} {path}: cannot write there ({err.strerror or err}); give a writable file"
        ) from None
    return path


def _text(value: Any) -> str:
    if isinstance(value, float):
        return "-" if not math.isfinite(value) else f"{value:.6g}"
    if value is None:
        return "-"
    return str(value)


def scalar_rows(result: Mapping[str, Any], prefix: str = "") -> list[tuple[str, str]]:
    """The scalar entries of a (nested) JSON result as ``(dotted key, text)`` rows.

    Lists and the entries below them are left out (they are in the embedded JSON and the
    plots); floats are shown with 6 significant digits.
    """
    rows: list[tuple[str, str]] = []
    for key, value in result.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            rows.extend(scalar_rows(value, f"{name}."))
        elif not isinstance(value, list | tuple):
            rows.append((name, _text(value)))
    return rows


@dataclass
class Report:
    """An HTML report under construction.

    Attributes
    ----------
    title
        The page's heading (and ``<title>``).
    subtitle
        One line under the heading: what was computed from what.
    result
        The command's JSON result, embedded whole and tabled by :func:`scalar_rows`.
    """

    title: str
    subtitle: str
    result: Mapping[str, Any]
    _parts: list[str] = field(default_factory=list)
    _figures: int = 0

    def section(self, heading: str, text: str = "") -> None:
        """Start a section: a heading and an optional paragraph (plain text)."""
        self._parts.append(f"<h2>{html.escape(heading)}</h2>")
        if text:
            self._parts.append(f"<p>{html.escape(text)}</p>")

    def figure(self, figure: go.Figure, height_px: int = 480) -> None:
        """Add an interactive plot (zoom, pan, hover) of a plotly figure."""
        self._figures += 1
        figure.update_layout(template="plotly_white", height=height_px)
        self._parts.append(
            figure.to_html(
                full_html=False,
                include_plotlyjs=False,
                div_id=f"figure-{self._figures}",
                config={"displaylogo": False, "responsive": True},
            )
        )

    def table(self, rows: Sequence[Sequence[Any]], header: Sequence[str]) -> None:
        """Add a table of values (floats with 6 significant digits)."""
        head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
        body = "".join(
            "<tr>" + "".join(f"<td>{html.escape(_text(v))}</td>" for v in row) + "</tr>"
            for row in rows
        )
        self._parts.append(f'<table class="figures"><tr>{head}</tr>{body}</table>')

    def render(self) -> str:
        """The whole page as text."""
        import plotly.offline

        rows = scalar_rows(self.result)[:MAX_ROWS]
        figures = "".join(
            f'<tr><td>{html.escape(k)}</td><td class="v">{html.escape(v)}</td></tr>'
            for k, v in rows
        )
        data = finite_json.dumps(dict(self.result)).replace("</", "<\\/")
        script = plotly.offline.get_plotlyjs().replace("</script", "<\\/script")
        return (
            "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
            f"<title>{html.escape(self.title)}</title><style>{_STYLE}</style>"
            f"<script>{script}</script></head><body>"
            f"<h1>{html.escape(self.title)}</h1>"
            f"<p class='sub'>{html.escape(self.subtitle)} (cnctwin {__version__})</p>"
            f"<h2>Key figures</h2><table class='figures'>{figures}</table>"
            + "".join(self._parts)
            + f'<script type="application/json" id="cnctwin-result">{data}</script>'
            "</body></html>\n"
        )

    def write(self, path: Path) -> Path:
        """Write the page to ``path`` (UTF-8) and return the path.

        Raises
        ------
        InputError
            When the file cannot be written (a one-line message naming it).
        """
        text = self.render()
        try:
            path.write_text(text, encoding="utf-8")
        except OSError as err:
            raise InputError(
                f"--report {path}: cannot write the report ({err.strerror or err})"
            ) from None
        return path
