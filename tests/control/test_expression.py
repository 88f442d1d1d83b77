"""The safe expression evaluator: whitelisted syntax, load-time name checks, Python semantics."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnctwin.control import Expression
from cnctwin.errors import ConfigError

NAMES = {"force_n", "band_low_n", "feed_mm_min", "form_error_um", "feed_override_pct"}


@pytest.mark.parametrize(
    ("text", "values", "expected"),
    [
        (
            "force_n < band_low_n and feed_mm_min > 10",
            dict(force_n=5, band_low_n=8, feed_mm_min=600),
            True,
        ),
        (
            "force_n < band_low_n and feed_mm_min > 10",
            dict(force_n=5, band_low_n=8, feed_mm_min=0),
            False,
        ),
        ("not (force_n >= 3) or form_error_um > 40", dict(force_n=2, form_error_um=0), True),
        ("0 < force_n <= 10", dict(force_n=10), True),
        ("abs(form_error_um) > 40", dict(form_error_um=-41), True),
        (
            "max(force_n, band_low_n) - min(force_n, band_low_n, 3) == 7",
            dict(force_n=10, band_low_n=4),
            True,
        ),
        ("feed_override_pct * 0.5 + 2 / 4 - -1", dict(feed_override_pct=80), 41.5),
        ("true and not false", {}, True),
        ("force_n > 1 and\n    feed_mm_min > 10", dict(force_n=2, feed_mm_min=20), True),
    ],
)
def test_evaluates_like_python(text: str, values: dict, expected: object) -> None:
    expr = Expression(text, NAMES)
    assert expr.evaluate(values) == expected
    # the same text evaluated by Python itself (the whitelist only narrows the syntax)
    python = " ".join(text.replace("true", "True").replace("false", "False").split())
    assert eval(python, {"abs": abs, "min": min, "max": max}, dict(values)) == expected


def test_names_in_order_of_appearance_without_functions() -> None:
    expr = Expression("max(force_n, band_low_n) > force_n + feed_mm_min", NAMES)
    assert expr.names == ("force_n", "band_low_n", "feed_mm_min")


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("__import__('os').system('true')", "calls"),
        ("force_n.real > 1", "Attribute"),
        ("force_n[0] > 1", "Subscript"),
        ("'abc' == force_n", "constant 'abc'"),
        ("(lambda: 1)() > 0", "calls|Lambda"),
        ("force_n ** 2 > 1", "Pow"),
        ("force_n if feed_mm_min else 1", "IfExp"),
        ("round(force_n) > 1", "calls 'round'"),
        ("abs(force_n, 2) > 1", "takes 1"),
        ("max(force_n) > 1", "takes 2 to 64"),
        ("min(force_n, key=band_low_n) > 1", "without keywords"),
        ("_secret > 1", "may not start with '_'"),
        ("abs > 1", "must be called"),
        ("force_n >", "not a valid expression"),
        ("", "not a valid expression"),
    ],
)
def test_rejects_everything_outside_the_whitelist(text: str, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        Expression(text, origin="rule 'x' condition")


def test_unknown_name_error_names_rule_expression_and_valid_names() -> None:
    with pytest.raises(ConfigError) as err:
        Expression("forse_n > 5", NAMES, origin="rule 'hole' condition")
    message = str(err.value)
    assert "rule 'hole' condition 'forse_n > 5'" in message
    assert "unknown name(s) forse_n" in message
    assert "band_low_n, feed_mm_min, feed_override_pct, force_n, form_error_um" in message
    assert "\n" not in message


def test_condition_must_be_logical() -> None:
    with pytest.raises(ConfigError, match="not a condition"):
        Expression("force_n - 5", NAMES, logical=True)
    assert Expression("not force_n > 5", NAMES, logical=True).evaluate({"force_n": 1})


def test_missing_and_nonfinite_inputs_are_detected() -> None:
    expr = Expression("force_n > band_low_n", NAMES)
    assert expr.finite_inputs({"force_n": 1.0, "band_low_n": 2.0})
    assert not expr.finite_inputs({"force_n": 1.0})
    assert not expr.finite_inputs({"force_n": math.nan, "band_low_n": 2.0})
    with pytest.raises(KeyError):
        expr.evaluate({"force_n": 1.0})


@settings(max_examples=200, deadline=None)
@given(
    a=st.floats(-1e6, 1e6, allow_nan=False),
    b=st.floats(-1e6, 1e6, allow_nan=False),
    c=st.floats(0.5, 1e3),
)
def test_arithmetic_matches_python(a: float, b: float, c: float) -> None:
    expr = Expression("abs(a - b) / c + max(a, b) * 2 > min(a, b, c) or not a < b", None)
    values = {"a": a, "b": b, "c": c}
    assert expr.evaluate(values) == (abs(a - b) / c + max(a, b) * 2 > min(a, b, c) or not a < b)
