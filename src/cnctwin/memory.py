"""The work limit: how much memory one computation may take, checked before it allocates.

Every entry point whose memory grows with its input estimates the bytes first and calls
:func:`check_memory`: a dexel stock (its rays, from the stock box and the dexel density, and
each growth of its overflow heap), the per-step table of a simulated program (positions: the
program's duration over the cycle time), the predicted signals, a stability lobe diagram
(spindle speeds x depths or steps per period). Over the limit, :func:`check_memory` raises a
one-line :class:`~cnctwin.errors.ConfigError` that says what was asked, what fits and what to
change, instead of running until the operating system or numpy gives up.

The limit is :data:`DEFAULT_MEMORY_LIMIT_GB` (4 GB, 1 GB = 1e9 bytes: a large stock of
500 x 500 x 100 mm at 10 /mm takes about 1.1 GB, a day-long program at the twin's 12.5 ms cycle
about 1.1 GB of steps) unless the environment variable :data:`MEMORY_LIMIT_ENV` says otherwise,
e.g. ``CNCTWIN_MEMORY_LIMIT_GB=32 cnctwin simulate ...``. See docs/configuration.md.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable

from cnctwin.errors import ConfigError

__all__ = [
    "DEFAULT_MEMORY_LIMIT_GB",
    "MEMORY_LIMIT_ENV",
    "check_memory",
    "format_bytes",
    "memory_limit_bytes",
]

#: The environment variable that sets the limit, in GB (1e9 bytes).
MEMORY_LIMIT_ENV = "CNCTWIN_MEMORY_LIMIT_GB"
#: The limit without :data:`MEMORY_LIMIT_ENV`, GB.
DEFAULT_MEMORY_LIMIT_GB = 4.0
#: The largest limit :data:`MEMORY_LIMIT_ENV` may set, GB (1 PB: beyond any machine).
_MAX_MEMORY_LIMIT_GB = 1e6


def memory_limit_bytes() -> float:
    """The memory one computation may take, bytes (from :data:`MEMORY_LIMIT_ENV` if set).

    Raises
    ------
    ConfigError
        When the variable is set but not a number of GB > 0 and <= 1,000,000.
    """
    text = os.environ.get(MEMORY_LIMIT_ENV)
    if text is None or not text.strip():
        return DEFAULT_MEMORY_LIMIT_GB * 1e9
    try:
        gb = float(text)
    except ValueError:
        gb = math.nan
    if not 0.0 < gb <= _MAX_MEMORY_LIMIT_GB:
        raise ConfigError(
            f"{MEMORY_LIMIT_ENV}={text!r}: give the memory limit in GB, > 0 and "
            f"<= {_MAX_MEMORY_LIMIT_GB:g}"
        )
    return gb * 1e9


def check_memory(what: str, nbytes: float, remedy: Callable[[float], str]) -> None:
    """Refuse a computation whose estimated memory exceeds the limit.

    Parameters
    ----------
    what
        What would be allocated, with its size in the user's terms, e.g. ``"stock 1e+06 x
        1e+06 x 1e+06 mm at 10 /mm is 3e+14 rays"``.
    nbytes
        The estimate, bytes (a float: estimates of absurd inputs exceed any integer type).
    remedy
        Given the fraction of the request that fits (``limit / nbytes``, < 1), what to change,
        e.g. ``"use density_per_mm <= 3.2 or a smaller stock"``.

    Raises
    ------
    ConfigError
        ``"WHAT (~SIZE) exceeds the memory limit of LIMIT (CNCTWIN_MEMORY_LIMIT_GB): REMEDY"``.
    """
    limit = memory_limit_bytes()
    if nbytes <= limit:
        return
    raise ConfigError(
        f"{what} (~{format_bytes(nbytes)}) exceeds the memory limit of {format_bytes(limit)} "
        f"({MEMORY_LIMIT_ENV}): {remedy(limit / nbytes)}"
    )


def format_bytes(nbytes: float) -> str:
    """A byte count for people: ``"1.3 GB"``, ``"200 TB"`` (decimal units)."""
    for unit, size in (("EB", 1e18), ("PB", 1e15), ("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if nbytes >= size:
            return f"{nbytes / size:.3g} {unit}"
    return f"{nbytes / 1e3:.3g} kB"
