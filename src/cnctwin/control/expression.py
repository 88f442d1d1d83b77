"""A safe arithmetic and logical expression over named signals, for rule conditions and values.

An expression is parsed once (``ast.parse``) and every node checked against a whitelist:
names, numbers (and ``true``/``false``), comparisons (``<  <=  >  >=  ==  !=``, chained),
``and``, ``or``, ``not``, ``+ - * /``, unary ``-``/``+``, parentheses and the functions
``abs``, ``min`` and ``max``. Nothing else parses: no attributes, subscripts, strings, lambdas
or other calls, so evaluating a checked expression cannot reach anything but its names'
values. The checked tree is compiled once and evaluated with an empty set of builtins.
"""

from __future__ import annotations

import ast
import math
from collections.abc import Collection, Mapping
from types import CodeType

from cnctwin.errors import ConfigError

__all__ = ["Expression", "FUNCTIONS"]

#: The functions an expression may call, with their allowed argument counts (min, max).
FUNCTIONS: dict[str, tuple[int, int]] = {"abs": (1, 1), "min": (2, 64), "max": (2, 64)}

_ALLOWED_NODES = (
    ast.Expression,
    ast.BoolOp,
    ast.And,
    ast.Or,
    ast.UnaryOp,
    ast.Not,
    ast.USub,
    ast.UAdd,
    ast.BinOp,
    ast.Add,
    ast.Sub,
    ast.Mult,
    ast.Div,
    ast.Compare,
    ast.Lt,
    ast.LtE,
    ast.Gt,
    ast.GtE,
    ast.Eq,
    ast.NotEq,
    ast.Name,
    ast.Load,
    ast.Constant,
    ast.Call,
)
_LOGICAL = (ast.Compare, ast.BoolOp)
_GLOBALS: dict[str, object] = {"__builtins__": {}, "abs": abs, "min": min, "max": max}


class _TomlBooleans(ast.NodeTransformer):
    """Reads the names ``true`` and ``false`` (TOML's spelling) as the constants."""

    def visit_Name(self, node: ast.Name) -> ast.AST:
        if node.id in ("true", "false"):
            return ast.copy_location(ast.Constant(node.id == "true"), node)
        return node


class Expression:
    """A checked, compiled expression.

    Parameters
    ----------
    text
        The expression, e.g. ``"measured_force_xy_n < force_band_low_n and feed_mm_min > 10"``.
    valid_names
        The names it may use (signals and predictions); ``None`` accepts any identifier
        (unknown names then make :meth:`evaluate` raise ``KeyError``).
    origin
        Where the expression comes from, for error messages (``"rule 'hole' condition"``).
    logical
        Require a condition: a comparison, ``and``/``or``, ``not`` or ``true``/``false`` at
        the top, so that ``"force_n - 5"`` is refused rather than read as "non-zero".

    Attributes
    ----------
    names
        The signal names the expression reads, in order of first appearance.

    Raises
    ------
    ConfigError
        On a syntax error, a construct outside the whitelist or an unknown name.
    """

    __slots__ = ("_code", "logical", "names", "origin", "text")

    def __init__(
        self,
        text: str,
        valid_names: Collection[str] | None = None,
        origin: str = "expression",
        logical: bool = False,
    ) -> None:
        self.text = text
        self.origin = origin
        self.logical = logical
        try:
            # one line: a TOML multi-line string may break a long condition anywhere
            tree = ast.parse(" ".join(text.split()), mode="eval")
        except SyntaxError as err:
            raise ConfigError(
                f"{origin} {text!r} is not a valid expression ({err.msg} at column "
                f"{err.offset}); write e.g. 'force_n > 500 and feed_mm_min > 10'"
            ) from None
        tree = ast.fix_missing_locations(_TomlBooleans().visit(tree))
        names: list[str] = []
        called = {id(node.func) for node in ast.walk(tree) if isinstance(node, ast.Call)}
        for node in ast.walk(tree):
            self._check_node(node, names, id(node) in called)
        if logical:
            top = tree.body
            is_not = isinstance(top, ast.UnaryOp) and isinstance(top.op, ast.Not)
            is_bool = isinstance(top, ast.Constant) and isinstance(top.value, bool)
            if not (isinstance(top, _LOGICAL) or is_not or is_bool):
                raise ConfigError(
                    f"{origin} {text!r} is not a condition; give a comparison or a combination "
                    f"of comparisons with and/or/not (e.g. 'force_n > 500')"
                )
        if valid_names is not None:
            unknown = [name for name in names if name not in valid_names]
            if unknown:
                raise ConfigError(
                    f"{origin} {text!r} uses unknown name(s) {', '.join(unknown)}; valid names "
                    f"are {', '.join(sorted(valid_names))}"
                )
        self.names: tuple[str, ...] = tuple(names)
        self._code: CodeType = compile(tree, f"<{origin}>", "eval")

    def _check_node(self, node: ast.AST, names: list[str], called: bool) -> None:
        origin, text = self.origin, self.text
        if not isinstance(node, _ALLOWED_NODES):
            raise ConfigError(
                f"{origin} {text!r} uses {type(node).__name__}, which is not allowed; use "
                f"names, numbers, comparisons, and/or/not, + - * / and abs/min/max"
            )
        if isinstance(node, ast.Constant) and not isinstance(node.value, int | float):
            raise ConfigError(
                f"{origin} {text!r} contains the constant {node.value!r}; only numbers and "
                f"true/false are allowed"
            )
        if isinstance(node, ast.Call):
            func = node.func
            if not isinstance(func, ast.Name) or func.id not in FUNCTIONS or node.keywords:
                shown = ast.unparse(func)
                raise ConfigError(
                    f"{origin} {text!r} calls {shown!r}; only abs(x), min(a, b, ...) and "
                    f"max(a, b, ...) may be called, without keywords"
                )
            low, high = FUNCTIONS[func.id]
            if not low <= len(node.args) <= high:
                raise ConfigError(
                    f"{origin} {text!r} calls {func.id} with {len(node.args)} argument(s); "
                    f"it takes {low}" + ("" if low == high else f" to {high}")
                )
        elif isinstance(node, ast.Name) and not called:
            if node.id.startswith("_") or node.id in FUNCTIONS:
                raise ConfigError(
                    f"{origin} {text!r} uses the name {node.id!r} as a value; names may not "
                    f"start with '_', and abs/min/max must be called"
                )
            if node.id not in names:
                names.append(node.id)

    def evaluate(self, values: Mapping[str, float]) -> float:
        """The expression's value with each name taken from ``values`` (a bool is 0 or 1).

        Raises ``KeyError`` for a missing name and ``ZeroDivisionError`` for a division by
        zero; :class:`~cnctwin.control.rules.RuleEngine` checks both before it acts.
        """
        scope = {name: values[name] for name in self.names}
        # safe: the tree was checked against the whitelist and runs without builtins
        return eval(self._code, _GLOBALS, scope)

    def finite_inputs(self, values: Mapping[str, float]) -> bool:
        """Whether every name is present in ``values`` with a finite value."""
        for name in self.names:
            value = values.get(name)
            if value is None or not math.isfinite(value):
                return False
        return True

    def __repr__(self) -> str:
        return f"Expression({self.text!r})"
