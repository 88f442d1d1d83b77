"""JSON text that is always valid JSON: non-finite numbers become ``null``.

Python's :mod:`json` writes NaN and infinities as ``NaN``, ``Infinity`` and
``-Infinity``, which are not JSON (RFC 8259) and which strict parsers reject. Every JSON
document cnctwin writes (``--json`` output of the commands, summary files) goes through
:func:`dumps`, which writes a float that is NaN, +inf or -inf as ``null``: "no finite
value" (undefined, or unbounded such as a stability limit that does not exist). The
encoder runs with ``allow_nan=False`` as a backstop, so anything that slips past the
mapping is an error, never invalid output.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from typing import Any

__all__ = ["dumps", "finite"]


def finite(value: Any) -> Any:
    """``value`` with every non-finite float, at any depth, replaced by ``None``.

    Dicts, lists and tuples are copied (tuples become lists, as JSON has no tuples);
    anything else is returned as it is.
    """
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: finite(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [finite(item) for item in value]
    return value


def dumps(
    value: Any, *, indent: int | None = None, default: Callable[[Any], Any] | None = None
) -> str:
    """Serialize ``value`` as strict JSON, non-finite floats as ``null``.

    Parameters
    ----------
    value
        Dicts, lists, tuples, strings, numbers, booleans and ``None``.
    indent
        Indentation as in :func:`json.dumps`; ``None`` writes one line.
    default
        As in :func:`json.dumps`: what an object of another type is written as (e.g.
        ``str``); ``None`` refuses such objects with :class:`TypeError`.

    Raises
    ------
    ValueError
        Only if a non-finite number hides in a type :func:`finite` does not walk.
    """
    return json.dumps(finite(value), indent=indent, default=default, allow_nan=False)
