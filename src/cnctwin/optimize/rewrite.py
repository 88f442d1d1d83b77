"""Editing NC blocks as text: a feed or speed word set in place, a block split into pieces.

Only *simple* blocks are edited: after their comments (``(...)`` anywhere, ``;`` to the end of
the line) they are words of a letter and a plain number, as CAM posts write them (``N120 G1
X30.5 Y-2 F350``). Everything else in a line (comments, spacing, letter case, the words not
touched) is kept as written. A split block becomes a comment holding the original line, then
one block per piece: the first keeps the block number (``N``) and every word that is not an axis
or a feed, the others repeat the motion word; the last piece ends on the original axis words,
so the block's end point is the programmed one, character for character.

Units: whatever the program uses (these functions only write the numbers they are given).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

__all__ = ["Block", "comment_style", "format_number", "read_block", "set_words", "split_block"]

_NUMBER = r"[-+]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)"
_WORD = re.compile(rf"([A-Za-z])[ \t]*({_NUMBER})")
_SIMPLE = re.compile(rf"(?:[A-Za-z]{_NUMBER})*")
#: Motion G-codes a piece of a split block repeats (G1, G2, G3 written any way).
_MOTION = {1, 2, 3}
_AXES = "XYZIJK"


@dataclass(frozen=True)
class Block:
    """A simple block's words, with where they stand in the line.

    Attributes
    ----------
    raw
        The line as read, without its line end.
    words
        ``(letter upper-cased, number text, start, end)`` per word, in order; ``start:end`` is
        the word's span in ``raw``.
    code_end
        Index in ``raw`` just after the last word (where a new word goes).
    """

    raw: str
    words: tuple[tuple[str, str, int, int], ...]
    code_end: int

    def value(self, letter: str) -> float | None:
        """The number of the first word of ``letter`` (upper case); None without one."""
        for word, number, _, _ in self.words:
            if word == letter:
                return float(number)
        return None

    def has(self, letter: str) -> bool:
        """Whether a word of ``letter`` (upper case) is in the block."""
        return any(word == letter for word, _, _, _ in self.words)

    @property
    def lower(self) -> bool:
        """Whether the block writes its letters in lower case."""
        letters = [self.raw[start] for _, _, start, _ in self.words]
        return bool(letters) and all(c.islower() for c in letters)

    @property
    def spaced(self) -> bool:
        """Whether the block separates its words with spaces."""
        return (
            any(
                self.raw[end:start].strip() == "" and end < start
                for (_, _, _, end), (_, _, start, _) in zip(
                    self.words, self.words[1:], strict=False
                )
            )
            or len(self.words) <= 1
        )


def _code_spans(raw: str) -> list[tuple[int, int]]:
    """The spans of ``raw`` outside comments (``(...)``, and ``;`` to the end)."""
    spans = []
    start = 0
    depth = 0
    for k, char in enumerate(raw):
        if depth:
            if char == ")":
                depth = 0
                start = k + 1
            continue
        if char == "(":
            spans.append((start, k))
            depth = 1
        elif char == ";":
            spans.append((start, k))
            return [s for s in spans if s[1] > s[0]]
    if not depth:
        spans.append((start, len(raw)))
    return [s for s in spans if s[1] > s[0]]


def read_block(raw: str) -> Block | None:
    """The words of a simple block; None for any other line (expressions, keywords, ``%``).

    Parameters
    ----------
    raw
        One line of the program, without its line end.

    Returns
    -------
    Block or None
        The words and where they are.
    """
    spans = _code_spans(raw)
    code = "".join(raw[a:b] for a, b in spans)
    if "(" in code or not _SIMPLE.fullmatch("".join(code.split())):
        return None
    words = []
    for a, b in spans:
        for match in _WORD.finditer(raw, a, b):
            words.append((match.group(1).upper(), match.group(2), match.start(), match.end()))
    code_end = words[-1][3] if words else (spans[-1][1] if spans else 0)
    return Block(raw, tuple(words), code_end)


def comment_style(lines: Sequence[str]) -> str:
    """``";"`` where the program writes its comments after ``;`` only, else ``"("``."""
    paren = semicolon = False
    for raw in lines:
        for a, b in _code_spans(raw):
            del a
            if b < len(raw):
                if raw[b] == "(":
                    paren = True
                elif raw[b] == ";":
                    semicolon = True
    return ";" if semicolon and not paren else "("


def format_number(value: float, decimals: int) -> str:
    """``value`` with at most ``decimals`` decimals, trailing zeros dropped (``-0`` as ``0``)."""
    text = f"{value:.{decimals}f}"
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def _word(block: Block, letter: str, number: str) -> str:
    return (letter.lower() if block.lower else letter) + number


def set_words(block: Block, values: dict[str, str]) -> str:
    """The block's line with words set: each letter's first word gets the number given, a
    letter the block lacks is added after its last word.

    Parameters
    ----------
    block
        The block.
    values
        Number text by upper-case letter (``{"F": "420"}``).

    Returns
    -------
    str
        The edited line.
    """
    raw = block.raw
    edits: list[tuple[int, int, str]] = []
    added = []
    for letter, number in values.items():
        for word, _, start, end in block.words:
            if word == letter:
                edits.append((start, end, raw[start] + number))
                break
        else:
            added.append(_word(block, letter, number))
    if added:
        sep = " " if block.spaced else ""
        joined = sep.join(added)
        text = sep + joined if block.words else joined
        edits.append((block.code_end, block.code_end, text))
    for start, end, text in sorted(edits, reverse=True):
        raw = raw[:start] + text + raw[end:]
    return raw


def split_block(
    block: Block,
    pieces: Sequence[tuple[dict[str, str], dict[str, str]]],
    comment: str,
    note: str,
) -> list[str]:
    """The lines of a block split into pieces.

    Parameters
    ----------
    block
        The block (a straight or circular move).
    pieces
        Per piece, in path order: the axis and centre words of its end (``{"X": "12.5",
        "I": "-3"}``; the last piece gives only its centre words, its end being the block's
        own axis words) and its other words (``{"F": "420"}``).
    comment
        ``"("`` or ``";"``: how the program writes comments.
    note
        Text of the comment line before the pieces (the original line is appended to it).

    Returns
    -------
    list of str
        The comment line, then one line per piece.
    """
    original = block.raw.strip()
    if comment == "(":
        original = original.replace("(", "[").replace(")", "]")
        lines = [f"({note}: {original})"]
    else:
        lines = [f"; {note}: {original}"]
    motion = [
        block.raw[start:end]
        for letter, number, start, end in block.words
        if letter == "G" and float(number) in _MOTION
    ]
    first = [
        (letter, block.raw[start:end])
        for letter, _, start, end in block.words
        if letter not in _AXES and letter != "F" and letter != "R"
    ]
    own_axes = [block.raw[start:end] for letter, _, start, end in block.words if letter in "XYZ"]
    sep = " " if block.spaced else ""
    for k, (axes, others) in enumerate(pieces):
        head = [text for letter, text in first if letter not in others] if k == 0 else motion
        last = k == len(pieces) - 1
        ends = own_axes if last else [_word(block, a, v) for a, v in axes.items() if a in "XYZ"]
        centre = [_word(block, a, v) for a, v in axes.items() if a in "IJK"]
        extra = [_word(block, a, v) for a, v in others.items()]
        lines.append(sep.join([*head, *ends, *centre, *extra]))
    return lines
