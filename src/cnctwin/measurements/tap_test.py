"""Readers of tap-test files: FRF tables, impact records and MATLAB ``.mat`` FRFs.

Three kinds of file are read into a :class:`~cnctwin.dynamics.frf.FRF`:

- an FRF table (text): columns frequency [Hz], real part, imaginary part (m/N by default);
- an impact record (text): columns time [s], hammer force [N], response (acceleration in
  m/s^2 by default), one hit; the H1 FRF is computed from it
  (:func:`cnctwin.dynamics.frf.impact_frf`);
- a MATLAB ``.mat`` file holding an FRF: an ``N x 2`` (real, imaginary) or complex variable,
  with a frequency vector (``f``, ``freq`` or ``frequency``, Hz) or ``df`` and ``f_start`` (Hz).

A text file is an impact record when its first column advances by less than
:data:`IMPACT_STEP_LIMIT` per row (a sampling interval, s) and an FRF table otherwise (a
frequency step, Hz); ``kind`` overrides. The FRFs are in SI: angular frequency in rad/s.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from cnctwin.dynamics import FRF, FRFQuantity, impact_frf
from cnctwin.errors import DataError, InputError

__all__ = [
    "EXCITED_DB",
    "IMPACT_STEP_LIMIT",
    "TapTest",
    "TapTestKind",
    "load_tap_test",
    "read_frf_mat",
    "read_impact_record",
    "read_table",
]

TWO_PI = 2.0 * math.pi
#: A text file whose first column steps by less than this is an impact record (s), else an FRF.
IMPACT_STEP_LIMIT = 0.01
#: An impact record's excited band ends where the force spectrum is this far below its peak, dB.
EXCITED_DB = 40.0

#: What a tap-test file holds: ``"frf"``, ``"impact"``, or ``"auto"`` (decide from the file).
TapTestKind = Literal["auto", "frf", "impact"]
_KINDS = ("auto", "frf", "impact")
_NUMBER_SPLIT = re.compile(r"[\s,;]+")


@dataclass(frozen=True)
class TapTest:
    """What a tap-test file gave.

    Attributes
    ----------
    frf
        The FRF (still the file's quantity; an impact record's H1 with its coherence),
        angular frequency in rad/s.
    kind
        ``"frf"`` or ``"impact"``.
    variable
        The ``.mat`` variable read, else None.
    excited_omega
        For an impact record, the highest angular frequency the hammer excites (force spectrum
        within :data:`EXCITED_DB` of its peak), rad/s; else None.
    """

    frf: FRF
    kind: Literal["frf", "impact"]
    variable: str | None = None
    excited_omega: float | None = None


def read_table(path: Path, n_columns: int = 3) -> NDArray[np.float64]:
    """The numeric rows of a text table: whitespace, comma or semicolon separated.

    Blank lines and lines starting with ``#``, ``%`` or ``;`` are skipped, and so is a header
    (rows before the first numeric one). The values keep the file's units.

    Parameters
    ----------
    path
        The text file.
    n_columns
        Numbers each row must hold.

    Returns
    -------
    numpy.ndarray
        Shape ``(rows, n_columns)``; extra columns are an error.

    Raises
    ------
    DataError
        ``FILE:LINE: ...`` for a row that is not ``n_columns`` numbers, or a file with fewer
        than 4 rows or with NaN or infinite values.
    """
    rows: list[list[float]] = []
    with path.open(encoding="utf-8", errors="replace") as handle:
        for number, line in enumerate(handle, start=1):
            text = line.strip()
            if not text or text[0] in "#%;":
                continue
            fields = [field for field in _NUMBER_SPLIT.split(text) if field]
            try:
                values = [float(field) for field in fields]
            except ValueError:
                if not rows:
                    continue  # a header
                raise DataError(
                    f"{path}:{number}: {text[:40]!r} is not {n_columns} numbers"
                ) from None
            if len(values) != n_columns:
                raise DataError(
                    f"{path}:{number}: {len(values)} columns; give {n_columns} (see "
                    "cnctwin dynamics fit-frf --help)"
                )
            rows.append(values)
    if len(rows) < 4:
        raise DataError(f"{path}: {len(rows)} numeric rows; give a table of at least 4")
    table = np.asarray(rows)
    if not np.all(np.isfinite(table)):
        raise DataError(f"{path}: the table holds NaN or infinite values")
    return table


def _frf_from_table(path: Path, table: NDArray[np.float64], quantity: FRFQuantity) -> FRF:
    frequency_hz = table[:, 0]
    if np.any(np.diff(frequency_hz) <= 0.0) or frequency_hz[0] < 0.0:
        raise DataError(f"{path}: the frequencies (first column, Hz) must be >= 0 and increasing")
    return FRF(TWO_PI * frequency_hz, table[:, 1] + 1j * table[:, 2], quantity)


def read_impact_record(
    path: Path, table: NDArray[np.float64] | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """Force [N], response (file's unit) and sampling interval [s] of an impact record.

    Parameters
    ----------
    path
        A text file with the columns time [s], hammer force [N] and response.
    table
        The file's table when it has been read already (:func:`read_table`).

    Raises
    ------
    DataError
        When the time column is not uniformly increasing.
    """
    rows = read_table(path) if table is None else table
    time = rows[:, 0]
    dt = float(time[-1] - time[0]) / (time.size - 1)
    # The times are printed with few digits: allow rounding, not a missing or repeated sample.
    if not dt > 0.0 or np.max(np.abs(time - time[0] - dt * np.arange(time.size))) > 0.25 * dt:
        raise DataError(f"{path}: the time column (s) must increase by a constant step")
    return rows[:, 1], rows[:, 2], dt


def read_frf_mat(
    path: Path, variable: str | None = None, quantity: FRFQuantity = "receptance"
) -> tuple[FRF, str]:
    """An FRF from a MATLAB ``.mat`` file (module docstring), and the variable's name.

    Parameters
    ----------
    path
        The ``.mat`` file.
    variable
        The variable holding the FRF; None when the file holds exactly one.
    quantity
        What the FRF is (receptance in m/N, mobility in m/(N s), accelerance in m/(N s^2)).

    Raises
    ------
    DataError
        When the file holds no FRF, several without ``variable``, or no frequencies.
    """
    from scipy.io import loadmat  # scipy.io only when a .mat is read

    try:
        content = {k: v for k, v in loadmat(str(path)).items() if not k.startswith("__")}
    except (ValueError, NotImplementedError, TypeError) as err:
        raise DataError(f"{path}: not a readable MATLAB file ({err})") from None
    candidates = {name: value for name, value in content.items() if _frf_like(value)}
    if variable is None:
        if len(candidates) != 1:
            found = ", ".join(sorted(candidates)) or "none"
            raise DataError(
                f"{path}: {len(candidates)} FRF variables ({found}); name one with --variable"
            )
        variable = next(iter(candidates))
    elif variable not in candidates:
        raise DataError(
            f"{path}: no FRF variable {variable!r}; valid: "
            f"{', '.join(sorted(candidates)) or 'none'}"
        )
    value = np.asarray(candidates[variable])
    h = value[:, 0] + 1j * value[:, 1] if np.isrealobj(value) else value.ravel()
    frequency_hz = _mat_frequencies(path, content, h.size)
    return FRF(TWO_PI * frequency_hz, h.astype(complex), quantity), variable


def _frf_like(value: Any) -> bool:
    """An N x 2 real array or a complex vector, N >= 4."""
    if not isinstance(value, np.ndarray) or value.dtype.kind not in "fc" or value.size < 8:
        return False
    if value.dtype.kind == "c":
        return value.ndim == 1 or (value.ndim == 2 and 1 in value.shape)
    return value.ndim == 2 and value.shape[1] == 2 and value.shape[0] >= 4


def _mat_frequencies(path: Path, content: dict[str, Any], n: int) -> NDArray[np.float64]:
    for name in ("f", "freq", "frequency", "f_hz", "freq_hz"):
        if name in content and np.asarray(content[name]).size == n:
            return np.asarray(content[name], dtype=np.float64).ravel()
    if "df" in content:
        df = float(np.asarray(content["df"]).ravel()[0])
        start = float(np.asarray(content.get("f_start", 0.0)).ravel()[0])
        if df > 0.0:
            return np.asarray(start + df * np.arange(n), dtype=np.float64)
    raise DataError(
        f"{path}: no frequencies; give a vector f (Hz) of {n} values, or df and f_start (Hz)"
    )


def load_tap_test(
    path: Path,
    *,
    kind: TapTestKind = "auto",
    variable: str | None = None,
    quantity: FRFQuantity | None = None,
    tau_s: float | None = None,
) -> TapTest:
    """Read a tap-test file (module docstring) into an FRF.

    Parameters
    ----------
    path
        The file: ``.mat``, or a text table.
    kind
        ``"frf"``, ``"impact"`` or ``"auto"`` (a ``.mat`` is an FRF; a text file by its first
        column's step).
    variable
        The ``.mat`` variable holding the FRF.
    quantity
        What the FRF (or the impact record's response) is; default ``"receptance"`` (m/N) for
        an FRF, ``"accelerance"`` (response in m/s^2) for an impact record.
    tau_s
        Exponential window time constant for an impact record, s; None for none.

    Raises
    ------
    InputError
        For a ``kind`` other than ``"auto"``, ``"frf"`` and ``"impact"``.
    DataError
        For a file that is missing or cannot be read as ``kind``.
    """
    if kind not in _KINDS:
        raise InputError(f"kind {kind!r}; valid: {', '.join(_KINDS)}")
    if not path.is_file():
        raise DataError(f"{path}: no such file")
    if path.suffix.lower() == ".mat":
        if kind == "impact":
            raise DataError(f"{path}: impact records are read from text files, not .mat")
        frf, name = read_frf_mat(path, variable, quantity or "receptance")
        return TapTest(frf, "frf", name)
    table = read_table(path)
    if kind == "auto":
        step = float(np.median(np.diff(table[:, 0])))
        kind = "impact" if 0.0 < step < IMPACT_STEP_LIMIT else "frf"
    if kind == "frf":
        return TapTest(_frf_from_table(path, table, quantity or "receptance"), "frf")
    force, response, dt = read_impact_record(path, table)
    frf = impact_frf(force, response, dt, quantity=quantity or "accelerance", tau=tau_s)
    spectrum = np.abs(np.fft.rfft(force))
    excited = np.flatnonzero(spectrum >= spectrum.max() * 10.0 ** (-EXCITED_DB / 20.0))
    return TapTest(
        frf, "impact", None, TWO_PI * float(np.fft.rfftfreq(force.size, dt)[excited[-1]])
    )
