"""Every table of docs/validation.md says what its reference is (the legend at the top).

A table is labelled by a ``Kind:`` line just before it or by a ``kind`` column: independent
(paper, closed form, measurement, other implementation), self-consistency, not checked, and
for fits in-sample or held-out.
"""

from __future__ import annotations

import re
from pathlib import Path

DOC = Path(__file__).resolve().parents[2] / "docs" / "validation.md"
LABEL = re.compile(r"independent|self-consistency|not checked|in-sample|held[- ]out")
KINDS = ("paper", "closed form", "measurement", "other implementation")


def _cells(row: str) -> list[str]:
    return [cell.strip() for cell in row.strip().strip("|").split("|")]


def tables(text: str) -> list[tuple[int, str, list[str]]]:
    """(line number, the non-blank line before it, rows) of each table."""
    lines = text.splitlines()
    found = []
    i = 0
    while i < len(lines):
        if lines[i].startswith("|"):
            j = i
            while j < len(lines) and lines[j].startswith("|"):
                j += 1
            before = next((line for line in reversed(lines[:i]) if line.strip()), "")
            found.append((i + 1, before, lines[i:j]))
            i = j
        else:
            i += 1
    return found


def unlabelled(text: str) -> list[str]:
    """The tables of ``text`` that carry no label, as 'line: header'."""
    bad = []
    for line, before, rows in tables(text):
        if before.startswith("Kind:") and LABEL.search(before):
            continue
        header = _cells(rows[0])
        if "kind" in header:
            # counted from the right: a cell may hold a `|x|` of its own
            column = header.index("kind") - len(header)
            body = [r for r in rows[2:] if not re.fullmatch(r"\|[-: |]+\|", r.strip())]
            cells = [_cells(r)[column] if len(_cells(r)) >= -column else "" for r in body]
            if body and all(LABEL.search(cell) for cell in cells):
                continue
        bad.append(f"{line}: {rows[0][:80]}")
    return bad


def test_every_validation_table_says_what_its_reference_is() -> None:
    text = DOC.read_text("utf-8")
    assert len(tables(text)) >= 40
    assert unlabelled(text) == []


def test_the_legend_names_every_kind() -> None:
    legend = DOC.read_text("utf-8").split("\n## ", 1)[0]
    for word in (*KINDS, "independent", "self-consistency", "in-sample", "held-out"):
        assert word in legend, word


def test_an_unlabelled_table_and_a_wrong_kind_column_are_found() -> None:
    text = (
        "Kind: independent: closed form.\n\n| a | b |\n|---|---|\n| 1 | 2 |\n\n"
        "Some text.\n\n| a | b |\n|---|---|\n| 1 | 2 |\n\n"
        "| case | kind |\n|---|---|\n| x | hopf |\n\n"
        "| case | kind |\n|---|---|\n| x | self-consistency |\n| y | held-out |\n"
    )
    assert unlabelled(text) == ["9: | a | b |", "13: | case | kind |"]
