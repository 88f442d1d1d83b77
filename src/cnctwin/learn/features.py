"""The one feature path: a schema's filters, windows and categories, live or over a log.

:meth:`FeaturePath.update` takes one sample (a mapping of signal name to value, as the twin's
read stage delivers) and returns the features of the window ending at it;
:meth:`FeaturePath.batch` takes a whole run (columns) and returns the same features for every
sample, as a matrix, in a fraction of the time. Both use :mod:`cnctwin.signals`: the filters'
``process`` equals their ``update`` (the filters' own contract) and the window features are
those of :class:`~cnctwin.signals.SlidingWindow` over the last ``length`` finite samples, so
the offline dataset a model is trained on is what the live twin computes, sample for sample
(tests/learn/test_features.py checks this against the twin's filter and feature stages).

Missing samples (NaN, or a sample matching an ``invalid_when`` rule): a filter holds (Hampel,
Butterworth) or predicts (Kalman) as in the twin; an unfiltered signal holds its last finite
value; a window skips the sample and its features hold. Before a signal's first finite
sample its features are NaN. Values keep their signal's unit; times are in s.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray

from cnctwin.errors import DataError
from cnctwin.learn.schema import FeatureSchema, FilterSpec
from cnctwin.signals import (
    ButterworthFilter,
    CausalFilter,
    HampelFilter,
    KalmanFilter,
    SlidingWindow,
)

__all__ = ["FeaturePath", "make_filter"]

#: Windows computed per block in :meth:`FeaturePath.batch` (bounds the temporary arrays).
_BLOCK = 4096


def make_filter(spec: FilterSpec, sample_period_s: float) -> CausalFilter:
    """The filter a :class:`FilterSpec` describes, sampling every ``sample_period_s`` s
    (the twin's ``[twin.filters.X]`` too)."""
    if spec.kind == "hampel":
        return HampelFilter(spec.window, spec.n_sigma)
    if spec.kind == "kalman":
        return KalmanFilter(spec.process_var, spec.measurement_var)
    return ButterworthFilter(spec.order, spec.cutoff_hz, 1.0 / sample_period_s)


class FeaturePath:
    """A schema's features, one sample at a time (:meth:`update`) or per run (:meth:`batch`).

    Parameters
    ----------
    schema
        The feature schema.

    Attributes
    ----------
    invalid
        Samples dropped as invalid (``invalid_when``) so far by :meth:`update`.
    """

    def __init__(self, schema: FeatureSchema) -> None:
        self.schema = schema
        spec = schema.spec
        self._period = spec.sample_period_s
        self._rate = 1.0 / spec.sample_period_s
        self._invalid_rules = [(rule.signal, rule.equals) for rule in spec.invalid_when]
        self.invalid = 0
        self.reset()

    def reset(self) -> None:
        """Forget every sample (a new run)."""
        spec = self.schema.spec
        self._filters = {n: make_filter(f, self._period) for n, f in spec.filters.items()}
        self._held = dict.fromkeys(spec.signals, math.nan)
        self._windows = [
            (w.signal, SlidingWindow(w.length, self._rate), tuple(w.features)) for w in spec.windows
        ]
        self._window_values = [[math.nan] * len(w.features) for w in spec.windows]

    def is_invalid(self, sample: Mapping[str, object]) -> bool:
        """Whether ``sample`` matches one of the schema's ``invalid_when`` rules."""
        return any(sample.get(name) == value for name, value in self._invalid_rules)

    def update(self, sample: Mapping[str, object], t_s: float | None = None) -> dict[str, float]:
        """Push one sample; the features by name (the schema's order).

        ``sample`` maps signal names to values (numbers; a category's value as text); a
        missing or non-finite value is a missing sample of that signal. ``t_s`` is the
        sample's time in s (``None``: the nominal time, as :class:`SlidingWindow` counts).
        """
        spec = self.schema.spec
        if self.is_invalid(sample):
            self.invalid += 1
            sample = {}
        current: dict[str, float] = {}
        for name in spec.signals:
            raw = sample.get(name)
            value = float(raw) if isinstance(raw, int | float) else math.nan
            flt = self._filters.get(name)
            if flt is not None:
                value = flt.update(value)
            if math.isfinite(value):
                self._held[name] = value
            current[name] = value
        out = dict(self._held)
        for k, (signal, window, features) in enumerate(self._windows):
            value = current[signal]
            if math.isfinite(value):
                window.push(value, t_s)
                self._window_values[k] = [float(getattr(window, f)()) for f in features]
            for feature, result in zip(features, self._window_values[k], strict=True):
                out[f"{signal}_{feature}"] = result
        for name, values in spec.categories.items():
            raw = sample.get(name)
            for value in values:
                out[f"{name}={value}"] = 1.0 if raw == value else 0.0
        return out

    def batch(
        self, columns: Mapping[str, NDArray[np.generic]], t_s: NDArray[np.float64] | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """The features of every sample of one run, from the start (the path is reset).

        Parameters
        ----------
        columns
            One array per source signal, all of one length (numbers as float, categories as
            text).
        t_s
            The samples' times, s; ``None``: ``k * sample_period_s``.

        Returns
        -------
        features : numpy.ndarray
            ``(n, len(schema.names))``, float64, equal to :meth:`update` sample by sample.
        valid : numpy.ndarray
            Per sample: not invalid and every feature finite.

        Raises
        ------
        cnctwin.errors.DataError
            For a missing signal or columns of different lengths.
        """
        self.reset()
        schema, spec = self.schema, self.schema.spec
        schema.require_signals(frozenset(columns), "the run")
        n = len(next(iter(columns.values()))) if columns else 0
        if any(len(c) != n for c in columns.values()):
            raise DataError("the run's signal columns differ in length; give one value per sample")
        times = np.arange(n) * self._period if t_s is None else np.asarray(t_s, dtype=float)
        invalid = np.zeros(n, dtype=bool)
        for name, value in self._invalid_rules:
            column = columns.get(name)
            if column is not None and column.dtype.kind == "f":
                invalid |= column == value
        out = np.full((n, len(schema.names)), np.nan)
        current: dict[str, NDArray[np.float64]] = {}
        for j, name in enumerate(spec.signals):
            values = _numeric(columns[name], name)
            values[invalid] = np.nan
            flt = self._filters.get(name)
            if flt is not None:
                values = flt.process(values)
            current[name] = values
            out[:, j] = _hold(values)
        j = len(spec.signals)
        for window_spec in spec.windows:
            block = _window_features(
                current[window_spec.signal],
                times,
                window_spec.length,
                window_spec.features,
            )
            out[:, j : j + block.shape[1]] = block
            j += block.shape[1]
        for name, values in spec.categories.items():
            column = np.asarray(columns[name])
            for value in values:
                out[:, j] = np.where(invalid, 0.0, column == value)
                j += 1
        valid = ~invalid & np.all(np.isfinite(out), axis=1)
        self.reset()
        return out, valid


def _numeric(column: NDArray[np.generic], name: str) -> NDArray[np.float64]:
    try:
        return np.array(column, dtype=float)
    except (TypeError, ValueError):
        raise DataError(
            f"signal {name!r} holds text; give numbers (or list it as a category)"
        ) from None


def _hold(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """Each NaN replaced by the last finite value before it (NaN before the first)."""
    finite = np.isfinite(values)
    index = np.where(finite, np.arange(values.size), -1)
    np.maximum.accumulate(index, out=index)
    held = np.where(index >= 0, values[np.maximum(index, 0)], np.nan)
    return np.asarray(held, dtype=float)


def _window_features(
    values: NDArray[np.float64], times: NDArray[np.float64], length: int, features: list[str]
) -> NDArray[np.float64]:
    """Features of the window of the last ``length`` finite samples at every sample, held
    over non-finite ones (the vectorised :class:`SlidingWindow`)."""
    n = values.size
    finite = np.flatnonzero(np.isfinite(values))
    m = finite.size
    result = np.full((n, len(features)), np.nan)
    if m == 0:
        return result
    v, t = values[finite], times[finite]
    per_finite = np.empty((m, len(features)))
    # windows that are not full yet: the first length - 1 finite samples
    head = min(m, length - 1)
    for k in range(head):
        per_finite[k] = _features_of(v[None, : k + 1], t[None, : k + 1], features)[0]
    if m >= length:
        vw, tw = sliding_window_view(v, length), sliding_window_view(t, length)
        for start in range(0, vw.shape[0], _BLOCK):
            stop = min(start + _BLOCK, vw.shape[0])
            per_finite[length - 1 + start : length - 1 + stop] = _features_of(
                vw[start:stop], tw[start:stop], features
            )
    # sample i shows the features of the last finite sample at or before it
    count = np.cumsum(np.isfinite(values)) - 1
    seen = count >= 0
    result[seen] = per_finite[count[seen]]
    return result


def _features_of(
    v: NDArray[np.float64], t: NDArray[np.float64], features: list[str]
) -> NDArray[np.float64]:
    """Row-wise window features (the formulas of :mod:`cnctwin.signals.windows`)."""
    columns = []
    length = v.shape[1]
    for feature in features:
        if feature == "mean":
            columns.append(np.mean(v, axis=1))
        elif feature == "rms":
            columns.append(np.sqrt(np.einsum("ij,ij->i", v, v) / length))
        elif feature == "peak_to_peak":
            columns.append(v.max(axis=1) - v.min(axis=1))
        else:  # slope
            tc = t - t.mean(axis=1, keepdims=True)
            stt = np.einsum("ij,ij->i", tc, tc)
            vc = v - v.mean(axis=1, keepdims=True)
            with np.errstate(invalid="ignore", divide="ignore"):
                columns.append(np.where(stt == 0.0, np.nan, np.einsum("ij,ij->i", tc, vc) / stt))
    return np.stack(columns, axis=1)
