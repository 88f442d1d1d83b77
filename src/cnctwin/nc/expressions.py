"""RS274NGC parameters and expressions, as LinuxCNC reads them.

The NC lexer prepares a line (comments removed, white space removed, lower-cased)
and calls :func:`read_value` where a word value starts and :func:`read_assignment`
where a ``#...=`` parameter setting starts. Both read directly from the string with a
hand-written recursive-descent reader (no token list), so a typical
``[#<zscale>*-25.372]`` costs a few microseconds. A place (text, position) met a second
time is compiled into closures (constants folded) that later reads only evaluate, with
the parameters of that moment; compiled places are kept in a bounded store.

Semantics follow the LinuxCNC G-code overview (sections *Parameters*, *Expressions*,
*Binary Operators*, *Functions*) and, where the prose is silent, the behaviour of its
interpreter (``interp_read.cc``, ``interp_execute.cc``):

- A *real value* is a number (``-1.5``, ``+.5``, ``3.``; no exponent), a parameter
  (``#123``, ``#<name>``, ``#[expr]``, ``##1``), a bracketed expression, a function
  call, or any of these after a unary ``-``/``+``. The sign belongs to the value, so
  it binds tighter than every binary operator: ``[-2**2]`` is 4.
- Binary operator precedence, highest first: ``**``; ``* / mod``; ``+ -``;
  ``eq ne gt ge lt le``; ``and or xor``. Equal precedence is evaluated left to right,
  ``**`` included: ``[2**3**2]`` is 64.
- ``eq``, ``ne``, ``ge`` and ``le`` treat values closer than 1e-6
  (:data:`EQUAL_TOLERANCE`, LinuxCNC ``TOLERANCE_EQUAL``) as equal; ``gt`` and ``lt``
  compare exactly. Comparisons and logic return 1.0 or 0.0; any non-zero value is true.
- ``a mod b`` is ``fmod(a, b)`` plus ``|b|`` when that is negative, so the result lies
  in ``[0, |b|)`` whatever the signs: ``[-7 mod 3]`` is 2, ``[7 mod -3]`` is 1.
- ``a ** b`` with ``a < 0`` needs an integer ``b``.
- Trigonometry is in degrees; ``atan[y]/[x]`` is the four-quadrant arc tangent.
  ``fix`` rounds down, ``fup`` up, ``round`` to nearest with halves away from zero.
  ``exists[#<name>]`` is 1.0 when the named parameter is defined; ``exists[#n]`` is 1.0
  when ``n`` is a valid parameter number.
- A parameter number must lie within 1e-4 of an integer in 1..:data:`MAX_PARAMETER`.
- Division (and ``mod``) by zero, ``sqrt``/``ln`` outside their domain, ``asin``/
  ``acos`` outside [-1, 1] and any result that is not a finite number raise
  :class:`~cnctwin.errors.NCError`. LinuxCNC checks finiteness only where a value ends;
  this reader also checks after every arithmetic operation, so an overflow inside an
  expression is reported where it happens.
- Nesting (brackets, ``#`` indirection, functions, unary signs) deeper than
  :data:`MAX_NESTING` levels is refused rather than allowed to exhaust the stack.

Every error raised while reading is an :class:`~cnctwin.errors.NCError` whose
``column`` is the 1-based index in the text of the offending character.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from typing import Any, Final, TypeVar

from cnctwin.errors import NCError
from cnctwin.nc.limits import check_number_text

__all__ = [
    "EQUAL_TOLERANCE",
    "MAX_NESTING",
    "MAX_PARAMETER",
    "SUBROUTINE_PARAMETERS",
    "RAISES",
    "CACHE_SIZE",
    "Evaluator",
    "Parameters",
    "Setting",
    "compile_setting",
    "compile_value",
    "expand_parameters",
    "raising",
    "read_assignment",
    "read_assignment_once",
    "read_value",
    "read_value_once",
]

#: Highest numbered parameter (numbered parameters are #1..#MAX_PARAMETER).
MAX_PARAMETER: Final = 5602
#: Numbered parameters #1..#SUBROUTINE_PARAMETERS are local to a subroutine call.
SUBROUTINE_PARAMETERS: Final = 30
#: Values closer than this compare equal under ``eq``, ``ne``, ``ge`` and ``le``.
EQUAL_TOLERANCE: Final = 1e-6
#: Deepest nesting of brackets, ``#`` indirections, functions and unary signs.
MAX_NESTING: Final = 100
#: A parameter number may differ from an integer by at most this much.
_INDEX_TOLERANCE: Final = 1e-4

_DEG: Final = math.pi / 180.0
_RAD: Final = 180.0 / math.pi
_isfinite: Final = math.isfinite
_number: Final = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)").match

# Binary operators: codes, and precedence (higher binds tighter). _CLOSE is the ']'
# that ends an expression; its precedence is below every operator's.
_POW, _MUL, _DIV, _MOD, _ADD, _SUB = range(6)
_EQ, _NE, _GT, _GE, _LT, _LE, _AND, _OR, _XOR = range(6, 15)
_CLOSE = 15
_PRECEDENCE = (5, 4, 4, 4, 3, 3, 2, 2, 2, 2, 2, 2, 1, 1, 1, 0)
_SPELLING = (
    "**",
    "*",
    "/",
    "mod",
    "+",
    "-",
    "eq",
    "ne",
    "gt",
    "ge",
    "lt",
    "le",
    "and",
    "or",
    "xor",
    "]",
)
_SYMBOL_OPERATORS = {"*": _MUL, "/": _DIV, "+": _ADD, "-": _SUB}
_WORD_OPERATORS = {
    "eq": _EQ,
    "ne": _NE,
    "gt": _GT,
    "ge": _GE,
    "lt": _LT,
    "le": _LE,
    "or": _OR,
    "mod": _MOD,
    "and": _AND,
    "xor": _XOR,
}
_OPERATOR_LIST = "**, *, /, mod, +, -, eq, ne, gt, ge, lt, le, and, or, xor"

_FUNCTIONS = frozenset(
    (
        "abs",
        "acos",
        "asin",
        "atan",
        "cos",
        "exp",
        "exists",
        "fix",
        "fup",
        "ln",
        "round",
        "sin",
        "sqrt",
        "tan",
    )
)
_FUNCTION_LIST = ", ".join(sorted(_FUNCTIONS))
_SIGNS = "+-"
_NUMBER_START = "0123456789."


def _fmt(value: float) -> str:
    """Format a value for an error message."""
    return f"{value:.10g}"


def _range_text() -> str:
    return f"numbered parameters are #1 to #{MAX_PARAMETER}"


def _undefined(name: str, column: int | None) -> NCError:
    return NCError(
        f"named parameter #<{name}> is not defined; assign it first, e.g. #<{name}> = 1",
        column=column,
    )


def _index(value: float, column: int | None) -> int:
    """Turn an evaluated parameter number into a valid index, or raise."""
    index = round(value)
    if abs(value - index) > _INDEX_TOLERANCE:
        raise NCError(
            f"parameter number #{_fmt(value)} is not an integer; {_range_text()}",
            column=column,
        )
    if not 1 <= index <= MAX_PARAMETER:
        raise NCError(f"parameter number #{index} is out of range; {_range_text()}", column=column)
    return index


def _clean_name(name: object) -> str:
    """Normalise a parameter name given through the Python API."""
    if not isinstance(name, str):
        raise NCError(
            f"parameter key {name!r} is neither a parameter number (int) nor a name (str)"
        )
    cleaned = "".join(name.split()).lower()
    if not cleaned or ">" in cleaned:
        raise NCError(
            f"parameter name {name!r} is not valid: a name is one or more characters "
            "other than '>', e.g. 'depth' for #<depth> or '_depth' for #<_depth>"
        )
    return cleaned


class Parameters:
    """The numbered and named parameters of an NC program.

    Numbered parameters #1..#:data:`MAX_PARAMETER` hold floats and read as 0.0 until
    set; the interpreter stores its system parameters there too (#5220 current
    coordinate system, #5221.. G54 offsets, ...) through ``params[5220]``. Named
    parameters are ``#<name>`` (local to the current subroutine call, or to the main
    program) and ``#<_name>`` (global); reading one that was never assigned is an
    error. Names are case-insensitive and ignore spaces: keys given here are
    lower-cased and stripped of white space, and are written without ``#<`` and ``>``.

    Numbered parameters #1..#30 are local to a subroutine call: :meth:`push_call`
    saves them and sets them to the call's arguments, :meth:`pop_call` restores them.

    Examples
    --------
    >>> params = Parameters()
    >>> params["xscale"] = 2.0
    >>> params[5220] = 1.0
    >>> read_value("[#<xscale>*3]", 0, params)
    (6.0, 13)
    """

    __slots__ = ("_numbered", "_globals", "_locals", "_frames")

    def __init__(self) -> None:
        self._numbered: list[float] = [0.0] * (MAX_PARAMETER + 1)
        self._globals: dict[str, float] = {}
        self._locals: dict[str, float] = {}
        self._frames: list[tuple[list[float], dict[str, float]]] = []

    def __getitem__(self, key: int | str) -> float:
        """Value of ``#key`` (an int) or ``#<key>`` (a str).

        Raises
        ------
        NCError
            For a number outside 1..MAX_PARAMETER, or a name never assigned.
        """
        if isinstance(key, int):
            return self._numbered[_index(key, None)]
        name = _clean_name(key)
        value = (self._globals if name[0] == "_" else self._locals).get(name)
        if value is None:
            raise _undefined(name, None)
        return value

    def __setitem__(self, key: int | str, value: float) -> None:
        """Set ``#key`` (an int) or ``#<key>`` (a str) to ``value``.

        A name that starts with ``_`` is global; any other name is local to the
        current subroutine call (or to the main program).

        Raises
        ------
        NCError
            For an invalid key, or a value that is not a finite number.
        """
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise NCError(f"parameter value {value!r} is not a number") from None
        if not _isfinite(number):
            raise NCError(f"parameter value {value!r} is not a finite number")
        if isinstance(key, int):
            self._numbered[_index(key, None)] = number
            return
        name = _clean_name(key)
        (self._globals if name[0] == "_" else self._locals)[name] = number

    def exists(self, name: str) -> bool:
        """Whether the named parameter ``#<name>`` is defined where the program is now.

        Parameters
        ----------
        name
            The name without ``#<`` and ``>``, e.g. ``"depth"`` or ``"_depth"``.
        """
        cleaned = _clean_name(name)
        return cleaned in (self._globals if cleaned[0] == "_" else self._locals)

    @property
    def call_depth(self) -> int:
        """Number of subroutine calls open (0 in the main program)."""
        return len(self._frames)

    def push_call(self, args: Sequence[float]) -> None:
        """Enter a subroutine call.

        Saves #1..#30 and the caller's local named parameters, sets #1..#len(args)
        to ``args`` and the rest of #1..#30 to 0.0 (as LinuxCNC does), and opens an
        empty scope for local named parameters.

        Parameters
        ----------
        args
            The call's arguments, at most 30.

        Raises
        ------
        NCError
            For more than 30 arguments or one that is not a finite number.
        """
        if len(args) > SUBROUTINE_PARAMETERS:
            raise NCError(
                f"a subroutine call takes at most {SUBROUTINE_PARAMETERS} arguments, "
                f"got {len(args)}"
            )
        values = [float(a) for a in args]
        for position, value in enumerate(values, start=1):
            if not _isfinite(value):
                raise NCError(f"subroutine argument {position} is {value}, not a finite number")
        numbered = self._numbered
        self._frames.append((numbered[1 : SUBROUTINE_PARAMETERS + 1], self._locals))
        values.extend([0.0] * (SUBROUTINE_PARAMETERS - len(values)))
        numbered[1 : SUBROUTINE_PARAMETERS + 1] = values
        self._locals = {}

    def pop_call(self) -> None:
        """Leave the innermost subroutine call, restoring #1..#30 and local names.

        Raises
        ------
        NCError
            If no call is open.
        """
        if not self._frames:
            raise NCError("return from a subroutine, but no subroutine call is open")
        saved, self._locals = self._frames.pop()
        self._numbered[1 : SUBROUTINE_PARAMETERS + 1] = saved


def read_value(text: str, pos: int, params: Parameters) -> tuple[float, int]:
    """Read one real value starting at ``text[pos]``.

    Parameters
    ----------
    text
        A line prepared by the lexer: no comments, no white space, lower case.
    pos
        0-based index where the value starts.
    params
        The parameter store that ``#`` references read.

    Returns
    -------
    value : float
        The value, always finite.
    end : int
        Index just after the value.

    Raises
    ------
    NCError
        For any malformed or unevaluable value; ``column`` is the 1-based index in
        ``text`` of the offending character.

    Examples
    --------
    >>> read_value("g1x[1+2*3]y2", 3, Parameters())
    (7.0, 10)
    """
    n = len(text)
    if not 0 <= pos <= n:
        raise NCError(f"start index {pos} is outside the text (0 to {n})")
    key = (text, pos)
    compiled = _COMPILED.get(key, _UNSEEN)
    if compiled is _UNSEEN:  # first sight: read and evaluate in one pass
        _remember(key, None)
        return _value(text, pos, n, params, 0)
    if compiled is None:  # second sight: compile, to evaluate from now on
        compiled = _remember(key, compile_value(text, pos))
    evaluate, end = compiled
    return evaluate(params), end


def compile_value(text: str, pos: int) -> tuple[Evaluator, int]:
    """Compile the real value starting at ``text[pos]`` (see :func:`read_value`).

    Parameters
    ----------
    text
        A line prepared by the lexer: no comments, no white space, lower case.
    pos
        0-based index where the value starts, 0 to ``len(text)``.

    Returns
    -------
    evaluate : Evaluator
        Called with the parameters, returns the value (always finite) as
        :func:`read_value` would read it then, or raises its NCError.
    end : int
        Index just after the value; :data:`RAISES` when ``evaluate`` always raises
        (the text is malformed there, or a constant part cannot be evaluated).
    """
    node, end = _compile_value(text, pos, len(text), 0)
    return _evaluator(node), end


def expand_parameters(text: str, params: Parameters) -> str:
    """``(DEBUG, ...)``/``(PRINT, ...)`` text with each ``#n``, ``#<name>`` or ``#[expr]``
    replaced by its value written ``%.6f`` (LinuxCNC); a reference that cannot be read
    is left as written.

    Examples
    --------
    >>> params = Parameters()
    >>> params[1] = 2.5
    >>> expand_parameters("X is #1", params)
    'X is 2.500000'
    """
    out: list[str] = []
    pos = 0
    while True:
        at = text.find("#", pos)
        if at < 0:
            out.append(text[pos:])
            return "".join(out)
        out.append(text[pos:at])
        end = at + 1
        if text[end : end + 1] == "<":
            close = text.find(">", end)
            end = close + 1 if close > 0 else len(text)
        elif text[end : end + 1] == "[":
            close = text.find("]", end)
            end = close + 1 if close > 0 else len(text)
        else:
            while end < len(text) and text[end] in "0123456789.":
                end += 1
        ref = "".join(text[at:end].split()).lower()
        try:
            value, used = read_value(ref, 0, params)
            out.append(f"{value:.6f}" + ref[used:])
        except NCError:
            out.append(text[at:end])
        pos = end


def read_assignment(text: str, pos: int, params: Parameters) -> tuple[int | str, float, int]:
    """Read a parameter setting ``#key=value`` starting at ``text[pos]``.

    Nothing is stored: RS274NGC applies all settings of a line after the whole line
    has been read, so the caller stores them.

    Parameters
    ----------
    text
        A line prepared by the lexer: no comments, no white space, lower case.
    pos
        0-based index of the ``#``.
    params
        The parameter store that the key and value expressions read.

    Returns
    -------
    key : int or str
        The parameter number (``#12=``, ``#[1+2]=``, ``##1=``) or the name without
        ``#<`` and ``>`` (``#<depth>=`` gives ``"depth"``).
    value : float
        The value to assign.
    end : int
        Index just after the value.

    Raises
    ------
    NCError
        For a malformed setting, an invalid parameter number or an unevaluable value;
        ``column`` is the 1-based index of the offending character.
    """
    n = len(text)
    if not 0 <= pos <= n:
        raise NCError(f"start index {pos} is outside the text (0 to {n})")
    place = (text, pos)
    compiled = _COMPILED_SETTINGS.get(place, _UNSEEN)
    if compiled is _UNSEEN:
        _remember_setting(place, None)
        return read_assignment_once(text, pos, params)
    if compiled is None:
        compiled = _remember_setting(place, compile_setting(text, pos))
    read_key, evaluate, end = compiled
    key = read_key(params)
    return key, evaluate(params), end


def read_value_once(text: str, pos: int, params: Parameters) -> tuple[float, int]:
    """:func:`read_value` reading and evaluating in one pass, nothing compiled or kept:
    for text met once (the lexer compiles a line met again)."""
    return _value(text, pos, len(text), params, 0)


def read_assignment_once(text: str, pos: int, params: Parameters) -> tuple[int | str, float, int]:
    """:func:`read_assignment` reading and evaluating in one pass, nothing compiled or
    kept."""
    n = len(text)
    if pos >= n or text[pos] != "#":
        raise NCError(
            "expected a parameter setting such as #1=2 or #<name>=2"
            + (f", found '{text[pos]}'" if pos < n else ", found the end of the line"),
            column=pos + 1,
        )
    key: int | str
    after = pos + 1
    if after < n and text[after] == "<":
        key, after = _name(text, pos, n)
    else:
        number, after = _value(text, after, n, params, 1)
        key = _index(number, pos + 1)
    if after >= n or text[after] != "=":
        raise NCError(
            "expected '=' after the parameter in a setting such as #1=2, found "
            + (f"'{text[after]}'" if after < n else "the end of the line"),
            column=after + 1,
        )
    value, end = _value(text, after + 1, n, params, 0)
    return key, value, end


def _name(text: str, hash_pos: int, n: int) -> tuple[str, int]:
    """Read ``<name>`` after the ``#`` at ``hash_pos``; return the name and its end."""
    close = text.find(">", hash_pos + 2)
    if close < 0:
        raise NCError(
            "named parameter is missing its closing '>': write #<name>", column=hash_pos + 1
        )
    if close == hash_pos + 2:
        raise NCError(
            "empty parameter name '#<>': write a name such as #<depth>", column=hash_pos + 1
        )
    return text[hash_pos + 2 : close], close + 1


def _value(text: str, pos: int, n: int, params: Parameters, depth: int) -> tuple[float, int]:
    """Read a real value at ``pos`` (see :func:`read_value`)."""
    if pos >= n:
        raise NCError(
            "expected a value (number, #parameter, [expression] or function) but the line ends",
            column=pos + 1,
        )
    if depth > MAX_NESTING:
        raise NCError(f"expression nested deeper than {MAX_NESTING} levels", column=pos + 1)
    c = text[pos]
    if c == "[":
        return _expression(text, pos, n, params, depth)
    if c == "#":
        if pos + 1 < n and text[pos + 1] == "<":
            name, end = _name(text, pos, n)
            value = (params._globals if name[0] == "_" else params._locals).get(name)
            if value is None:
                raise _undefined(name, pos + 1)
            return value, end
        number, end = _value(text, pos + 1, n, params, depth + 1)
        return params._numbered[_index(number, pos + 1)], end
    if c in _SIGNS and pos + 1 < n and text[pos + 1] not in _NUMBER_START:
        value, end = _value(text, pos + 1, n, params, depth + 1)
        return (-value if c == "-" else value), end
    if "a" <= c <= "z":
        return _function(text, pos, n, params, depth)
    found = _number(text, pos)
    if found is None:
        raise NCError(
            f"expected a value (number, #parameter, [expression] or function), found '{c}'",
            column=pos + 1,
        )
    literal = found.group()
    check_number_text(literal, pos + 1)  # so that float() is finite
    return float(literal), found.end()


def _expression(text: str, pos: int, n: int, params: Parameters, depth: int) -> tuple[float, int]:
    """Evaluate the bracketed expression whose '[' is at ``pos``.

    Operator precedence is resolved with an operand stack and an operator stack, so
    the Python stack grows only with bracket nesting, not with expression length.
    """
    value, end = _value(text, pos + 1, n, params, depth + 1)
    op, after = _operator(text, end, n, pos)
    if op == _CLOSE:
        return value, after
    values = [value]
    pending: list[tuple[int, int]] = []  # (operator, its 0-based position)
    while True:
        prec = _PRECEDENCE[op]
        while pending and _PRECEDENCE[pending[-1][0]] >= prec:
            top, top_pos = pending.pop()
            right = values.pop()
            values[-1] = _apply(top, values[-1], right, top_pos)
        if op == _CLOSE:
            return values[0], after
        pending.append((op, end))
        value, end = _value(text, after, n, params, depth + 1)
        values.append(value)
        op, after = _operator(text, end, n, pos)


def _function(text: str, pos: int, n: int, params: Parameters, depth: int) -> tuple[float, int]:
    """Evaluate the function call whose name starts at ``pos``."""
    bracket = pos
    while bracket < n and "a" <= text[bracket] <= "z":
        bracket += 1
    name = text[pos:bracket]
    if name not in _FUNCTIONS:
        raise NCError(
            f"unknown function or word '{name}': expected a value or one of the "
            f"functions {_FUNCTION_LIST}",
            column=pos + 1,
        )
    if bracket >= n or text[bracket] != "[":
        raise NCError(
            f"function {name} must be followed by '[', e.g. {name}[1]"
            if name != "atan"
            else "function atan must be followed by '[', e.g. atan[1]/[2]",
            column=bracket + 1,
        )
    if name == "exists":
        return _exists(text, bracket, n, params, depth)
    x, end = _expression(text, bracket, n, params, depth + 1)
    if name == "atan":
        if end + 1 >= n or text[end] != "/" or text[end + 1] != "[":
            raise NCError(
                "atan takes two arguments written atan[y]/[x]; expected '/[' after "
                f"atan[{_fmt(x)}]",
                column=end + 1,
            )
        x2, end = _expression(text, end + 1, n, params, depth + 1)
        return math.atan2(x, x2) * _RAD, end
    return _function_value(name, x, pos + 1), end


def _exists(text: str, bracket: int, n: int, params: Parameters, depth: int) -> tuple[float, int]:
    """Evaluate ``exists[#<name>]`` or ``exists[#n]`` whose '[' is at ``bracket``."""
    hash_pos = bracket + 1
    if hash_pos >= n or text[hash_pos] != "#":
        raise NCError("exists takes a parameter, e.g. exists[#<depth>]", column=hash_pos + 1)
    if hash_pos + 1 < n and text[hash_pos + 1] == "<":
        name, end = _name(text, hash_pos, n)
        found = name in (params._globals if name[0] == "_" else params._locals)
    else:
        number, end = _value(text, hash_pos + 1, n, params, depth + 1)
        index = round(number)
        if abs(number - index) > _INDEX_TOLERANCE:
            raise NCError(
                f"parameter number #{_fmt(number)} is not an integer; {_range_text()}",
                column=hash_pos + 1,
            )
        found = 1 <= index <= MAX_PARAMETER
    if end >= n or text[end] != "]":
        raise NCError(
            "exists takes a single parameter; expected ']' after it, e.g. exists[#<depth>]",
            column=end + 1,
        )
    return (1.0 if found else 0.0), end + 1


def _operator(text: str, pos: int, n: int, open_pos: int) -> tuple[int, int]:
    """Read the binary operator or ']' at ``pos``; return its code and its end."""
    if pos >= n:
        raise NCError(f"missing ']' to close the '[' at column {open_pos + 1}", column=pos + 1)
    c = text[pos]
    if c == "]":
        return _CLOSE, pos + 1
    op = _SYMBOL_OPERATORS.get(c)
    if op is not None:
        if op == _MUL and pos + 1 < n and text[pos + 1] == "*":
            return _POW, pos + 2
        return op, pos + 1
    op = _WORD_OPERATORS.get(text[pos : pos + 2])
    if op is not None:
        return op, pos + 2
    op = _WORD_OPERATORS.get(text[pos : pos + 3])
    if op is not None:
        return op, pos + 3
    raise NCError(
        f"expected a binary operator ({_OPERATOR_LIST}) or ']' to close the '[' at "
        f"column {open_pos + 1}, found '{c}'",
        column=pos + 1,
    )


def _apply(op: int, a: float, b: float, pos: int) -> float:
    """Apply binary operator ``op`` to ``a`` and ``b``; ``pos`` locates errors."""
    if op == _MUL:
        result = a * b
    elif op == _ADD:
        result = a + b
    elif op == _SUB:
        result = a - b
    elif op == _DIV:
        if b == 0.0:
            raise NCError(
                f"division by zero: {_fmt(a)} / {_fmt(b)}; the divisor must not be 0",
                column=pos + 1,
            )
        result = a / b
    elif op == _MOD:
        if b == 0.0:
            raise NCError(
                f"modulo by zero: {_fmt(a)} mod {_fmt(b)}; the divisor must not be 0",
                column=pos + 1,
            )
        result = math.fmod(a, b)
        if result < 0.0:
            result += abs(b)
    elif op == _POW:
        if a < 0.0 and b != math.floor(b):
            raise NCError(
                f"{_fmt(a)} ** {_fmt(b)}: a negative number can only be raised to an integer power",
                column=pos + 1,
            )
        if a == 0.0 and b < 0.0:
            raise NCError(
                f"{_fmt(a)} ** {_fmt(b)}: zero cannot be raised to a negative power",
                column=pos + 1,
            )
        try:
            result = math.pow(a, b)
        except OverflowError:
            result = math.inf
    elif op == _EQ:
        return 1.0 if abs(a - b) < EQUAL_TOLERANCE else 0.0
    elif op == _NE:
        return 0.0 if abs(a - b) < EQUAL_TOLERANCE else 1.0
    elif op == _GT:
        return 1.0 if a > b else 0.0
    elif op == _GE:
        return 1.0 if a >= b or abs(a - b) < EQUAL_TOLERANCE else 0.0
    elif op == _LT:
        return 1.0 if a < b else 0.0
    elif op == _LE:
        return 1.0 if a <= b or abs(a - b) < EQUAL_TOLERANCE else 0.0
    elif op == _AND:
        return 1.0 if a != 0.0 and b != 0.0 else 0.0
    elif op == _OR:
        return 1.0 if a != 0.0 or b != 0.0 else 0.0
    else:  # _XOR
        return 1.0 if (a != 0.0) != (b != 0.0) else 0.0
    if not _isfinite(result):
        raise NCError(
            f"{_fmt(a)} {_SPELLING[op]} {_fmt(b)} overflows: the result is not a finite number",
            column=pos + 1,
        )
    return result


# ---------------------------------------------------------------------------------------
# Compiled reading. A value is read once per place of a line (text, position) into a
# node: a float when it is a constant, else an Evaluator that computes it from the
# parameters at the time it is called, so a line repeated by an O-word loop, or written
# again later, is not read again. Every error, malformed text included, becomes a node
# that raises when it is evaluated, placed where the reader met it: the nodes before it
# are evaluated first, so that a line raises the same error, at the same column, as a
# reader that evaluates while it reads (LinuxCNC's order: ``[1/0+]`` is a division by
# zero, not a missing value). A piece whose evaluation raises ends at _STOP.

#: A value compiled for one place of one line; called with the parameters, it returns the
#: value or raises the error of that place.
Evaluator = Callable[[Parameters], float]
Node = float | Evaluator
#: A compiled parameter setting: the key's reader, the value's evaluator and the end.
Setting = tuple[Callable[[Parameters], int | str], Evaluator, int]

#: The end of a compiled piece that always raises when evaluated.
RAISES = -1
_STOP = RAISES
_C = TypeVar("_C", tuple["Evaluator", int], None)
_S = TypeVar("_S", "Setting", None)
#: Most compiled places kept; the store is emptied when full, so memory stays bounded
#: whatever the program's length.
CACHE_SIZE = 4096
#: Compiled places by (text, position); None for a place seen once (read directly then:
#: compiling costs about one more reading, so only places met again are compiled).
_COMPILED: dict[tuple[str, int], tuple[Evaluator, int] | None] = {}
_COMPILED_SETTINGS: dict[tuple[str, int], Setting | None] = {}
_UNSEEN: Any = object()


def _remember(key: tuple[str, int], compiled: _C) -> _C:
    if len(_COMPILED) >= CACHE_SIZE:
        _COMPILED.clear()
    _COMPILED[key] = compiled
    return compiled


def _remember_setting(key: tuple[str, int], compiled: _S) -> _S:
    if len(_COMPILED_SETTINGS) >= CACHE_SIZE:
        _COMPILED_SETTINGS.clear()
    _COMPILED_SETTINGS[key] = compiled
    return compiled


def _evaluator(node: Node) -> Evaluator:
    if isinstance(node, float):
        constant = node
        return lambda params: constant
    return node


def raising(message: str, column: int | None) -> Evaluator:
    """An evaluator that raises a new NCError(message, column) each time it is evaluated."""

    def evaluate(params: Parameters) -> float:
        raise NCError(message, column=column)

    return evaluate


def _failing(error: NCError) -> Evaluator:
    return raising(error.message, error.column)


def _then(first: Sequence[Node], last: Evaluator) -> Evaluator:
    """Evaluate the nodes ``first`` in order (for the errors they raise), then ``last``."""
    before = [node for node in first if not isinstance(node, float)]

    def evaluate(params: Parameters) -> float:
        for node in before:
            node(params)
        return last(params)

    return evaluate


def _compile_value(text: str, pos: int, n: int, depth: int) -> tuple[Node, int]:
    """Compile the real value at ``pos`` (see :func:`read_value`)."""
    if pos >= n:
        return raising(
            "expected a value (number, #parameter, [expression] or function) but the line ends",
            pos + 1,
        ), _STOP
    if depth > MAX_NESTING:
        return raising(f"expression nested deeper than {MAX_NESTING} levels", pos + 1), _STOP
    c = text[pos]
    if c == "[":
        return _compile_expression(text, pos, n, depth)
    if c == "#":
        return _compile_parameter(text, pos, n, depth)
    if c in _SIGNS and pos + 1 < n and text[pos + 1] not in _NUMBER_START:
        inner, end = _compile_value(text, pos + 1, n, depth + 1)
        if end == _STOP or c == "+":
            return inner, end
        if isinstance(inner, float):
            return -inner, end
        negated = inner
        return (lambda params: -negated(params)), end
    if "a" <= c <= "z":
        return _compile_function(text, pos, n, depth)
    found = _number(text, pos)
    if found is None:
        return raising(
            f"expected a value (number, #parameter, [expression] or function), found '{c}'",
            pos + 1,
        ), _STOP
    literal = found.group()
    try:
        check_number_text(literal, pos + 1)  # so that float() is finite
    except NCError as err:
        return _failing(err), _STOP
    return float(literal), found.end()


def _compile_parameter(text: str, pos: int, n: int, depth: int) -> tuple[Node, int]:
    """Compile ``#<name>``, ``#n``, ``#[expr]`` or ``##n`` whose '#' is at ``pos``."""
    column = pos + 1
    if pos + 1 < n and text[pos + 1] == "<":
        try:
            name, end = _name(text, pos, n)
        except NCError as err:
            return _failing(err), _STOP
        if name[0] == "_":

            def named(params: Parameters) -> float:
                value = params._globals.get(name)
                if value is None:
                    raise _undefined(name, column)
                return value

        else:

            def named(params: Parameters) -> float:
                value = params._locals.get(name)
                if value is None:
                    raise _undefined(name, column)
                return value

        return named, end
    number, end = _compile_value(text, pos + 1, n, depth + 1)
    if end == _STOP:
        return number, end
    if isinstance(number, float):
        try:
            index = _index(number, column)
        except NCError as err:
            return _failing(err), _STOP
        return (lambda params: params._numbered[index]), end
    indirect = number
    return (lambda params: params._numbered[_index(indirect(params), column)]), end


def _compile_expression(text: str, pos: int, n: int, depth: int) -> tuple[Node, int]:
    """Compile the bracketed expression whose '[' is at ``pos``.

    Operator precedence is resolved with an operand stack and an operator stack, as the
    operators are met; the nodes evaluate their operands and apply their operators in
    that same order.
    """
    value, end = _compile_value(text, pos + 1, n, depth + 1)
    if end == _STOP:
        return value, end
    values = [value]
    try:
        op, after = _operator(text, end, n, pos)
    except NCError as err:
        return _then(values, _failing(err)), _STOP
    if op == _CLOSE:
        return value, after
    pending: list[tuple[int, int]] = []  # (operator, its 0-based position)
    while True:
        prec = _PRECEDENCE[op]
        while pending and _PRECEDENCE[pending[-1][0]] >= prec:
            top, top_pos = pending.pop()
            right = values.pop()
            values[-1] = _binary(top, values[-1], right, top_pos)
        if op == _CLOSE:
            return values[0], after
        pending.append((op, end))
        value, end = _compile_value(text, after, n, depth + 1)
        if end == _STOP:
            return _then(values, _evaluator(value)), _STOP
        values.append(value)
        try:
            op, after = _operator(text, end, n, pos)
        except NCError as err:
            return _then(values, _failing(err)), _STOP


def _binary(op: int, a: Node, b: Node, pos: int) -> Node:
    """The node of ``a op b``: :func:`_apply` of the operands' values."""
    if isinstance(a, float) and isinstance(b, float):
        try:
            return _apply(op, a, b, pos)
        except NCError as err:
            return _failing(err)
    if isinstance(b, float) and op in (_ADD, _SUB, _MUL):
        return _binary_constant(op, _evaluator(a), b, pos)
    left, right = _evaluator(a), _evaluator(b)
    if op == _ADD:

        def evaluate(params: Parameters) -> float:
            x = left(params)
            y = right(params)
            result = x + y
            return result if _isfinite(result) else _apply(_ADD, x, y, pos)

    elif op == _SUB:

        def evaluate(params: Parameters) -> float:
            x = left(params)
            y = right(params)
            result = x - y
            return result if _isfinite(result) else _apply(_SUB, x, y, pos)

    elif op == _MUL:

        def evaluate(params: Parameters) -> float:
            x = left(params)
            y = right(params)
            result = x * y
            return result if _isfinite(result) else _apply(_MUL, x, y, pos)

    else:

        def evaluate(params: Parameters) -> float:
            return _apply(op, left(params), right(params), pos)

    return evaluate


def _binary_constant(op: int, left: Evaluator, y: float, pos: int) -> Evaluator:
    """The node of ``left op y`` for ``+``, ``-`` and ``*`` with a constant ``y``."""
    if op == _ADD:

        def evaluate(params: Parameters) -> float:
            x = left(params)
            result = x + y
            return result if _isfinite(result) else _apply(_ADD, x, y, pos)

    elif op == _SUB:

        def evaluate(params: Parameters) -> float:
            x = left(params)
            result = x - y
            return result if _isfinite(result) else _apply(_SUB, x, y, pos)

    else:

        def evaluate(params: Parameters) -> float:
            x = left(params)
            result = x * y
            return result if _isfinite(result) else _apply(_MUL, x, y, pos)

    return evaluate


def _compile_function(text: str, pos: int, n: int, depth: int) -> tuple[Node, int]:
    """Compile the function call whose name starts at ``pos``."""
    bracket = pos
    while bracket < n and "a" <= text[bracket] <= "z":
        bracket += 1
    name = text[pos:bracket]
    if name not in _FUNCTIONS:
        return raising(
            f"unknown function or word '{name}': expected a value or one of the "
            f"functions {_FUNCTION_LIST}",
            pos + 1,
        ), _STOP
    if bracket >= n or text[bracket] != "[":
        return raising(
            f"function {name} must be followed by '[', e.g. {name}[1]"
            if name != "atan"
            else "function atan must be followed by '[', e.g. atan[1]/[2]",
            bracket + 1,
        ), _STOP
    if name == "exists":
        return _compile_exists(text, bracket, n, depth)
    x, end = _compile_expression(text, bracket, n, depth + 1)
    if end == _STOP:
        return x, end
    if name == "atan":
        return _compile_atan(text, x, end, n, depth)
    column = pos + 1
    if isinstance(x, float):
        try:
            return _function_value(name, x, column), end
        except NCError as err:
            return _failing(err), _STOP
    argument = x
    return (lambda params: _function_value(name, argument(params), column)), end


def _compile_atan(text: str, y: Node, end: int, n: int, depth: int) -> tuple[Node, int]:
    """Compile ``/[x]`` of ``atan[y]/[x]``, ``y`` compiled and ending at ``end``."""
    first = _evaluator(y)
    if end + 1 >= n or text[end] != "/" or text[end + 1] != "[":
        column = end + 1

        def missing(params: Parameters) -> float:
            raise NCError(
                "atan takes two arguments written atan[y]/[x]; expected '/[' after "
                f"atan[{_fmt(first(params))}]",
                column=column,
            )

        return missing, _STOP
    x, end = _compile_expression(text, end + 1, n, depth + 1)
    if end == _STOP:
        return _then([y], _evaluator(x)), _STOP
    second = _evaluator(x)
    return (lambda params: math.atan2(first(params), second(params)) * _RAD), end


def _function_value(name: str, x: float, column: int) -> float:
    """``name[x]`` for the functions of one argument; ``column`` locates errors."""
    if name == "sin":
        return math.sin(x * _DEG)
    if name == "cos":
        return math.cos(x * _DEG)
    if name == "tan":
        return math.tan(x * _DEG)
    if name == "abs":
        return abs(x)
    if name == "sqrt":
        if x < 0.0:
            raise NCError(
                f"sqrt[{_fmt(x)}]: the argument of sqrt must not be negative", column=column
            )
        return math.sqrt(x)
    if name == "asin" or name == "acos":
        if not -1.0 <= x <= 1.0:
            raise NCError(
                f"{name}[{_fmt(x)}]: the argument of {name} must lie in [-1, 1]",
                column=column,
            )
        return (math.asin(x) if name == "asin" else math.acos(x)) * _RAD
    if name == "ln":
        if x <= 0.0:
            raise NCError(f"ln[{_fmt(x)}]: the argument of ln must be positive", column=column)
        return math.log(x)
    if name == "exp":
        try:
            return math.exp(x)
        except OverflowError:
            raise NCError(
                f"exp[{_fmt(x)}] overflows: the argument must be at most about 709.78",
                column=column,
            ) from None
    if name == "fix":
        return float(math.floor(x))
    if name == "fup":
        return float(math.ceil(x))
    # round: to nearest, halves away from zero (LinuxCNC), not Python's half-to-even.
    magnitude = math.floor(abs(x) + 0.5)
    return float(magnitude if x >= 0.0 else -magnitude)


def _compile_exists(text: str, bracket: int, n: int, depth: int) -> tuple[Node, int]:
    """Compile ``exists[#<name>]`` or ``exists[#n]`` whose '[' is at ``bracket``."""
    hash_pos = bracket + 1
    if hash_pos >= n or text[hash_pos] != "#":
        return raising("exists takes a parameter, e.g. exists[#<depth>]", hash_pos + 1), _STOP
    closed = "exists takes a single parameter; expected ']' after it, e.g. exists[#<depth>]"
    if hash_pos + 1 < n and text[hash_pos + 1] == "<":
        try:
            name, end = _name(text, hash_pos, n)
        except NCError as err:
            return _failing(err), _STOP
        if end >= n or text[end] != "]":
            return raising(closed, end + 1), _STOP
        if name[0] == "_":
            return (lambda params: 1.0 if name in params._globals else 0.0), end + 1
        return (lambda params: 1.0 if name in params._locals else 0.0), end + 1
    number, end = _compile_value(text, hash_pos + 1, n, depth + 1)
    if end == _STOP:
        return number, end
    argument = _evaluator(number)
    bracket_end = end if end < n and text[end] == "]" else _STOP

    def exists(params: Parameters) -> float:
        value = argument(params)
        index = round(value)
        if abs(value - index) > _INDEX_TOLERANCE:
            raise NCError(
                f"parameter number #{_fmt(value)} is not an integer; {_range_text()}",
                column=hash_pos + 1,
            )
        if bracket_end == _STOP:
            raise NCError(closed, column=end + 1)
        return 1.0 if 1 <= index <= MAX_PARAMETER else 0.0

    return exists, (_STOP if bracket_end == _STOP else end + 1)


def compile_setting(text: str, pos: int) -> Setting:
    """Compile the parameter setting whose '#' is at ``text[pos]`` (see
    :func:`read_assignment`).

    Returns
    -------
    read_key : callable
        Called with the parameters, returns the key (parameter number or name).
    evaluate : Evaluator
        Called with the parameters after ``read_key``, returns the value to assign.
    end : int
        Index just after the value; :data:`RAISES` when the setting is malformed: then
        ``read_key`` raises, or ``evaluate`` does, the error that reading it raises.
    """
    n = len(text)
    unused = raising("internal: a malformed setting's value is not evaluated", None)
    if pos >= n or text[pos] != "#":
        message = "expected a parameter setting such as #1=2 or #<name>=2" + (
            f", found '{text[pos]}'" if pos < n else ", found the end of the line"
        )
        return _keyraising(raising(message, pos + 1)), unused, _STOP
    read_key: Callable[[Parameters], int | str]
    after = pos + 1
    if after < n and text[after] == "<":
        try:
            name, after = _name(text, pos, n)
        except NCError as err:
            return _keyraising(_failing(err)), unused, _STOP
        read_key = lambda params: name  # noqa: E731
    else:
        number, after = _compile_value(text, after, n, 1)
        if after == _STOP:
            return _keyraising(_evaluator(number)), unused, _STOP
        column = pos + 1
        if isinstance(number, float):
            try:
                index = _index(number, column)
            except NCError as err:
                return _keyraising(_failing(err)), unused, _STOP
            read_key = lambda params: index  # noqa: E731
        else:
            indirect = number
            read_key = lambda params: _index(indirect(params), column)  # noqa: E731
    if after >= n or text[after] != "=":
        message = "expected '=' after the parameter in a setting such as #1=2, found " + (
            f"'{text[after]}'" if after < n else "the end of the line"
        )
        key_only = read_key
        equals_column = after + 1

        def bad_key(params: Parameters) -> int | str:
            key_only(params)
            raise NCError(message, column=equals_column)

        return bad_key, unused, _STOP
    value, end = _compile_value(text, after + 1, n, 0)
    return read_key, _evaluator(value), end


def _keyraising(raising: Evaluator) -> Callable[[Parameters], int | str]:
    """A key reader that raises the error of ``raising``."""

    def read_key(params: Parameters) -> int | str:
        raising(params)
        raise AssertionError("unreachable: the node raises")

    return read_key
