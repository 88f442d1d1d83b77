"""Reading one NC block (line) into words.

A block is read in two passes of the kind RS274NGC prescribes: comments are removed
(``(...)`` anywhere, ``;`` to the end of the line), all white space is dropped and the
text is lower-cased; then the words are read. Lines made only of letters and numbers take
a fast path through two compiled regular expressions; lines with parameters, expressions
or O-words go through :mod:`cnctwin.nc.expressions`, compiled once per distinct line: a
line met again (an O-word loop's body, or the same text later) only evaluates its
compiled values with the parameters of the moment.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Final

from cnctwin.errors import NCError
from cnctwin.nc.expressions import (
    CACHE_SIZE,
    RAISES,
    Evaluator,
    Parameters,
    compile_setting,
    compile_value,
    raising,
    read_assignment_once,
    read_value_once,
)
from cnctwin.nc.limits import MAX_NUMBER_CHARS, check_number_text, check_word

__all__ = ["Block", "OWord", "lex_block", "read_oword", "squeeze", "strip_comments", "O_KEYWORDS"]

_NUMBER: Final = r"[-+]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)"
_SIMPLE_LINE: Final = re.compile(rf"(?:[a-z@^]{_NUMBER})*")
_WORD: Final = re.compile(rf"([a-z@^])({_NUMBER})")
_MESSAGE: Final = re.compile(r"^\s*(msg|debug|print)\s*,(.*)$", re.IGNORECASE | re.DOTALL)
_PROGRAM_NUMBER: Final = re.compile(r"^[o:][0-9]+$")
_NO_ASSIGNMENTS: Final[list[tuple[int | str, float]]] = []  # shared, never mutated

#: One word or setting of a compiled line: ``("#", read_key, value)`` for a parameter
#: setting, ``(letter, _NO_KEY, value)`` for a word.
_Step = tuple[str, Callable[[Parameters], int | str], Evaluator]
#: Lines read the general way, by the raw line: their messages and compiled steps, or None
#: for a line seen once (read directly then: compiling costs about one more reading, so
#: only lines met again are compiled). Bounded like the expressions' store.
_COMPILED_LINES: Final[dict[str, tuple[tuple[tuple[str, str], ...], tuple[_Step, ...]] | None]] = {}
_UNSEEN: Final[Any] = object()


def _no_key(params: Parameters) -> int | str:
    raise AssertionError("a word has no parameter key")


_NO_KEY: Final = _no_key

#: O-word keywords (LinuxCNC subroutines and control flow).
O_KEYWORDS: Final = (
    "sub",
    "endsub",
    "call",
    "do",
    "while",
    "endwhile",
    "if",
    "elseif",
    "else",
    "endif",
    "repeat",
    "endrepeat",
    "break",
    "continue",
    "return",
)
_O_WORD: Final = re.compile(
    r"^o([0-9]+|<[^>]*>)(" + "|".join(sorted(O_KEYWORDS, key=len, reverse=True)) + ")"
)


@dataclass(slots=True, init=False)
class OWord:
    """An O-word control statement.

    Attributes
    ----------
    label
        The O-word's label: its number as text (``"101"``) or its name (``"<name>"``
        lower-cased, angle brackets kept).
    keyword
        One of :data:`O_KEYWORDS`.
    text
        The lower-cased, space-free block text.
    args_pos
        Index in ``text`` where the statement's arguments (condition, call arguments,
        return value) start.
    """

    label: str
    keyword: str
    text: str
    args_pos: int

    def __init__(self, label: str, keyword: str, text: str, args_pos: int) -> None:
        # Written out (init=False above): compiled by mypyc, a dataclass's generated
        # __init__ would stay interpreted Python, and one runs per O-word line.
        self.label = label
        self.keyword = keyword
        self.text = text
        self.args_pos = args_pos


@dataclass(slots=True, init=False)
class Block:
    """The words of one NC block.

    Attributes
    ----------
    gcodes
        G-codes in the order written, as ten times their number (G1 -> 10, G92.1 -> 921),
        so that decimal G-codes compare exactly.
    mcodes
        M-codes in the order written.
    words
        Every other word by its lower-case letter (N excluded; ``@`` and ``^`` are the
        polar radius and angle), value in program units.
    assignments
        Parameter assignments ``(key, value)`` to apply after the block is read.
    messages
        ``(kind, text)`` of ``(MSG,...)``, ``(DEBUG,...)`` and ``(PRINT,...)`` comments,
        kind lower-cased (``"msg"``, ``"debug"``, ``"print"``).
    oword
        The block's O-word statement, if any.
    """

    gcodes: list[int]
    mcodes: list[int]
    words: dict[str, float]
    assignments: list[tuple[int | str, float]]
    messages: list[tuple[str, str]]
    oword: OWord | None

    def __init__(
        self,
        gcodes: list[int] | None = None,
        mcodes: list[int] | None = None,
        words: dict[str, float] | None = None,
        assignments: list[tuple[int | str, float]] | None = None,
        messages: list[tuple[str, str]] | None = None,
        oword: OWord | None = None,
    ) -> None:
        # Written out (init=False above), as OWord's: one block is made per line.
        self.gcodes = [] if gcodes is None else gcodes
        self.mcodes = [] if mcodes is None else mcodes
        self.words = {} if words is None else words
        self.assignments = [] if assignments is None else assignments
        self.messages = [] if messages is None else messages
        self.oword = oword


def strip_comments(raw: str, messages: list[tuple[str, str]] | None = None) -> str:
    """Remove ``(...)`` and ``;`` comments from a line.

    Parameters
    ----------
    raw
        The line as read from the file.
    messages
        If given, ``(kind, text)`` of each ``(MSG, ...)``, ``(DEBUG, ...)`` or
        ``(PRINT, ...)`` comment is appended to it.

    Returns
    -------
    str
        The line without comments (case and spaces kept).

    Raises
    ------
    NCError
        For an unclosed ``(`` or a ``(`` nested inside a comment; ``line`` is left 0 for
        the caller to fill in.
    """
    out: list[str] = []
    i = 0
    n = len(raw)
    while i < n:
        open_at = raw.find("(", i)
        semi = raw.find(";", i)
        if semi != -1 and (open_at == -1 or semi < open_at):
            out.append(raw[i:semi])
            break
        if open_at == -1:
            out.append(raw[i:])
            break
        out.append(raw[i:open_at])
        close = raw.find(")", open_at + 1)
        if close == -1:
            raise NCError(
                "unclosed comment: '(' has no matching ')' on this line", column=open_at + 1
            )
        body = raw[open_at + 1 : close]
        if "(" in body:
            raise NCError("nested comment: '(' inside a comment is not allowed", column=open_at + 1)
        if messages is not None:
            found = _MESSAGE.match(body)
            if found:
                messages.append((found.group(1).lower(), found.group(2).strip()))
        i = close + 1
    return "".join(out)


def lex_block(raw: str, params: Parameters) -> Block | None:
    """Read one line of an NC program into a :class:`Block`.

    Parameters
    ----------
    raw
        The line as read from the file, without its line terminator.
    params
        Parameter store used to evaluate ``#`` references and expressions.

    Returns
    -------
    Block or None
        ``None`` for a line with nothing to execute (blank, comment only, ``%``,
        a program number such as ``O1003``).

    Raises
    ------
    NCError
        For anything that is not valid RS274NGC; ``line`` is left 0 and ``column`` refers
        to the comment-free, space-free text.
    """
    compiled = _COMPILED_LINES.get(raw, _UNSEEN)
    if compiled is not None and compiled is not _UNSEEN:
        return _evaluate_line(compiled[0], compiled[1], params)
    messages: list[tuple[str, str]] = []
    text = squeeze(strip_comments(raw, messages) if "(" in raw or ";" in raw else raw)
    if text.startswith("/"):
        # Block delete: the switch is off, so the block is executed.
        text = text[1:]
    if not text or text == "%":
        if messages:
            return Block(messages=messages)
        return None
    if text[0] == "o":
        statement = _O_WORD.match(text)
        if statement is not None:  # never words alone: a letter follows the label
            return _oword(text, statement, messages)
    if _SIMPLE_LINE.fullmatch(text):
        if text[0] in "o:" and _PROGRAM_NUMBER.match(text):
            return None
        found = _WORD.findall(text)
        if len(text) > MAX_NUMBER_CHARS:
            for _, number in found:
                check_number_text(number)
        gcodes, mcodes, words = _sort_words([(letter, float(number)) for letter, number in found])
        return Block(gcodes, mcodes, words, _NO_ASSIGNMENTS, messages)
    if text[0] == "o":
        return _oword(text, None, messages)
    if len(_COMPILED_LINES) >= CACHE_SIZE:
        _COMPILED_LINES.clear()
    if compiled is _UNSEEN:  # first sight: read and evaluate in one pass
        _COMPILED_LINES[raw] = None
        return _lex_once(text, params, messages)
    steps = _compile_line(text)  # met again: compiled, evaluated from now on
    _COMPILED_LINES[raw] = (tuple(messages), steps)
    return _evaluate_line(messages, steps, params)


def squeeze(text: str) -> str:
    """A line without comments as its words are read: white space (spaces, tabs, form
    and vertical feeds) removed, lower case."""
    text = text.replace(" ", "")
    if "\t" in text or "\f" in text or "\v" in text:
        text = "".join(text.split())
    return text.lower()


def read_oword(text: str, params: Parameters) -> OWord | None:
    """The O-word statement of a prepared line that starts with ``o`` (comments and white
    space removed, lower case), as :func:`lex_block` reads it from that text: ``None`` for
    a block without one (a program number such as ``o1003``).

    Raises
    ------
    NCError
        For a line that :func:`lex_block` refuses (an unrecognised O-word statement).
    """
    found = _O_WORD.match(text)
    if found is not None:
        return OWord(found.group(1), found.group(2), text, found.end())
    lex_block(text, params)  # no statement: raises for a malformed line
    return None


def _sort_words(
    pairs: list[tuple[str, float]],
) -> tuple[list[int], list[int], dict[str, float]]:
    """(letter, value) pairs filed into a block's G-codes, M-codes and other words (see
    :class:`Block`), each checked against :data:`cnctwin.nc.limits.WORD_LIMITS`."""
    gcodes: list[int] = []
    mcodes: list[int] = []
    words: dict[str, float] = {}
    for letter, value in pairs:
        check_word(letter, value)
        if letter == "g":
            gcodes.append(_gcode_key(value))
        elif letter == "m":
            mcodes.append(_mcode_key(value))
        elif letter == "n":
            continue
        elif letter in words:
            raise NCError(
                f"word {letter.upper()} appears twice in one block "
                f"({letter.upper()}{_fmt(words[letter])} and {letter.upper()}{_fmt(value)})"
            )
        else:
            words[letter] = value
    return gcodes, mcodes, words


def _oword(text: str, found: re.Match[str] | None, messages: list[tuple[str, str]]) -> Block:
    """The block of an O-word line (its arguments are read when it runs); ``found``: its
    match of the O-word statement pattern."""
    if found:
        label, keyword = found.groups()
        return Block([], [], {}, [], messages, OWord(label, keyword, text, found.end()))
    if _PROGRAM_NUMBER.match(text):
        return Block([], [], {}, [], messages)
    raise NCError(
        f"unrecognised O-word statement '{text}': expected o<label> followed by one of "
        + ", ".join(O_KEYWORDS),
        column=1,
    )


def _lex_once(text: str, params: Parameters, messages: list[tuple[str, str]]) -> Block:
    """The block of a line with parameters or expressions, read and evaluated in one
    pass (as :func:`_compile_line` then :func:`_evaluate_line` would give it)."""
    assignments: list[tuple[int | str, float]] = []
    pairs: list[tuple[str, float]] = []
    pos = 0
    n = len(text)
    while pos < n:
        ch = text[pos]
        if ch == "#":
            key, value, pos = read_assignment_once(text, pos, params)
            assignments.append((key, value))
            continue
        if "a" <= ch <= "z" or ch == "@" or ch == "^":
            value, pos = read_value_once(text, pos + 1, params)
            pairs.append((ch, value))
            continue
        raise NCError(_unexpected(ch, text), column=pos + 1)
    gcodes, mcodes, words = _sort_words(pairs)
    return Block(gcodes, mcodes, words, assignments, messages)


def _unexpected(ch: str, text: str) -> str:
    return f"unexpected character '{ch}' in '{text}': expected a word letter (A-Z, @, ^) or '#'"


def _compile_line(text: str) -> tuple[_Step, ...]:
    """Compile a line with parameters or expressions into its steps, in the order
    written. A malformed line ends with a step that raises its error."""
    steps: list[_Step] = []
    pos = 0
    n = len(text)
    while pos < n:
        ch = text[pos]
        if ch == "#":
            read_key, value, pos = compile_setting(text, pos)
            steps.append(("#", read_key, value))
        elif "a" <= ch <= "z" or ch == "@" or ch == "^":
            value, pos = compile_value(text, pos + 1)
            steps.append((ch, _NO_KEY, value))
        else:
            steps.append(("?", _NO_KEY, raising(_unexpected(ch, text), pos + 1)))
            break
        if pos == RAISES:
            break
    return tuple(steps)


def _evaluate_line(
    messages: Sequence[tuple[str, str]], steps: tuple[_Step, ...], params: Parameters
) -> Block:
    """The block of a compiled line, its values read from ``params`` now."""
    assignments: list[tuple[int | str, float]] = []
    pairs: list[tuple[str, float]] = []
    for letter, read_key, value in steps:
        if letter == "#":
            key = read_key(params)
            assignments.append((key, value(params)))
        else:
            pairs.append((letter, value(params)))
    gcodes, mcodes, words = _sort_words(pairs)
    return Block(gcodes, mcodes, words, assignments, list(messages))


def _gcode_key(value: float) -> int:
    if value == 1.0:
        return 10
    if value == 0.0:
        return 0
    key = round(value * 10.0)
    if abs(key - value * 10.0) > 1e-6 or key < 0:
        raise NCError(
            f"G{_fmt(value)} is not a G-code: G numbers are 0-999 with at most one decimal"
        )
    return key


def _mcode_key(value: float) -> int:
    key = round(value)
    if abs(key - value) > 1e-9 or key < 0:
        raise NCError(f"M{_fmt(value)} is not an M-code: M numbers are non-negative integers")
    return key


def _fmt(value: float) -> str:
    return f"{value:g}"
