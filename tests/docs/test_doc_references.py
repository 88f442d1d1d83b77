"""Every file the README and docs/ point to is in the repository.

Two kinds of reference are checked: Markdown links to local files (``[text](path)``, relative
to the page that holds them; web addresses and in-page anchors are not files) and paths written
out in the text that name a page or a benchmark (``docs/NAME.md``, ``benchmarks/NAME.py``,
relative to the repository root).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PAGES = sorted([REPO / "README.md", *(REPO / "docs").glob("*.md"), REPO / "examples/README.md"])
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
WRITTEN = re.compile(r"(?<![\w/.])((?:docs|benchmarks)/[\w.-]+\.(?:md|py))")


def _targets(page: Path) -> list[tuple[str, Path]]:
    text = page.read_text(encoding="utf-8")
    found: list[tuple[str, Path]] = []
    for ref in LINK.findall(text):
        if re.match(r"[a-z][a-z0-9+.-]*:", ref) or ref.startswith("#"):
            continue  # a web address (https:, mailto:) or an anchor on the same page
        found.append((ref, page.parent / ref.split("#", 1)[0]))
    found.extend((ref, REPO / ref) for ref in WRITTEN.findall(text))
    return found


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_every_referenced_file_exists(page: Path) -> None:
    missing = [ref for ref, path in _targets(page) if not path.exists()]
    assert not missing, f"{page.relative_to(REPO)} points to files not in the repository: {missing}"


def test_a_missing_file_is_found(tmp_path: Path) -> None:
    page = tmp_path / "page.md"
    page.write_text("See [the guide](guide.md), docs/_bench_x.md and [web](https://a.b/c).\n")
    refs = {ref for ref, path in _targets(page) if not path.exists()}
    assert refs == {"guide.md", "docs/_bench_x.md"}
